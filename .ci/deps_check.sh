#!/usr/bin/env bash
# scripts/install-deps.sh must install every pkg-config module the CMake files require: a module
# installed by hand on a developer's machine configures there and fails on a fresh Debian 12
# machine (libimgui-dev was missing for a session). For every `pkg_check_modules(... REQUIRED ...)`
# module, the Debian package owning its .pc file must be named in install-deps.sh.
#   .ci/deps_check.sh [REPO_ROOT]
set -euo pipefail
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
deps=$root/scripts/install-deps.sh
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
exit $missing
