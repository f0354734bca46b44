#!/usr/bin/env bash
# Runs GoogleTest executables of a build directory directly (every test of one executable in one
# process), as many at once as there are cores, each into its own log; prints the failures' logs
# and exits 1 if any executable fails. `make tsan` runs the threaded suites this way: one process
# per executable instead of one per test keeps ThreadSanitizer's start-up cost to a few.
#   .ci/run_tests.sh BUILD_DIR test_executable...
set -uo pipefail
build=$1
shift
logs=$build/test-logs
mkdir -p "$logs"
# tsan.supp: reports whose every frame is in a library we do not build (it says which and why).
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$(cd "$(dirname "$0")" && pwd)/tsan.supp ${TSAN_OPTIONS:-}"
export ASAN_OPTIONS="detect_leaks=1 ${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1 halt_on_error=1 ${UBSAN_OPTIONS:-}"
jobs=$(nproc)
pids=()
names=()
for t in "$@"; do
  while (($(jobs -rp | wc -l) >= jobs)); do wait -n || true; done
  ( start=$SECONDS
    "$build/bin/$t" --gtest_color=no >"$logs/$t.log" 2>&1
    rc=$?
    echo "$t: exit $rc in $((SECONDS - start)) s" >>"$logs/$t.log"
    exit $rc ) &
  pids+=($!)
  names+=("$t")
done
status=0
for i in "${!pids[@]}"; do
  if wait "${pids[$i]}"; then
    echo "ok      ${names[$i]} ($(tail -n 1 "$logs/${names[$i]}.log"))"
  else
    echo "FAILED  ${names[$i]}: $logs/${names[$i]}.log"
    grep -E '^\[  FAILED  \]|WARNING: ThreadSanitizer|ERROR: AddressSanitizer|runtime error|^  (Previous )?([Rr]ead|[Ww]rite) of size|^ +#[0-9]+ (0x[0-9a-f]+ in )?tinstream::' \
      "$logs/${names[$i]}.log" | head -n 20
    status=1
  fi
done
exit $status
