#!/usr/bin/env bash
# Crash safety of `tinstream ingest` (#22): SIGKILLs a replacing ingest at random moments and
# checks, after every kill:
#   - the store passes PRAGMA integrity_check;
#   - the layer is either the version before, byte for byte, or the new one complete — byte for
#     byte what an uninterrupted ingest of the same input publishes — never partial;
#   - `tinstream verify` passes on it;
# and at the end that a re-run succeeds, publishes the reference bytes and leaves no abandoned
# version or temporary directory. Each kill replaces the layer with the other of two inputs, so
# every moment of an ingest (reading, sorting, triangulating, the pyramid, publishing) is a target.
#   tests/cli/crash_safety.sh [--build DIR] [--kills N] [--seed S] [--keep]
# CTest runs it with 20 kills (CrashSafety.IngestKilledAtRandomMoments); run it by hand with
# --kills 200 or more. Exit status 1 on the first violation, with what was seen.
set -euo pipefail

build=build
kills=20
seed=$$
keep=0
while (($#)); do
  case $1 in
    --build) build=$2; shift 2 ;;
    --kills) kills=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "crash_safety.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
tinstream=$(realpath "$build/bin/tinstream")
[[ -x $tinstream ]] || { echo "crash_safety.sh: no $tinstream (build it first)" >&2; exit 2; }
command -v sqlite3 >/dev/null || { echo "crash_safety.sh: sqlite3 is needed" >&2; exit 2; }

work=$(mktemp -d "${TMPDIR:-/tmp}/tinstream-crash-$$-XXXXXX")
cleanup() { if ((keep)); then echo "kept $work"; else rm -rf "$work"; fi; }
trap cleanup EXIT
RANDOM=$seed
echo "crash_safety: $kills kills, seed $seed, in $work"

fail() {
  echo "crash_safety: FAILED: $*" >&2
  keep=1
  exit 1
}

# Two inputs: a small one and one big enough that an ingest takes a few seconds.
"$tinstream" sample --out "$work/a.las" --points 20000 --seed 1 >/dev/null
"$tinstream" sample --out "$work/b.las" --points 150000 --seed 2 >/dev/null

ingest_args=(ingest -q --layer crash --threads 2 --max-points 2000 --tmp "$work/tmp")
ingest() {  # store input
  "$tinstream" "${ingest_args[@]}" --store "$1" "$2" >/dev/null
}
# The layer's published tiles, one hash (an empty layer or store hashes the empty string).
fingerprint() {
  sqlite3 "$1" "SELECT z, x, y, hex(data) FROM published_tiles WHERE layer = 'crash' ORDER BY z, x, y" \
    2>/dev/null | md5sum | cut -d' ' -f1
}

# References: each input ingested without interruption, and how long the big one takes.
ingest "$work/ref_a.sqlite" "$work/a.las"
start=$(date +%s%N)
ingest "$work/ref_b.sqlite" "$work/b.las"
duration_ms=$((($(date +%s%N) - start) / 1000000))
ref_a=$(fingerprint "$work/ref_a.sqlite")
ref_b=$(fingerprint "$work/ref_b.sqlite")
[[ $ref_a != "$ref_b" ]] || fail "the two inputs give the same layer"
echo "crash_safety: an uninterrupted ingest of b takes ${duration_ms} ms"

store=$work/store.sqlite
ingest "$store" "$work/a.las"
current=a
declare -A outcome=([before]=0 [after]=0)
for ((k = 1; k <= kills; k++)); do
  if [[ $current == a ]]; then target=b; else target=a; fi
  declare -n ref_current=ref_$current ref_target=ref_$target
  # Uniform over the whole ingest and a little after it (a kill after the end must find it done).
  delay_ms=$(((RANDOM * 32768 + RANDOM) % (duration_ms * 115 / 100 + 1)))
  # A simple command in the background: $! is the ingest itself, not a subshell around it.
  "$tinstream" "${ingest_args[@]}" --store "$store" "$work/$target.las" 2>/dev/null &
  pid=$!
  sleep "$(printf '%d.%03d' $((delay_ms / 1000)) $((delay_ms % 1000)))"
  kill -KILL "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true

  check=$(sqlite3 "$store" "PRAGMA integrity_check")
  [[ $check == ok ]] || fail "kill $k at ${delay_ms} ms: integrity_check says: $check"
  now=$(fingerprint "$store")
  if [[ $now == "$ref_current" ]]; then
    outcome[before]=$((outcome[before] + 1))
  elif [[ $now == "$ref_target" ]]; then
    outcome[after]=$((outcome[after] + 1))
    current=$target
  else
    fail "kill $k at ${delay_ms} ms: the layer is neither the version before nor the new one complete"
  fi
  "$tinstream" verify --store "$store" --layer crash -q >/dev/null \
    || fail "kill $k at ${delay_ms} ms: verify fails on the published layer"
  unset -n ref_current ref_target
done

# A re-run completes, publishes the reference, and cleans up after the killed ones.
if [[ $current == a ]]; then target=b; else target=a; fi
ingest "$store" "$work/$target.las" || fail "the re-run after $kills kills failed"
declare -n ref_final=ref_$target
[[ $(fingerprint "$store") == "$ref_final" ]] || fail "the re-run published other tiles than the reference"
building=$(sqlite3 "$store" "SELECT count(*) FROM layer_versions WHERE status = 'building'")
[[ $building == 0 ]] || fail "$building abandoned versions left after the re-run"
left=$(find "$work/tmp" -maxdepth 1 -name 'tinstream-ingest-*' | wc -l)
[[ $left == 0 ]] || fail "$left abandoned temporary directories left after the re-run"
[[ $(sqlite3 "$store" "PRAGMA integrity_check") == ok ]] || fail "integrity_check after the re-run"
echo "crash_safety: ok: $kills kills (${outcome[before]} left the version before, ${outcome[after]} the new one complete), re-run ok"
