#!/usr/bin/env bash
# Cold view A/B of two tinstream-viewer binaries (issue #17's 8 vs 1 threads), alternating every
# run: one tinstream-server and one delaying proxy for the whole set, then REPEAT rounds of
# "for each thread count in THREADS: viewer A, viewer B", each a fresh process on the cold near
# camera (run.sh's cold part). Alternating run by run, not by blocks of runs, puts A and B under
# the same load from the other processes on a shared machine.
#
#   VIEWER_A=/tmp/old/tinstream-viewer VIEWER_B=build/bin/tinstream-viewer bench/client/ab.sh
#   REPEAT=15 THREADS="8 1 2" DELAY_MS=30 ARGS_B="--prefetch-levels 6" bench/client/ab.sh
#
# VIEWER_A / VIEWER_B: the two binaries (default both $BIN/tinstream-viewer, e.g. to compare
# options with ARGS_A / ARGS_B). Results: $OUT/ab.jsonl (one line a run: viewer, threads, round,
# time_to_complete_s, the proxy's requests and bytes, the load average) and the medians printed
# by `analyze.py ab`. Store, SIZE, SSE, COLD_CAMERA, DELAY_MS and PROXY as in run.sh.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
HERE=$ROOT/bench/client
BUILD=${BUILD:-$ROOT/build}
BIN=${BIN:-$BUILD/bin}
OUT=${OUT:-$BUILD/bench-client-ab}
DELAY_MS=${DELAY_MS:-30}
REPEAT=${REPEAT:-10}
THREADS=${THREADS:-8 1}
SIZE=${SIZE:-1280x720}
SSE=${SSE:-0.25}
COLD_CAMERA=${COLD_CAMERA:-near}
VIEWER_A=${VIEWER_A:-$BIN/tinstream-viewer}
VIEWER_B=${VIEWER_B:-$BIN/tinstream-viewer}
read -r -a args_a <<< "${ARGS_A:-}"
read -r -a args_b <<< "${ARGS_B:-}"
if [[ -z ${PROXY:-} ]]; then
  if command -v node > /dev/null; then PROXY=node; else PROXY=python; fi
fi
mkdir -p "$OUT"
for b in "$VIEWER_A" "$VIEWER_B" "$BIN/tinstream-server"; do
  [[ -x $b ]] || { echo "ab.sh: $b is missing" >&2; exit 2; }
done

# shellcheck source=SCRIPTDIR/store.sh
source "$HERE/store.sh"
pick_store

# shellcheck source=SCRIPTDIR/serve.sh
source "$HERE/serve.sh"
start_server_and_proxy ab.sh
curl -fsS "$proxy/layers/$layer" > "$OUT/layer.json"
eval "$(python3 "$HERE/analyze.py" cameras "$OUT/layer.json" "$OUT/flight.txt" 60 "$OUT/stream.txt")"
case $COLD_CAMERA in
  far) cam=$CAM_FAR ;;
  near) cam=$CAM_NEAR ;;
  *) echo "ab.sh: COLD_CAMERA is far or near, not '$COLD_CAMERA'" >&2; exit 2 ;;
esac
echo "store $store, layer $layer, proxy $proxy (+$DELAY_MS ms), camera $cam"

: > "$OUT/ab.jsonl"
for r in $(seq "$REPEAT"); do
  for t in $THREADS; do
    for v in A B; do
      if [[ $v == A ]]; then bin=$VIEWER_A; extra=("${args_a[@]}"); else bin=$VIEWER_B; extra=("${args_b[@]}"); fi
      curl -fsS "$proxy/__reset" > /dev/null
      "$bin" --headless --url "$proxy" --layer "$layer" --size "$SIZE" --max-sse "$SSE" \
        --timeout 900 --threads "$t" --camera "$cam" --out "$OUT/shot.png" \
        --stats "$OUT/run.json" "${extra[@]}" > /dev/null 2>> "$OUT/viewer.log"
      python3 -c 'import json,sys; v=json.load(open(sys.argv[1])); p=json.loads(sys.argv[2]); print(json.dumps({"viewer": sys.argv[3], "threads": int(sys.argv[4]), "round": int(sys.argv[5]), "time_to_complete_s": v["time_to_complete_s"], "complete": v.get("complete"), "requests": p["requests"], "bytes": p["bytes"], "load": float(open("/proc/loadavg").read().split()[0])}))' \
        "$OUT/run.json" "$(curl -fsS "$proxy/__stats")" "$v" "$t" "$r" >> "$OUT/ab.jsonl"
    done
  done
  echo "round $r of $REPEAT done"
done
python3 "$HERE/analyze.py" ab "$OUT/ab.jsonl" | tee "$OUT/ab.md"
