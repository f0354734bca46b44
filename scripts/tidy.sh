#!/usr/bin/env bash
# clang-tidy over our C++ sources with the curated .clang-tidy (bug finders, performance, a few
# modernisations); every finding is an error: the run fails (exit 1) on any. `make tidy`; CI runs it.
#   scripts/tidy.sh [BUILD_DIR [file...]]     default: build, every core/server/client/tests .cpp
# Needs the build's compile_commands.json (any configured build directory; gcc's flags that clang
# does not know are ignored). Files whose result is known are skipped: a clean result is cached
# under ~/.cache/tinstream-tidy, keyed by clang-tidy's version, .clang-tidy, the compile command,
# the file and every header of the repository (so any header change re-checks everything).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
[[ -f $build/compile_commands.json ]] || { echo "tidy.sh: no $build/compile_commands.json (configure first)" >&2; exit 2; }
# A unity build's compile commands name its batches, not the files in them: those files would be
# skipped below as "not compiled in this build".
if grep -q '/Unity/unity_' "$build/compile_commands.json"; then
  echo "tidy.sh: $build is a unity build (TINSTREAM_UNITY=ON); use a build configured without it" >&2
  exit 2
fi
if (($#)); then files=("$@"); else mapfile -t files < <(git ls-files 'core/*.cpp' 'server/*.cpp' 'client/*.cpp' 'tests/*.cpp' | grep -v '/fuzz/'); fi
cache=${XDG_CACHE_HOME:-$HOME/.cache}/tinstream-tidy
mkdir -p "$cache"
# The compile commands are GCC's: clang reads GCC's -Wconversion as also -Wsign-conversion (GCC's
# C++ -Wconversion leaves signedness out), which -Werror then makes an error in every TU that
# includes such a header. The project's warning set is GCC's; clang's extra one is not applied.
extra_args=(--extra-arg=-Wno-unknown-warning-option --extra-arg=-Wno-sign-conversion)
common=$( { clang-tidy --version; echo "${extra_args[*]}"; cat .clang-tidy; git ls-files -z '*.hpp' '*.h' | xargs -0 cat; } | sha256sum | cut -c1-32)
todo=()
declare -A key_of
for f in "${files[@]}"; do
  command=$(grep -F "\"file\": \"$PWD/$f\"" -B 3 "$build/compile_commands.json" | grep '"command"' || true)
  if [[ -z $command ]]; then
    continue  # not compiled in this build (a module switched off)
  fi
  key=$( { echo "$common"; echo "$command"; cat "$f"; } | sha256sum | cut -c1-32)
  key_of[$f]=$key
  [[ -f $cache/$key ]] || todo+=("$f")
done
echo "tidy: ${#files[@]} files, ${#todo[@]} to check ($(( ${#files[@]} - ${#todo[@]} )) known clean)"
((${#todo[@]})) || exit 0
logs=$build/tidy-logs
mkdir -p "$logs"
failed=0
check_one() {
  local f=$1 log=$logs/$(echo "$1" | tr / _).log
  if clang-tidy -p "$build" --quiet "${extra_args[@]}" "$f" >"$log" 2>&1; then
    touch "$cache/${key_of[$f]}"
  else
    echo "tidy: findings in $f:"
    grep -E 'error:|warning:' "$log" | grep -v 'warnings generated' | head -n 20
    return 1
  fi
}
jobs=$(nproc)
# Each check's pid is waited for by pid: `wait -n` in a loop that tests `jobs -r` first loses the
# status of a check that ended before the loop looked (it then said "clean" after a finding).
pids=()
for f in "${todo[@]}"; do
  while (($(jobs -rp | wc -l) >= jobs)); do sleep 0.2; done
  check_one "$f" &
  pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
if ((failed)); then
  echo "tidy: FAILED (logs in $logs)"
  exit 1
fi
echo "tidy: clean"
