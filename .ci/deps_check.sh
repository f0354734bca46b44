#!/usr/bin/env bash
# scripts/install-deps.sh must install every pkg-config module the CMake files require: a module
# installed by hand on a developer's machine configures there and fails on a fresh Debian 12
# machine (libimgui-dev was missing for a session). For every `pkg_check_modules(... REQUIRED ...)`
# module, the Debian package owning its .pc file must be named in install-deps.sh.
# Given a configured build tree, the same for every `find_package(NAME ... REQUIRED ...)` whose
# result the tree's CMakeCache.txt records as a file (NAME_DIR's config file; else NAME's or
# NAME-in-capitals' _LIBRARY[_RELEASE], _SSL_LIBRARY, _EXECUTABLE; PKG_CONFIG_EXECUTABLE): the
# package owning that file
# must be listed or a dependency of a listed one (libboost-dev and libjpeg-dev are such
# metapackages). A name with no such entry (Threads, a package this tree did not look for) is
# reported as unchecked, not failed.
#   .ci/deps_check.sh [REPO_ROOT [BUILD_DIR]]
# DEPS_CHECK_INSTALL_SCRIPT names another install script (the test of this check uses it).
set -euo pipefail
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
build=${2:-}
deps=${DEPS_CHECK_INSTALL_SCRIPT:-$root/scripts/install-deps.sh}
# The package names install-deps.sh lists (words of its `packages=(...)` / `packages+=(...)`
# lines and their continuation lines, comments dropped).
listed=$(awk '
  /^ *packages\+?=\(/ { on = 1; sub(/^ *packages\+?=\(/, "") }
  on { line = $0; sub(/#.*/, "", line); if (line ~ /\)/) { sub(/\).*/, "", line); on = 0 }; print line }
' "$deps" | tr -s ' \t' '\n\n' | sed '/^$/d' | sort -u)
# The required pkg-config modules: the words after IMPORTED_TARGET in pkg_check_modules(... REQUIRED ...).
modules=$(cd "$root" && git ls-files '*CMakeLists.txt' '*.cmake' | xargs grep -h 'pkg_check_modules(' |
  grep REQUIRED | sed -E 's/.*IMPORTED_TARGET +//; s/\).*//' | tr ' ' '\n' | sed '/^$/d' | sort -u)
if [[ -z $modules ]]; then
  echo "deps_check: found no pkg_check_modules(... REQUIRED IMPORTED_TARGET ...) in the CMake files"
  exit 1
fi
missing=0
for m in $modules; do
  pc=$(pkg-config --path "$m" 2>/dev/null || true)
  if [[ -z $pc ]]; then
    echo "deps_check: pkg-config module '$m' is not installed here (install-deps.sh should have)"
    missing=1
    continue
  fi
  pc=$(readlink -f "$pc")
  pkg=$(dpkg -S "$pc" 2>/dev/null | head -n 1 | cut -d: -f1 || true)
  if [[ -z $pkg ]]; then
    echo "deps_check: no Debian package owns $pc (module '$m'): install it from a package"
    missing=1
  elif ! grep -qx "$pkg" <<<"$listed"; then
    echo "deps_check: module '$m' comes from package '$pkg', which scripts/install-deps.sh does not install"
    missing=1
  else
    echo "deps_check: $m <- $pkg (listed)"
  fi
done
[[ -n $build ]] || exit $missing

cache=$build/CMakeCache.txt
[[ -f $cache ]] || { echo "deps_check: no $cache (configure $build first)"; exit 1; }
# The listed packages and everything they depend on, installed here.
# shellcheck disable=SC2086  # word splitting of the package list is intended
closure=$(apt-cache depends --recurse --installed --no-recommends --no-suggests --no-conflicts \
            --no-breaks --no-replaces --no-enhances $listed 2>/dev/null | grep -v '^ ' | sort -u)
names=$(cd "$root" && git ls-files '*CMakeLists.txt' '*.cmake' | xargs grep -hoE 'find_package\([A-Za-z0-9_]+[^)]*' |
  grep -w REQUIRED | sed -E 's/find_package\(([A-Za-z0-9_]+).*/\1/' | sort -u)
cached() {  # the value of cache entry $1 when it names an existing file, else nothing
  local v
  v=$(grep -m 1 "^$1:[A-Z]*=" "$cache" | cut -d= -f2- || true)
  if [[ -n $v && -e $v ]]; then echo "$v"; fi
}
for n in $names; do
  file=
  dir=$(cached "${n}_DIR")
  if [[ -n $dir ]]; then
    file=$(find "$dir" -maxdepth 1 \( -name '*Config.cmake' -o -name '*-config.cmake' \) | head -n 1)
  fi
  if [[ -z $file ]]; then
    upper=$(tr '[:lower:]' '[:upper:]' <<<"$n")
    for key in "${n}_LIBRARY" "${n}_LIBRARY_RELEASE" "${upper}_LIBRARY" "${upper}_LIBRARY_RELEASE" \
               "${upper}_SSL_LIBRARY" "${n}_EXECUTABLE" "${upper}_EXECUTABLE" \
               "$([[ $n == PkgConfig ]] && echo PKG_CONFIG_EXECUTABLE)"; do
      file=$(cached "$key") && [[ -n $file ]] && break
    done
  fi
  if [[ -z $file ]]; then
    echo "deps_check: find_package($n): no file of it in $cache (unchecked)"
    continue
  fi
  # Not resolved through links: libz.so (zlib1g-dev) points into zlib1g.
  pkg=$(dpkg -S "$file" 2>/dev/null | head -n 1 | cut -d: -f1 || true)
  if [[ -z $pkg ]]; then
    echo "deps_check: find_package($n): no Debian package owns $file: install it from a package"
    missing=1
  elif grep -qx "$pkg" <<<"$closure"; then
    echo "deps_check: find_package($n) <- $pkg ($file)"
  else
    echo "deps_check: find_package($n) comes from package '$pkg' ($file), which scripts/install-deps.sh does not install"
    missing=1
  fi
done
exit $missing
