# shellcheck shell=bash
# shellcheck disable=SC2034,SC2153,SC2154  # the sourcing script sets and reads these globals
# bench/client/serve.sh — sourced by run.sh and ab.sh (needs ROOT, HERE, BIN, OUT, DELAY_MS, PROXY
# and pick_store's `store`). start_server_and_proxy NAME [PROXY_ARGS…] starts tinstream-server on
# 127.0.0.1 and the delaying proxy in front of it (PROXY: node, proxy.mjs, or python, proxy.py;
# PROXY_ARGS go to the proxy, e.g. --static DIR), sets server_port and proxy (the proxy's URL),
# and adds both processes to `pids`, which are stopped when the script exits.
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; wait "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
wait_line() {  # NAME FILE PATTERN: until FILE has a line matching PATTERN (30 s at most)
  for _ in $(seq 300); do grep -q "$3" "$2" 2>/dev/null && return 0; sleep 0.1; done
  echo "$1: no '$3' in $2" >&2; cat "$2" >&2; exit 1
}
start_server_and_proxy() {
  local name=$1
  shift
  "$BIN/tinstream-server" --config "$ROOT/config/server.json" --store "$store" --address 127.0.0.1 \
    --port 0 > "$OUT/server.out" 2> "$OUT/server.log" &
  pids+=($!)
  wait_line "$name" "$OUT/server.out" "listening on"
  server_port=$(sed -n 's/^listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$OUT/server.out" | head -1)
  local proxy_cmd
  case $PROXY in
    node) proxy_cmd=(node "$HERE/proxy.mjs") ;;
    python) proxy_cmd=(python3 "$HERE/proxy.py") ;;
    *) echo "$name: PROXY is node or python, not '$PROXY'" >&2; exit 2 ;;
  esac
  "${proxy_cmd[@]}" --port 0 --upstream "http://127.0.0.1:$server_port" --delay-ms "$DELAY_MS" \
    "$@" > "$OUT/proxy.out" 2> "$OUT/proxy.log" &
  pids+=($!)
  wait_line "$name" "$OUT/proxy.out" "listening"
  proxy=http://127.0.0.1:$(awk '/listening/ {print $2; exit}' "$OUT/proxy.out")
}
