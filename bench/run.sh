#!/usr/bin/env bash
# `make bench`: runs the benchmarks side by side with their peers, one after the other; each prints
# its own tables (bench/README.md explains them, each folder's RESULTS.md keeps the last run).
#   bench/run.sh [--help] [NAME...]   NAME: kernel lod laz server client ingest (default: all)
# Each bench builds what it needs; the server bench installs nginx/wrk (install-deps --bench).
# Not a test: the numbers depend on the machine and its load.
set -euo pipefail
cd "$(dirname "$0")/.."
all=(kernel lod laz server client ingest)
if [[ ${1:-} == --help || ${1:-} == -h ]]; then sed -n '2,6p' "$0" | cut -c3-; exit 0; fi
names=("$@")
((${#names[@]})) || names=("${all[@]}")
failed=()
for n in "${names[@]}"; do
  echo "=== bench: $n"
  case $n in
    kernel)
      { cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTINSTREAM_BUILD_BENCH=ON \
          && cmake --build build-bench --target kernel_bench && build-bench/bin/kernel_bench; } || failed+=("$n") ;;
    lod | laz | client | ingest) bash "bench/$n/run.sh" || failed+=("$n") ;;
    server) { bash scripts/install-deps.sh --bench && bash bench/server/run.sh; } || failed+=("$n") ;;
    *) echo "bench/run.sh: unknown bench '$n' (known: ${all[*]})" >&2; exit 2 ;;
  esac
done
if ((${#failed[@]})); then echo "=== bench: FAILED: ${failed[*]}"; exit 1; fi
echo "=== bench: done"
