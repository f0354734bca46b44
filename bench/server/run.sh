#!/usr/bin/env bash
# Serving benchmark: tinstream-server vs nginx serving the same Cesium terrain tiles on loopback.
#
#   bench/server/run.sh            build, make a store, export it, run wrk at 64 and 256 connections
#   DURATION=30 bench/server/run.sh
#   BUILD=build SKIP_BUILD=1 bench/server/run.sh
#   PIN=0 bench/server/run.sh      only the shared configuration; PIN=1: only the pinned one
#
# Two configurations, each with its own table (default: shared, then pinned):
#   shared  wrk -t$THREADS, $THREADS io threads / nginx workers, all free to run on every core
#           (the load generator competes with the server for the same cores);
#   pinned  the load generator on its own core and the server on another, the standard way to
#           measure a server on a small machine: `taskset -c 1 wrk -t1`, tinstream-server (1 io
#           thread) and nginx (master + 1 worker) under `taskset -c 0`. Both servers get exactly the
#           same treatment. CPUs: SERVER_CPU=0 WRK_CPU=1.
#
# Store: STORE_IN=FILE LAYER=NAME, else `tinstream ingest` of ../shared/data/N00E010.hgt (SRTM,
# 1.4 M points, ~90 s on 2 cores) when the ingest pipeline and the file are there, else a synthetic
# layer (tinstream-bench-store). Static copy: `tinstream export
# --dir` (fallback: the tiles fetched from tinstream-server, byte-identical). Both servers get the
# same URL list (every tile), the same headers (gzip + octvertexnormals, as CesiumJS sends) and
# send the same bytes; tinstream-server answers from its LRU (warmed up first), nginx from the page
# cache with sendfile. RSS is sampled every 0.5 s (nginx: master + workers). Needs wrk, nginx,
# curl, python3 (scripts/install-deps.sh --bench). Server CPU per request (utime + stime from
# /proc during the run; nginx: master + workers) is recorded too: it depends far less than req/s
# on what else runs on the machine; so is wrk's (the load generator shares the cores).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${BUILD:-$ROOT/build-bench}
DURATION=${DURATION:-10}
THREADS=${THREADS:-2}
SERVER_CPU=${SERVER_CPU:-0}
WRK_CPU=${WRK_CPU:-1}
case ${PIN:-} in
  0) CONFIGS=shared ;;
  1) CONFIGS=pinned ;;
  *) CONFIGS="shared pinned" ;;
esac
if [[ $CONFIGS == *pinned* ]] && (( $(nproc) < 2 )); then
  echo "run.sh: the pinned configuration needs 2 CPUs; running the shared one only" >&2
  CONFIGS=shared
fi
SERVER_PORT=${SERVER_PORT:-18080}
NGINX_PORT=${NGINX_PORT:-18081}
WORK=$(mktemp -d /tmp/tinstream-bench.XXXXXX)
chmod 755 "$WORK"  # nginx workers run as an unprivileged user
SERVER_PID= NGINX_PID= SAMPLER=

cleanup() {
  [[ -n $SAMPLER ]] && kill "$SAMPLER" 2>/dev/null || true
  [[ -n $SERVER_PID ]] && kill "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null || true
  [[ -n $NGINX_PID ]] && kill "$NGINX_PID" 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

for tool in wrk nginx curl python3; do
  command -v "$tool" >/dev/null || { echo "run.sh: $tool missing (scripts/install-deps.sh --bench)" >&2; exit 1; }
done
NGINX=$(command -v nginx)

if [[ -z ${SKIP_BUILD:-} ]]; then
  cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$BUILD" --target tinstream-server tinstream-bench-store -j"$(nproc)"
  cmake --build "$BUILD" --target tinstream -j"$(nproc)" || echo "run.sh: tinstream CLI not built; using fallbacks"
fi
BIN=$BUILD/bin
CLI=${CLI:-$BIN/tinstream}  # the tinstream CLI (ingest, export --dir); may come from another build

# 1. A store: STORE_IN=FILE LAYER=NAME reuses one; else `tinstream ingest` of a real SRTM tile;
#    else a synthetic layer.
STORE=$WORK/bench.db
LAYER=${LAYER:-bench}
DEM=${DEM:-$ROOT/../shared/data/N00E010.hgt}
if [[ -n ${STORE_IN:-} ]]; then
  cp "$STORE_IN" "$STORE"
  SOURCE="$(basename "$STORE_IN") (layer $LAYER, given)"
elif [[ -x $CLI && -f $DEM ]] &&
   "$CLI" ingest --store "$STORE" --layer "$LAYER" --max-points 8192 --quiet "$DEM" >"$WORK/ingest.log" 2>&1; then
  SOURCE="$(basename "$DEM") via tinstream ingest --max-points 8192"
else
  rm -f "$STORE"*
  "$BIN/tinstream-bench-store" "$STORE" "$LAYER" >/dev/null
  SOURCE="synthetic layer (tinstream-bench-store: 336 tiles, 65×65 grids)"
fi

# 2. tinstream-server: start_tinstream THREADS [CPU] (CPU: pinned there with taskset).
BASE=http://127.0.0.1:$SERVER_PORT
pinned_to() { [[ -n ${1:-} ]] && echo taskset -c "$1"; }  # the command prefix, or nothing
start_tinstream() {
  cat >"$WORK/server.json" <<JSON
{"address": "127.0.0.1", "port": $SERVER_PORT, "threads": $1, "access_log": false,
 "log_level": "warn", "terrain_cache_bytes": 536870912, "max_connections": 4096}
JSON
  : >"$WORK/server.out"
  $(pinned_to "${2:-}") "$BIN/tinstream-server" --config "$WORK/server.json" --store "$STORE" \
    >"$WORK/server.out" 2>"$WORK/server.err" &
  SERVER_PID=$!
  for _ in $(seq 100); do grep -q listening "$WORK/server.out" 2>/dev/null && break; sleep 0.1; done
}
stop_servers() {
  [[ -n $SERVER_PID ]] && kill "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null || true
  [[ -n $NGINX_PID ]] && kill "$NGINX_PID" 2>/dev/null && wait "$NGINX_PID" 2>/dev/null || true
  SERVER_PID= NGINX_PID=
  sleep 0.5
}
start_tinstream "$THREADS"

# 3. The tile list (from layer.json) and the static copy.
curl -sf --compressed "$BASE/tiles/$LAYER/layer.json" >"$WORK/layer.json"
python3 - "$WORK/layer.json" >"$WORK/paths.txt" <<'PY'
import json, sys
doc = json.load(open(sys.argv[1]))
for z, ranges in enumerate(doc["available"]):
    for r in ranges:
        for x in range(r["startX"], r["endX"] + 1):
            for y in range(r["startY"], r["endY"] + 1):
                print(f"/{z}/{x}/{y}.terrain")
PY
STATIC=$WORK/static
if [[ -x $CLI ]] && "$CLI" export --store "$STORE" --layer "$LAYER" --dir "$STATIC" >"$WORK/export.log" 2>&1; then
  EXPORT="tinstream export --dir"
else
  EXPORT="fetched from tinstream-server (export --dir unavailable)"
  while read -r p; do
    mkdir -p "$STATIC$(dirname "$p")"
    curl -sf -H 'Accept-Encoding: gzip' -H 'Accept: application/vnd.quantized-mesh;extensions=octvertexnormals' \
      -o "$STATIC$p" "$BASE/tiles/$LAYER$p"
  done <"$WORK/paths.txt"
fi
TILES=$(wc -l <"$WORK/paths.txt")
BYTES=$(du -sb "$STATIC" | cut -f1)

stop_servers

# 4. nginx on the same files: start_nginx WORKERS [CPU] (master and workers pinned there).
mkdir -p "$WORK/nginx/logs"
start_nginx() {
  cat >"$WORK/nginx/nginx.conf" <<NGINX
worker_processes $1;
pid $WORK/nginx/nginx.pid;
error_log $WORK/nginx/logs/error.log warn;
daemon off;
events { worker_connections 4096; }
http {
  access_log off;
  sendfile on; tcp_nopush on; tcp_nodelay on;
  keepalive_requests 1000000; keepalive_timeout 60;
  open_file_cache max=10000 inactive=60s;
  types { application/json json; application/vnd.quantized-mesh terrain; }
  server {
    listen 127.0.0.1:$NGINX_PORT;
    root $STATIC;
    location ~ \.terrain\$ { add_header Content-Encoding gzip; add_header Access-Control-Allow-Origin *; }
  }
}
NGINX
  $(pinned_to "${2:-}") "$NGINX" -p "$WORK/nginx" -c "$WORK/nginx/nginx.conf" &
  NGINX_PID=$!
  sleep 0.5
}

# Warms tinstream-server's terrain LRU (every tile once, one keep-alive connection) and checks
# that both servers send the same bytes.
warm_and_check() {
  sed "s|^|url = \"$BASE/tiles/$LAYER|; s|\$|\"\noutput = \"/dev/null\"|" "$WORK/paths.txt" >"$WORK/warm.curl"
  curl -s -H 'Accept-Encoding: gzip' -H 'Accept: application/vnd.quantized-mesh;extensions=octvertexnormals' \
    -K "$WORK/warm.curl"
  local p1 pn p
  p1=$(sed -n '1p' "$WORK/paths.txt"); pn=$(tail -n1 "$WORK/paths.txt")
  for p in "$p1" "$pn"; do
    curl -sf -H 'Accept-Encoding: gzip' -H 'Accept: application/vnd.quantized-mesh;extensions=octvertexnormals' -o "$WORK/a" "$BASE/tiles/$LAYER$p"
    curl -sf -H 'Accept-Encoding: gzip' -o "$WORK/b" "http://127.0.0.1:$NGINX_PORT$p"
    cmp -s "$WORK/a" "$WORK/b" || { echo "run.sh: $p differs between the servers" >&2; exit 1; }
  done
}

TICKS=$(getconf CLK_TCK)
rss_kb() {  # total VmRSS of the given pids and their children
  local total=0 pid
  for pid in "$@" $(pgrep -P "$(echo "$@" | tr ' ' ',')" 2>/dev/null || true); do
    local kb; kb=$(awk '/VmRSS/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
    total=$((total + ${kb:-0}))  # a process that just exited has no VmRSS
  done
  echo "$total"
}

cpu_ticks() {  # user + system CPU clock ticks of the given pids and their children
  local total=0 pid
  for pid in "$@" $(pgrep -P "$(echo "$@" | tr ' ' ',')" 2>/dev/null || true); do
    local t; t=$(awk '{print $14 + $15}' "/proc/$pid/stat" 2>/dev/null || true)
    total=$((total + ${t:-0}))
  done
  echo "$total"
}

# Total VmRSS of the given pids every 0.5 s, with bash builtins only: a forked pgrep/awk/sleep
# every half second would land on the server's core now and then and show in its latency tail.
# Pinned configuration: runs on the load generator's core (SAMPLER_CPU).
rss_sampler() {
  [[ -n ${SAMPLER_CPU:-} ]] && taskset -p -c "$SAMPLER_CPU" "$BASHPID" >/dev/null
  local total k v _ p fd
  exec {fd}<> <(:)  # a pipe nobody writes to: `read -t` on it sleeps without a fork
  while true; do
    total=0
    for p in "$@"; do
      while read -r k v _; do [[ $k == VmRSS: ]] && total=$((total + v)); done <"/proc/$p/status" || true
    done 2>/dev/null
    echo "$total"
    read -r -t 0.5 -u "$fd" _ || true
  done
}

# Set per configuration: WRK (the load generator's command prefix and thread count).
run_wrk() {  # name pid prefix-url prefix-path connections
  local name=$1 pid=$2 url=$3 prefix=$4 conns=$5
  TILE_PATHS=$WORK/paths.txt PREFIX=$prefix $WRK -c"$conns" -d2s -s "$ROOT/bench/server/urls.lua" "$url" >/dev/null
  local before; before=$(rss_kb "$pid")
  local max=$before
  rss_sampler "$pid" $(pgrep -P "$pid" 2>/dev/null || true) >"$WORK/rss.$name.$conns" &
  local sampler=$!
  SAMPLER=$sampler
  local cpu_before; cpu_before=$(cpu_ticks "$pid")
  TILE_PATHS=$WORK/paths.txt PREFIX=$prefix /usr/bin/time -o "$WORK/time.$name.$conns" -f "%U %S" \
    $WRK -c"$conns" -d"${DURATION}s" --timeout 5s \
    -s "$ROOT/bench/server/urls.lua" "$url" >"$WORK/wrk.$name.$conns"
  local cpu_after; cpu_after=$(cpu_ticks "$pid")
  kill "$sampler" 2>/dev/null; wait "$sampler" 2>/dev/null || true
  SAMPLER=
  max=$(sort -n "$WORK/rss.$name.$conns" | tail -n1)
  local after; after=$(rss_kb "$pid")
  kill -0 "$pid" 2>/dev/null && [[ $(awk '/^State/ {print $2}' "/proc/$pid/status") != Z ]] ||
    { echo "run.sh: $name (pid $pid) died during the run" >&2; exit 1; }
  echo "$name $conns $(grep RESULT "$WORK/wrk.$name.$conns" | cut -d' ' -f2-) rss_before_kb=$before rss_max_kb=$max rss_after_kb=$after cpu_s=$(( (cpu_after - cpu_before) * 1000 / TICKS ))e-3 wrk_cpu_s=$(awk '{print $1 + $2}' "$WORK/time.$name.$conns")"
}

COMMIT=$(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)
for config in $CONFIGS; do
  if [[ $config == pinned ]]; then
    servers=1 server_cpu=$SERVER_CPU WRK="taskset -c $WRK_CPU wrk -t1" SAMPLER_CPU=$WRK_CPU
    SETUP="pinned: wrk -t1 on CPU $WRK_CPU; tinstream-server (1 io thread) and nginx (master + 1 worker) on CPU $SERVER_CPU (taskset)"
  else
    servers=$THREADS server_cpu= WRK="wrk -t$THREADS" SAMPLER_CPU=
    SETUP="shared: wrk -t$THREADS, $THREADS io threads / nginx workers, all on the same $(nproc) cores"
  fi
  start_tinstream "$servers" "$server_cpu"
  start_nginx "$servers" "$server_cpu"
  warm_and_check
  LOAD_START=$(cut -d' ' -f1-3 /proc/loadavg)
  {
    for c in 64 256; do
      run_wrk tinstream "$SERVER_PID" "$BASE" "/tiles/$LAYER" "$c"
      run_wrk nginx "$NGINX_PID" "http://127.0.0.1:$NGINX_PORT" "" "$c"
    done
  } | tee "$WORK/results.$config.txt"
  LOAD_END=$(cut -d' ' -f1-3 /proc/loadavg)
  stop_servers

  python3 - "$WORK/results.$config.txt" "$SOURCE" "$EXPORT" "$TILES" "$BYTES" "$DURATION" "$SETUP" \
    "$LOAD_START" "$LOAD_END" "$COMMIT" "$config" <<'PY'
import sys, datetime, os, platform
rows = {}
for line in open(sys.argv[1]):
    parts = line.split()
    kv = dict(p.split("=") for p in parts[2:])
    rows[(parts[0], int(parts[1]))] = {k: float(v) for k, v in kv.items()}
print(f"\n### Serving benchmark ({sys.argv[11]}) — {datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, {platform.node()}\n")
print(f"Store: {sys.argv[2]}; static copy: {sys.argv[3]}; {sys.argv[4]} tiles, {int(sys.argv[5])/1e6:.1f} MB gzip; "
      f"{sys.argv[7]}; {sys.argv[6]} s per run, keep-alive, over loopback; commit {sys.argv[10]}; "
      f"load average {sys.argv[8]} (start) → {sys.argv[9]} (end).\n")
print("| server | conns | req/s | p50 ms | p99 ms | errors | server CPU µs/req | wrk CPU µs/req | RSS before → max → after (MB) |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
for (name, c), r in sorted(rows.items(), key=lambda kv: (kv[0][1], kv[0][0] != "tinstream")):
    print(f"| {name} | {c} | {r['rps']:.0f} | {r['p50_ms']:.2f} | {r['p99_ms']:.2f} | {int(r['errors'])} | "
          f"{r['cpu_s']*1e6/max(r['requests'],1):.1f} | {r['wrk_cpu_s']*1e6/max(r['requests'],1):.1f} | {r['rss_before_kb']/1024:.1f} → {r['rss_max_kb']/1024:.1f} → {r['rss_after_kb']/1024:.1f} |")
print("\n| conns | throughput tinstream/nginx | p99 tinstream/nginx | CPU per request tinstream/nginx |")
print("|---:|---:|---:|---:|")
for c in sorted({c for _, c in rows}):
    t, n = rows.get(("tinstream", c)), rows.get(("nginx", c))
    if t and n:
        cpu = lambda r: r['cpu_s'] / max(r['requests'], 1)
        print(f"| {c} | {t['rps']/n['rps']:.2f}× | {t['p99_ms']/max(n['p99_ms'],1e-9):.2f}× | "
              f"{cpu(t)/max(cpu(n),1e-12):.2f}× |")
PY
done
