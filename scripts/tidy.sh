#!/usr/bin/env bash
# clang-tidy over our C++ sources with the curated .clang-tidy (bug finders, performance, a few
# modernisations); every finding is an error: the run fails (exit 1) on any. `make tidy`; CI runs it.
#   scripts/tidy.sh [BUILD_DIR [file...]]     default: build, every core/server/client/tests .cpp
# Needs the build's compile_commands.json (any configured build directory; gcc's flags that clang
# does not know are ignored). In a unity tree (CI's build-tidy: TINSTREAM_UNITY and
# TINSTREAM_UNITY_PRODUCT) a file is checked through its batch, its findings reported as in a
# header; elsewhere through its own command. Units whose result is known are skipped: a clean
# result is cached under ~/.cache/tinstream-tidy, keyed by clang-tidy's version, .clang-tidy, the
# compile command, the unit's files and every header of the repository (so any header change
# re-checks everything).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
[[ -f $build/compile_commands.json ]] || { echo "tidy.sh: no $build/compile_commands.json (configure first)" >&2; exit 2; }
if (($#)); then files=("$@"); else mapfile -t files < <(git ls-files 'core/*.cpp' 'server/*.cpp' 'client/*.cpp' 'tests/*.cpp' | grep -v '/fuzz/'); fi
cache=${XDG_CACHE_HOME:-$HOME/.cache}/tinstream-tidy
mkdir -p "$cache"
# The compile commands are GCC's: clang reads GCC's -Wconversion as also -Wsign-conversion (GCC's
# C++ -Wconversion leaves signedness out), which -Werror then makes an error in every TU that
# includes such a header. The project's warning set is GCC's; clang's extra one is not applied.
extra_args=(--extra-arg=-Wno-unknown-warning-option --extra-arg=-Wno-sign-conversion)
common=$( { clang-tidy --version; echo "${extra_args[*]}"; cat .clang-tidy; git ls-files -z '*.hpp' '*.h' | xargs -0 cat; } | sha256sum | cut -c1-32)

# Which translation unit checks which file. In a unity tree (TINSTREAM_UNITY, TINSTREAM_UNITY_PRODUCT:
# CI's build-tidy) most files are #included 8 to a generated batch: clang-tidy then parses and
# matches the shared headers (the standard library, Beast, gtest: three quarters of its time, every
# check matching in every header before the header filter drops the findings) once a batch instead
# of once a file. Each file is checked by one TU: the batch holding most files to check, else its
# own compile command; files in neither are not compiled in this build (a module switched off).
# Output, one TU a line: the TU's source, then the files it checks.
plan=$(python3 - "$build/compile_commands.json" "${files[@]}" <<'PY'
import json, os, re, sys
root = os.getcwd()
wanted = sys.argv[2:]
entries = json.load(open(sys.argv[1]))
alone, batches = set(), {}
for e in entries:
    path = os.path.join(e.get("directory", ""), e["file"])
    if "/Unity/" in path:
        with open(path) as f:
            inc = re.findall(r'^#include "([^"]+)"', f.read(), re.M)
        batches[path] = [os.path.relpath(i, root) for i in inc]
    else:
        alone.add(os.path.relpath(path, root))
todo = set(wanted)
chosen = {}
while True:
    best = max(batches, key=lambda b: len(todo.intersection(batches[b])), default=None)
    if best is None or not todo.intersection(batches[best]):
        break
    chosen[best] = sorted(todo.intersection(batches[best]))
    todo -= set(chosen[best])
for f in wanted:
    if f in todo and f in alone:
        chosen[os.path.join(root, f)] = [f]
for tu, checked in chosen.items():
    print(tu, *checked)
PY
)
declare -a units=()
declare -A key_of checks_of
nfiles=0
todo_files=0
while read -r tu checked; do
  [[ -z $tu ]] && continue
  read -r -a list <<<"$checked"
  nfiles=$((nfiles + ${#list[@]}))
  command=$(grep -F "\"file\": \"$tu\"" -B 3 "$build/compile_commands.json" | grep '"command"' || true)
  # the files checked (a batch checked for some of its files is not clean for the others), the
  # batch, the files it includes, and the command that compiles it
  key=$( { echo "$common"; echo "$checked"; echo "$command"; cat "$tu"; if [[ $tu == */Unity/* ]]; then sed -n 's/^#include "\(.*\)"$/\1/p' "$tu" | xargs cat; fi; } | sha256sum | cut -c1-32)
  [[ -f $cache/$key ]] && continue
  units+=("$tu")
  key_of[$tu]=$key
  checks_of[$tu]=$checked
  todo_files=$((todo_files + ${#list[@]}))
done <<<"$plan"
echo "tidy: ${#files[@]} files, $nfiles compiled in $build, $todo_files to check in ${#units[@]} translation units ($((nfiles - todo_files)) known clean)"
((${#units[@]})) || exit 0
logs=$build/tidy-logs
mkdir -p "$logs"
failed=0
check_one() {
  local tu=$1 log=$logs/$(echo "${1#"$PWD"/}" | tr / _).log
  local -a checked args=(-p "$build" --quiet "${extra_args[@]}")
  read -r -a checked <<<"${checks_of[$tu]}"
  if [[ $tu == */Unity/* ]]; then
    # Findings in the included files are reported as in headers: the filter names exactly the
    # files this batch checks (besides the project's headers, as .clang-tidy does). The batch
    # file's own #include "x.cpp" lines are what bugprone-suspicious-include reports: it is off
    # for batches and done by grep on the checked files instead (the check's own rule: an include
    # of a .c/.cc/.cpp/.cxx file).
    local f alternatives=
    for f in "${checked[@]}"; do alternatives+="${alternatives:+|}$(printf '%s' "$PWD/$f" | sed 's/[.[\*^$()+?{}|]/\\&/g')"; done
    args+=(--header-filter="(core|server|client)/.*\.hpp$|^($alternatives)$" --checks=-bugprone-suspicious-include)
    if grep -nHE '^[[:space:]]*#[[:space:]]*include[[:space:]]*[<"][^">]*\.(c|cc|cpp|cxx)[">]' "${checked[@]}" >"$log.include"; then
      echo "tidy: findings in ${checked[*]}:"
      sed 's/$/: suspicious #include of an implementation file [bugprone-suspicious-include]/' "$log.include"
      return 1
    fi
  fi
  if clang-tidy "${args[@]}" "$tu" >"$log" 2>&1; then
    touch "$cache/${key_of[$tu]}"
  else
    echo "tidy: findings in ${checked[*]}:"
    grep -E 'error:|warning:' "$log" | grep -v 'warnings generated' | head -n 20
    return 1
  fi
}
jobs=$(nproc)
# A failed check writes its unit into failed.list, read after every check ended: waiting for each
# pid lost statuses (`wait -n` after a `jobs -r` test missed a check that had just ended, and
# `wait PID` answered "not a child of this shell" for 3 of 69 clean checks on 2026-11-28).
rm -f "$logs/failed.list"
# Batches leave bugprone-suspicious-include to grep (check_one): for the project's headers once.
if printf '%s\n' "${units[@]}" | grep -q '/Unity/'; then
  mapfile -t headers < <(git ls-files 'core/*.hpp' 'server/*.hpp' 'client/*.hpp')
  if ((${#headers[@]})) && grep -nHE '^[[:space:]]*#[[:space:]]*include[[:space:]]*[<"][^">]*\.(c|cc|cpp|cxx)[">]' "${headers[@]}"; then
    echo "tidy: a header includes an implementation file [bugprone-suspicious-include]"
    failed=1
  fi
fi
for tu in "${units[@]}"; do
  while (($(jobs -rp | wc -l) >= jobs)); do sleep 0.2; done
  { check_one "$tu" || echo "$tu" >>"$logs/failed.list"; } &
done
wait
[[ -s $logs/failed.list ]] && failed=1
if ((failed)); then
  echo "tidy: FAILED (logs in $logs)"
  exit 1
fi
echo "tidy: clean"
