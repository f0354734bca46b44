#!/usr/bin/env bash
# The gist of a failed pipeline step's log, compact enough to survive in the tail CI shows:
# the failed CTest tests (or run_tests.sh executables), each with its first failure lines
# (GoogleTest failures, sanitizer reports, harness errors). Falls back to the log's last lines.
#   .ci/failure_digest.sh STEP_LOG
set -uo pipefail
log=$1
main() {
# CTest: "The following tests FAILED:" then "\t123 - Name (Failed)" lines.
mapfile -t tests < <(awk '/The following tests FAILED:/ { on = 1; next }
  on && /^[[:space:]]+[0-9]+ - / { sub(/^[[:space:]]+[0-9]+ - /, ""); sub(/ \(.*$/, ""); print; next }
  on { on = 0 }' "$log" | head -n 12)
# run_tests.sh: "FAILED  name: path".
mapfile -t -O "${#tests[@]}" tests < <(sed -n 's/^FAILED  \([^:]*\): .*/\1/p' "$log" | head -n 12)
if ((${#tests[@]} == 0)); then
  tail -n 25 "$log"
  return 0
fi
pattern='\*\*\*|Failure|FAILED|Expected|Which is|Value of|error:|ERROR|WARNING: ThreadSanitizer|runtime error|Assertion|Timeout|timed out|Killed|Segmentation|terminate|what\(\)|not ok|FAIL|^ +#[0-9]+ (0x[0-9a-f]+ in )?tinstream::'
for t in "${tests[@]}"; do
  echo "--- $t"
  # CTest's --output-on-failure block of the test: from its result line to the next result line.
  awk -v name="$t" '
    /^ *[0-9]+\/[0-9]+ Test +#[0-9]+: / { on = (index($0, " " name " ") > 0); if (on) print; next }
    on' "$log" | grep -E "$pattern" | grep -v '^\[  FAILED  \] .* tests\?, listed below' | head -n 10
  # run_tests.sh prints an executable's failure lines right after its FAILED line.
  grep -F -A 12 "FAILED  $t: " "$log" | tail -n +2 | grep -v '^FAILED  \|^ok  ' | head -n 10
done
}
main | sed "s/\.\{4,\}/ ... /g" | cut -c 1-240  # CTest's dot leaders; a build's command lines can be kilobytes long
