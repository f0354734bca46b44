#!/usr/bin/env bash
# Client benchmark (issue #17): tinstream-viewer --headless streaming from tinstream-server through
# a loopback proxy that holds every request 30 ms (proxy.mjs), so the server looks 30 ms away.
#
#   bench/client/run.sh                      everything below, results in $OUT (printed at the end)
#   BUILD=build REPEAT=3 FLIGHT_S=300 bench/client/run.sh
#   STORE_IN=terrain.sqlite LAYER=alps bench/client/run.sh
#   CESIUM=0 bench/client/run.sh             leave out the CesiumJS peer
#   PARTS=memory FLIGHT_S=60 bench/client/run.sh   only some of the parts below (cold stream
#                                            memory cesium; default all of them)
#   FLIGHT_ARGS="--heap-trim-ms -1" MALLOC_ARENA_MAX=64 PARTS=memory bench/client/run.sh
#                                            the flight with extra viewer options / environment
#   DELAY_MS=100 PARTS=cold bench/client/run.sh
#                                            the cold part with 100 ms added to each request (the
#                                            network latency knob: proxy.mjs holds every request
#                                            DELAY_MS, default 30); COLD_ARGS= adds viewer options
#                                            to its runs (e.g. --prefetch-levels 0)
#   PROXY=python bench/client/run.sh         the delaying proxy in Python 3 (proxy.py, standard
#                                            library only; the default when node is missing)
#                                            instead of proxy.mjs: same delay, counters, /__stats
#                                            and /__reset
#   COLD_CAMERA=far SSE=2 PARTS=cold bench/client/run.sh
#                                            the defaults before 2026-11-28: the framing camera at
#                                            the viewer's default 2 px, which needs about one tile
#
# Defaults: COLD_CAMERA=near (the close oblique view over the layer, COLD_CAMERA far|near) and
# SSE=0.25 (--max-sse, px, for every part, the memory flight and CesiumJS included), so that the
# cold and stream parts measure many tiles: on the client tests' DEM store (Big Tujunga) at
# 1280x720 the cold view loads ~59 tiles over 14 levels and the stream part's path streams 77
# (2026-11-28) — under the issue's "≥ 100 tiles stream in" on that small store; SSE=0.125
# streams 107 there. The far camera at 2 px needs one tile, which says
# nothing about download threads.
#
# 1. cold time to a complete view, --threads 8 vs --threads 1, REPEAT times alternating (each run a
#    fresh process: empty RAM and GPU tiers, no disk tier): time_to_complete_s from the viewer's
#    statistics, requests and bytes counted by the proxy;
# 2. the render thread while tiles stream in: a camera path that starts cold at a close view
#    (`wait complete`), then stays 5 s on it fully loaded; the frame times (stream update + draw +
#    glFinish) while streaming vs on the same view loaded (median, p95, p99, worst), and the
#    streaming part of each frame alone (update_ms: take results, select, upload);
# 3. memory: a scripted flight of FLIGHT_S seconds (default 300) back and forth over the layer
#    at several heights with small budgets (--gpu-mb GPU_MB --cache-mb CACHE_MB, 64 each by
#    default): RSS per frame against the budgets (the GPU tier lives in process memory with
#    Mesa) plus the RSS of the first frame;
# 4. CesiumJS (npm cesium in Debian's headless chromium, playwright-core; bench/client/cesium.html)
#    on the same layer's Cesium terrain endpoint, the cold part's camera, viewport, fov and maximum
#    screen-space error, through the same proxy: time to a complete view and bytes (CESIUM=1,
#    default when chromium and node are there; `npm install` in bench/client once;
#    CESIUM_TIMEOUT_S, default 600).
# Store: STORE_IN + LAYER, else the client tests' DEM store ($BUILD/tests/client/stores/dem.sqlite,
# Big Tujunga SRTM 30 m) when built, else `tinstream ingest` of ../shared/data's Big Tujunga DEM,
# else `tinstream sample`. Needs node or python3 (proxy), python3 (tables), the built tinstream-viewer,
# tinstream-server and tinstream in $BUILD/bin.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
HERE=$ROOT/bench/client
BUILD=${BUILD:-$ROOT/build}
BIN=${BIN:-$BUILD/bin}
OUT=${OUT:-$BUILD/bench-client}
DELAY_MS=${DELAY_MS:-30}
REPEAT=${REPEAT:-3}
FLIGHT_S=${FLIGHT_S:-300}
SIZE=${SIZE:-1280x720}
SSE=${SSE:-0.25}
COLD_CAMERA=${COLD_CAMERA:-near}
CESIUM=${CESIUM:-auto}
if [[ -z ${PROXY:-} ]]; then  # the delaying proxy: proxy.mjs (node) or proxy.py (python3)
  if command -v node > /dev/null; then PROXY=node; else PROXY=python; fi
fi
PARTS=${PARTS:-cold stream memory cesium}
GPU_MB=${GPU_MB:-64}      # the flight's tier budgets
CACHE_MB=${CACHE_MB:-64}
read -r -a flight_args <<< "${FLIGHT_ARGS:-}"
read -r -a cold_args <<< "${COLD_ARGS:-}"
mkdir -p "$OUT"
part() { [[ " $PARTS " == *" $1 "* ]]; }
# A part left out leaves no results of an earlier run behind for the report.
part cold || rm -f "$OUT"/cold.jsonl "$OUT"/cold_t*
part stream || rm -f "$OUT"/stream.jsonl "$OUT"/stream.png
part memory || rm -f "$OUT"/flight.jsonl "$OUT"/flight.maxrss_kb "$OUT"/flight.png
part cesium || { CESIUM=0; rm -f "$OUT"/cesium.jsonl "$OUT"/cesium_*.png; }
for b in tinstream-viewer tinstream-server tinstream; do
  [[ -x $BIN/$b ]] || { echo "run.sh: $BIN/$b is missing (cmake --build $BUILD --target $b)" >&2; exit 2; }
done

# --- the store ---
# shellcheck source=SCRIPTDIR/store.sh
source "$HERE/store.sh"
pick_store
echo "store $store, layer $layer"

# --- server and proxy ---
# shellcheck source=SCRIPTDIR/serve.sh
source "$HERE/serve.sh"
start_server_and_proxy run.sh --static "$HERE"
curl -fsS "$proxy/layers/$layer" > "$OUT/layer.json"
echo "server :$server_port, proxy $proxy ($PROXY, +$DELAY_MS ms per request)"

# Cameras from the layer's bounds: the framing view, a close oblique view, and a flight.
eval "$(python3 "$HERE/analyze.py" cameras "$OUT/layer.json" "$OUT/flight.txt" "$FLIGHT_S" \
  "$OUT/stream.txt")"
echo "cameras: far $CAM_FAR, near $CAM_NEAR"
case $COLD_CAMERA in
  far) CAM_COLD=$CAM_FAR ;;
  near) CAM_COLD=$CAM_NEAR ;;
  *) echo "run.sh: COLD_CAMERA is far or near, not '$COLD_CAMERA'" >&2; exit 2 ;;
esac

viewer() { "$BIN/tinstream-viewer" --headless --url "$proxy" --layer "$layer" --size "$SIZE" \
  --max-sse "$SSE" --timeout 900 "$@"; }
proxy_stats() { curl -fsS "$proxy/__stats"; }

# CPU seconds (user + system) a process has used so far, from /proc/PID/stat (Linux).
cpu_s() { awk -v hz="$(getconf CLK_TCK)" '{ sub(/^.*\) /, ""); printf "%.3f", ($12 + $13) / hz }' \
  "/proc/$1/stat" 2>/dev/null || echo -1; }

# --- 1. cold time to a complete view ---
# TIMELINE=1: each cold run also writes its request timeline (--timeline, cold_tT_R.timeline).
if part cold; then
: > "$OUT/cold.jsonl"
for r in $(seq "$REPEAT"); do
  for t in 8 1; do
    curl -fsS "$proxy/__reset" > /dev/null
    timeline_args=()
    [[ ${TIMELINE:-0} == 1 ]] && timeline_args=(--timeline "$OUT/cold_t${t}_$r.timeline")
    server_cpu0=$(cpu_s "${pids[0]}") proxy_cpu0=$(cpu_s "${pids[1]}")
    viewer --threads "$t" --camera "$CAM_COLD" --out "$OUT/cold_t${t}_$r.png" \
      --stats "$OUT/cold_t${t}_$r.json" "${timeline_args[@]}" "${cold_args[@]}"
    # The server's and the proxy's CPU over the run (the final draw and PNG included).
    others=$(python3 -c 'import json,sys; a=[float(x) for x in sys.argv[1:]]; print(json.dumps({"server_s": round(a[1] - a[0], 3), "proxy_s": round(a[3] - a[2], 3)}))' \
      "$server_cpu0" "$(cpu_s "${pids[0]}")" "$proxy_cpu0" "$(cpu_s "${pids[1]}")")
    python3 -c 'import json,sys; v=json.load(open(sys.argv[1])); p=json.loads(sys.argv[2]); print(json.dumps({"threads": int(sys.argv[3]), "run": int(sys.argv[4]), "viewer": v, "proxy": p, "cpu_others": json.loads(sys.argv[5]), "load": open("/proc/loadavg").read().split()[0]}))' \
      "$OUT/cold_t${t}_$r.json" "$(proxy_stats)" "$t" "$r" "$others" >> "$OUT/cold.jsonl"
    echo "cold, $t threads, run $r: $(python3 -c 'import json,sys; v=json.load(open(sys.argv[1])); print(v["time_to_complete_s"], "s,", v["tiles"]["loaded"], "tiles")' "$OUT/cold_t${t}_$r.json")"
  done
done
fi

# --- 2. frame times while streaming vs loaded (8 threads) ---
if part stream; then
  curl -fsS "$proxy/__reset" > /dev/null
  # --fps 1: the path's 5 loaded seconds are 5 frames, however slow the renderer (llvmpipe).
  viewer --threads 8 --fps 1 --camera-path "$OUT/stream.txt" --out "$OUT/stream.png" \
    --stats "$OUT/stream.jsonl"
fi

# --- 3. memory over a scripted flight ---
if part memory; then
  curl -fsS "$proxy/__reset" > /dev/null
  /usr/bin/time -f '%M' -o "$OUT/flight.maxrss_kb" \
    "$BIN/tinstream-viewer" --headless --url "$proxy" --layer "$layer" --size "$SIZE" \
    --max-sse "$SSE" --threads 8 --gpu-mb "$GPU_MB" --cache-mb "$CACHE_MB" --timeout 120 \
    --camera-path "$OUT/flight.txt" --out "$OUT/flight.png" --stats "$OUT/flight.jsonl" \
    "${flight_args[@]}"
fi

# --- 4. CesiumJS ---
if [[ $CESIUM == auto ]]; then
  if [[ -x /usr/bin/chromium && -d $HERE/node_modules/cesium && -d $HERE/node_modules/playwright-core ]]; then
    CESIUM=1
  else
    CESIUM=0
    echo "CesiumJS: left out (needs /usr/bin/chromium and 'npm ci' in bench/client)"
  fi
fi
: > "$OUT/cesium.jsonl"
if [[ $CESIUM == 1 ]]; then
  IFS=, read -r lon lat h hd p <<< "$CAM_COLD"  # the cold part's camera
  for r in $(seq "$REPEAT"); do
    node "$HERE/cesium_run.mjs" --proxy "$proxy" --layer "$layer" --camera "$lon,$lat,$h,$hd,$p" \
      --sse "$SSE" --size "$SIZE" --timeout-s "${CESIUM_TIMEOUT_S:-600}" --shot "$OUT/cesium_$r.png" \
      | tee -a "$OUT/cesium.jsonl" || echo "CesiumJS run $r: failed (see the line above)"
  done
fi

python3 "$HERE/analyze.py" report "$OUT" "$layer" "$store" "$DELAY_MS" "$SIZE" "$SSE" "$FLIGHT_S" \
  | tee "$OUT/report.md"
echo "results in $OUT (report.md)"
