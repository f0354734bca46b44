#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan, asserts on) and runs each for a while, several
# at once, then prints what each did: executions, coverage, corpus, peak memory, and any crash.
#   scripts/fuzz.sh                       every target for 60 s (what CI runs: make fuzz)
#   scripts/fuzz.sh --seconds 1800        longer
#   scripts/fuzz.sh --runs 10000000       a fixed number of executions per target (a long run)
#   scripts/fuzz.sh --runs 10000000 --procs 16 --jobs 1
#                                         the long run on a many-core machine: 16 processes per
#                                         target sharing its corpus (-reload=1), the runs split
#                                         between them (docs/SECURITY.md, "The long run")
#   scripts/fuzz.sh --only kernel_fuzzer,qmesh_fuzzer --jobs 1   (--targets is the same option)
#   scripts/fuzz.sh --bin-dir DIR --procs 16 --seconds 600 --targets laz_fuzzer,kernel_fuzzer
#                                         prebuilt binaries on a machine without cmake: DIR holds
#                                         the *_fuzzer binaries and the build's fuzzers.tsv (copy
#                                         build-fuzz/bin/*_fuzzer and build-fuzz/fuzzers.tsv); the
#                                         tsv's source paths (corpora, dictionaries, regressions)
#                                         are found again in this checkout. Implies --no-build.
#                                         Exits 2 when a selected binary is not in DIR or needs
#                                         a shared library that is not installed.
#   scripts/fuzz.sh --seed 1              libFuzzer's random seed (default: a new one each run).
#                                         CI passes --seed 1 and a fresh corpus: the same inputs in
#                                         the same order every time, so its result does not depend
#                                         on luck; exploration is the long runs' job.
# Options: --build DIR (default build-fuzz), --out DIR (default DIR/fuzz-out), --no-build,
#          --jobs N (targets at once; default: the number of cores).
# Targets are whatever cmake/TinstreamFuzz.cmake registered (build-fuzz/fuzzers.tsv): a module
# adds one with tinstream_add_fuzzer() in its fuzz/CMakeLists.txt and nothing else.
# Each target works on a corpus of its own in OUT/<target>/corpus, seeded from its checked-in
# corpus and regressions/. Exit status 1 when any target found a crash, leak, timeout or
# out-of-memory: the input is in OUT/<target>/artifacts/. Fix the bug, then copy the input into
# the target's regressions/ folder: the replay test (Fuzz.<target>.Replay, every test build) then
# runs it forever after. A summary table is written to OUT/summary.tsv.
set -euo pipefail
cd "$(dirname "$0")/.."

build=build-fuzz
out=
seconds=60
runs=
seed=
jobs=$(nproc)
procs=1
only=
do_build=1
bin_dir=
while (($#)); do
  case $1 in
    --seconds) seconds=$2; shift 2 ;;
    --minutes) seconds=$(($2 * 60)); shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --procs) procs=$2; shift 2 ;;
    --only|--targets) only=$2; shift 2 ;;
    --bin-dir) bin_dir=$2; do_build=0; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --no-build) do_build=0; shift ;;
    -h|--help) sed -n '2,32p' "$0"; exit 0 ;;
    *) echo "fuzz.sh: unknown option $1 (--help)" >&2; exit 2 ;;
  esac
done
if [[ -n $bin_dir ]]; then
  [[ $bin_dir == /* ]] || bin_dir=$OLDPWD/$bin_dir  # given from the caller's directory
  [[ -f $bin_dir/fuzzers.tsv ]] || { echo "fuzz.sh: no $bin_dir/fuzzers.tsv (copy build-fuzz/fuzzers.tsv there)" >&2; exit 2; }
  out=${out:-$bin_dir/fuzz-out}
fi
out=${out:-$build/fuzz-out}
tsv=${bin_dir:-$build}/fuzzers.tsv
# A source path of the machine that configured the build, found again in this checkout: the
# longest tail of it that exists here (unchanged when it exists as it is).
local_path() {
  local p=$1 rest
  if [[ $p == - || -e $p ]]; then echo "$p"; return; fi
  rest=${p#/}
  while [[ $rest == */* ]]; do
    rest=${rest#*/}
    [[ -e $rest ]] && { echo "$PWD/$rest"; return; }
  done
  echo "$p"
}

if ((do_build)); then
  if [[ ! -f $build/build.ninja ]]; then
    # -O1 without NDEBUG: the asserts (programmer errors) are fuzzed too. -g1 (line tables: every
    # report's frames keep file:line) compiles in 12% less CPU than -g (4 of the heaviest TUs,
    # clang 14, 2026-11-28: 67 s against 76 s).
    cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
      -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1" \
      -DTINSTREAM_FUZZ=ON -DTINSTREAM_BUILD_TESTS=OFF -DTINSTREAM_BUILD_CLIENT=OFF \
      -DTINSTREAM_WERROR=OFF >/dev/null
  fi
  cmake --build "$build" --target fuzzers -j "$(nproc)"
fi
[[ -f $tsv ]] || { echo "fuzz.sh: no $tsv (configure with TINSTREAM_FUZZ=ON)" >&2; exit 2; }

mkdir -p "$out"
declare -a names=()
while IFS=$'\t' read -r name _; do
  [[ -z $name ]] && continue
  if [[ -n $only && ",$only," != *",$name,"* ]]; then continue; fi
  names+=("$name")
done <"$tsv"
((${#names[@]})) || { echo "fuzz.sh: no target selected" >&2; exit 2; }
if [[ -n $bin_dir ]]; then  # every selected binary copied? (the tsv lists every configured one)
  missing=()
  for name in "${names[@]}"; do [[ -x $bin_dir/$name ]] || missing+=("$name"); done
  if ((${#missing[@]})); then
    echo "fuzz.sh: not in $bin_dir: ${missing[*]} (copy build-fuzz/bin/NAME, or choose with --targets)" >&2
    exit 2
  fi
  # Built elsewhere: the shared libraries they link (GDAL, PROJ, SQLite: ~110 for most targets)
  # must be installed here too, or every run fails at once.
  if command -v ldd >/dev/null; then
    for name in "${names[@]}"; do
      unresolved=$(ldd "$bin_dir/$name" 2>/dev/null | awk '/not found/ {print $1}' | tr '\n' ' ')
      [[ -z $unresolved ]] || { echo "fuzz.sh: $name needs $unresolved(install them)" >&2; exit 2; }
    done
  fi
fi

run_one() {
  local name=$1 line bin max_len timeout dict regressions
  line=$(grep -P "^$name\t" "$tsv")
  IFS=$'\t' read -r -a f <<<"$line"
  if [[ -n $bin_dir ]]; then
    f[1]=$bin_dir/$name
    local k
    for ((k = 4; k < ${#f[@]}; k++)); do f[k]=$(local_path "${f[k]}"); done
  fi
  bin=${f[1]} max_len=${f[2]} timeout=${f[3]} dict=${f[4]} regressions=${f[5]}
  local seeds=("${f[@]:6}")
  [[ -d $regressions ]] && seeds+=("$regressions")
  local dir=$out/$name
  rm -rf "$dir/artifacts"
  mkdir -p "$dir/corpus" "$dir/artifacts"
  local args=(-timeout="$timeout" -max_len="$max_len" -rss_limit_mb=2048 -print_final_stats=1
              -artifact_prefix="$dir/artifacts/")
  if [[ -n $runs ]]; then args+=(-runs="$(((runs + procs - 1) / procs))"); else args+=(-max_total_time="$seconds"); fi
  [[ $dict != - ]] && args+=(-dict="$dict")
  ((procs > 1)) && args+=(-reload=1)
  rm -f "$dir"/log.*
  local start=$SECONDS rc=0 i pids=()
  for ((i = 1; i <= procs; i++)); do
    local seed_arg=()
    [[ -n $seed ]] && seed_arg=(-seed="$((seed + i - 1))")
    "$bin" "${args[@]}" "${seed_arg[@]}" "$dir/corpus" "${seeds[@]}" >"$dir/log.$i" 2>&1 &
    pids+=($!)
  done
  for pid in "${pids[@]}"; do wait "$pid" || rc=$?; done
  echo "$((SECONDS - start))" >"$dir/seconds"
  echo "$rc" >"$dir/rc"
}

if [[ -n $runs ]]; then budget="$runs runs"; else budget="$seconds s"; fi
echo "fuzz.sh: ${#names[@]} targets, $budget each, $jobs at a time -> $out"
running=0
for name in "${names[@]}"; do
  run_one "$name" &
  running=$((running + 1))
  if ((running >= jobs)); then wait -n || true; running=$((running - 1)); fi
done
wait

status=0
printf '%-22s %8s %14s %10s %8s %8s %8s %s\n' target seconds executions exec/s cov corpus rss_mb result \
  | tee "$out/summary.txt"
printf 'target\tseconds\texecutions\texec_per_s\tcov\tcorpus\tpeak_rss_mb\tresult\n' >"$out/summary.tsv"
for name in "${names[@]}"; do
  dir=$out/$name
  log=$dir/log.1
  # Summed over the target's processes (--procs); peak memory and coverage: the largest.
  execs=$(cat "$dir"/log.* | grep -o 'stat::number_of_executed_units: [0-9]*' | awk '{s += $2} END {if (NR) print s}' || true)
  rss=$(cat "$dir"/log.* | grep -oE 'stat::peak_rss_mb: *[0-9]+' | awk '$2 > m {m = $2} END {if (NR) print m}' || true)
  cov=$(cat "$dir"/log.* | grep -oE 'cov: [0-9]+' | awk '$2 > m {m = $2} END {if (NR) print m}' || true)
  corpus=$(find "$dir/corpus" -type f | wc -l)
  secs=$(cat "$dir/seconds")
  rc=$(cat "$dir/rc")
  result=ok
  if [[ $rc != 0 ]] || [[ -n $(find "$dir/artifacts" -type f 2>/dev/null) ]]; then
    result="FAILED (rc $rc, see $dir/artifacts and $log)"
    status=1
  fi
  rate=$(( ${execs:-0} / (secs > 0 ? secs : 1) ))
  printf '%-22s %8s %14s %10s %8s %8s %8s %s\n' "$name" "$secs" "${execs:-?}" "$rate" \
    "${cov:-?}" "$corpus" "${rss:-?}" "$result" | tee -a "$out/summary.txt"
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$secs" "${execs:-}" "$rate" "${cov:-}" \
    "$corpus" "${rss:-}" "$result" >>"$out/summary.tsv"
done
exit $status
