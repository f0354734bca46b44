#!/usr/bin/env bash
# Resident memory of tinstream-viewer over a long scripted flight (issue #17: "RSS within the
# cache budgets plus a fixed overhead over a 5-minute scripted flight"), sampled from outside.
#
#   nice -n 10 bench/client/rss_flight.sh               5 minutes; results in $OUT (printed)
#   FLIGHT_S=60 SAMPLE_S=2 GPU_MB=16 CACHE_MB=16 bench/client/rss_flight.sh
#   STORE_IN=terrain.sqlite LAYER=alps bench/client/rss_flight.sh
#   VIEWER_ARGS="--heap-trim-ms -1" bench/client/rss_flight.sh   extra viewer options
#   REF_N=0 bench/client/rss_flight.sh                  no reference runs (default 3)
#
# tinstream-server serves the store on 127.0.0.1 (no delaying proxy: this measures memory, not
# latency). tinstream-viewer --headless flies analyze.py's flight (FLIGHT_S seconds, default 300,
# of 10-second legs back and forth over the layer at three heights, in real time; --threads 8,
# --max-sse SSE, --gpu-mb GPU_MB --cache-mb CACHE_MB: by default 0.25 px and 16 + 16 MB, which
# the flight over the client tests' DEM store fills, so both tiers evict and their LRU limit is
# what bounds the memory; at 2 px and 64 + 64 MB it never fills them) and writes one statistics
# line per frame (its own RSS, the tiers' bytes). From the first frame on, every SAMPLE_S
# seconds (default 5) this script reads the viewer's /proc/PID/status: VmRSS (resident now)
# and VmHWM (the kernel's peak so far, which also sees peaks between two samples).
# The report (analyze.py rss): RSS at the first sample, peak (VmHWM), at the end of the flight,
# per minute; the tiers' peaks and evictions against their budgets; and whether RSS stays
# bounded: the peak of the flight's last third against the peak of its middle third, and the
# least-squares slope of RSS over the last two thirds (MB per minute). A process that leaks
# per tile keeps climbing while the tiers stay at their budgets.
# Store (store.sh, as run.sh): STORE_IN + LAYER, else the client tests' DEM store
# ($BUILD/tests/client/stores/dem.sqlite: Big Tujunga SRTM 30 m, tests/client/make_stores.sh),
# else `tinstream ingest` of ../shared/data's Big Tujunga DEM into $OUT.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
HERE=$ROOT/bench/client
BUILD=${BUILD:-$ROOT/build}
BIN=${BIN:-$BUILD/bin}
OUT=${OUT:-$BUILD/bench-client-rss}
FLIGHT_S=${FLIGHT_S:-300}
SAMPLE_S=${SAMPLE_S:-5}
SIZE=${SIZE:-1280x720}
SSE=${SSE:-0.25}
GPU_MB=${GPU_MB:-16}
CACHE_MB=${CACHE_MB:-16}
read -r -a viewer_args <<< "${VIEWER_ARGS:-}"
mkdir -p "$OUT"
for b in tinstream-viewer tinstream-server tinstream; do
  [[ -x $BIN/$b ]] || { echo "rss_flight.sh: $BIN/$b is missing (cmake --build $BUILD --target $b)" >&2; exit 2; }
done

# shellcheck source=SCRIPTDIR/store.sh
source "$HERE/store.sh"
pick_store

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; wait "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
"$BIN/tinstream-server" --config "$ROOT/config/server.json" --store "$store" --address 127.0.0.1 \
  --port 0 > "$OUT/server.out" 2> "$OUT/server.log" &
pids+=($!)
for _ in $(seq 300); do grep -q "listening on" "$OUT/server.out" 2>/dev/null && break; sleep 0.1; done
port=$(sed -n 's/^listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$OUT/server.out" | head -1)
[[ -n $port ]] || { echo "rss_flight.sh: the server did not start" >&2; cat "$OUT/server.log" >&2; exit 1; }
url=http://127.0.0.1:$port
curl -fsS "$url/layers/$layer" > "$OUT/layer.json"
python3 "$HERE/analyze.py" cameras "$OUT/layer.json" "$OUT/flight.txt" "$FLIGHT_S" \
  "$OUT/unused_stream.txt" > /dev/null
echo "store $store, layer $layer, server $url; flying $FLIGHT_S s, RSS every $SAMPLE_S s"

started=$(date -u +%FT%TZ)
rm -f "$OUT/flight.jsonl"  # (a rerun into the same OUT: sampling waits for this run's first frame)
"$BIN/tinstream-viewer" --headless --url "$url" --layer "$layer" --size "$SIZE" --max-sse "$SSE" \
  --threads 8 --gpu-mb "$GPU_MB" --cache-mb "$CACHE_MB" --timeout 120 \
  --camera-path "$OUT/flight.txt" --out "$OUT/flight.png" --stats "$OUT/flight.jsonl" \
  "${viewer_args[@]}" 2> "$OUT/viewer.log" &
viewer=$!
pids+=("$viewer")
# Sampling starts with the first frame (before it: the process loading, the session opening).
until [[ -s $OUT/flight.jsonl ]] || ! kill -0 "$viewer" 2>/dev/null; do sleep 0.1; done
t0=$(date +%s.%N)
: > "$OUT/rss.tsv"  # seconds since the first frame, VmRSS kB, VmHWM kB
while kill -0 "$viewer" 2>/dev/null; do
  # A process that has exited but not been waited for has no VmRSS line: no sample.
  sample=$(awk '/^VmRSS:/ {r = $2} /^VmHWM:/ {h = $2} END {if (r != "") print r, h}' \
    "/proc/$viewer/status" 2>/dev/null || true)
  [[ -n $sample ]] && echo "$(awk -v a="$(date +%s.%N)" -v b="$t0" 'BEGIN {printf "%.1f", a - b}') $sample" >> "$OUT/rss.tsv"
  sleep "$SAMPLE_S"
done
status=0
wait "$viewer" || status=$?
pids=("${pids[@]:0:1}")
[[ $status == 0 ]] || { echo "rss_flight.sh: the viewer exited with $status" >&2; tail "$OUT/viewer.log" >&2; exit 1; }
# The restated target's reference (RESULTS.md, "RSS target on a software renderer"): REF_N
# (default 3; 0: none) of the flight's views that drew the most triangles, each a complete view in
# a fresh viewer with the same options (snapshot mode); its peak RSS less its tiers is what the
# process holds beside them for a full frame of a loaded view.
rm -f "$OUT"/ref-*.jsonl "$OUT"/ref-*.time
k=0
while read -r cam; do
  /usr/bin/time -f %M -o "$OUT/ref-$k.time" "$BIN/tinstream-viewer" --headless --url "$url" \
    --layer "$layer" --size "$SIZE" --max-sse "$SSE" --threads 8 --gpu-mb "$GPU_MB" \
    --cache-mb "$CACHE_MB" --timeout 60 --camera "$cam" --out "$OUT/ref-$k.png" \
    --stats "$OUT/ref-$k.jsonl" "${viewer_args[@]}" < /dev/null 2>> "$OUT/viewer.log" || true
  k=$((k + 1))
done < <(python3 "$HERE/analyze.py" heaviest "$OUT/flight.jsonl" "$OUT/flight.txt" "${REF_N:-3}")
python3 "$HERE/analyze.py" rss "$OUT" "$store" "$layer" "$SIZE" "$SSE" "$started" \
  | tee "$OUT/report.md"
echo "results in $OUT (report.md)"
