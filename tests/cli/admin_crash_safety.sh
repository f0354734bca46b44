#!/usr/bin/env bash
# Crash safety of an admin ingest (#22), with the real tinstream-server on 127.0.0.1:
#   1. an ingest that fails inside a worker (fault points armed through TINSTREAM_FAULT: an
#      exception on a pass-3 worker, a thread that cannot be created) fails its job and the server
#      goes on serving: an ingest failure never terminates the server process;
#   2. a VRT under the data root whose source lies outside it (the reproduction in #22) is refused
#      and nothing is published;
#   3. the server is SIGKILLed at random moments of a replacing ingest; after each kill the store
#      passes PRAGMA integrity_check and the layer is the version before or the new one complete
#      (byte for byte the reference), never partial; a restarted server serves it, and a final
#      re-submitted job succeeds with the reference bytes.
#   tests/cli/admin_crash_safety.sh [--build DIR] [--kills N] [--seed S] [--keep]
# CTest runs it with 20 kills (CrashSafety.AdminIngestKilledWithTheServer).
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
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "admin_crash_safety.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
tinstream=$(realpath "$build/bin/tinstream")
server=$(realpath "$build/bin/tinstream-server")
for b in "$tinstream" "$server"; do
  [[ -x $b ]] || { echo "admin_crash_safety.sh: no $b (build it first)" >&2; exit 2; }
done

work=$(mktemp -d "${TMPDIR:-/tmp}/tinstream-admin-crash-$$-XXXXXX")
server_pid=
cleanup() {
  if [[ -n $server_pid ]]; then kill -KILL "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  if ((keep)); then echo "kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT
RANDOM=$seed
fail() {
  echo "admin_crash_safety: FAILED: $*" >&2
  [[ -f $work/server.log ]] && tail -n 20 "$work/server.log" >&2
  keep=1
  exit 1
}

export TINSTREAM_ADMIN_TOKEN=crash-test-token
mkdir -p "$work/data" "$work/outside"
cat >"$work/server.json" <<EOF
{ "address": "127.0.0.1", "port": 0, "store": "$work/store.sqlite", "data_root": "$work/data",
  "log_level": "warn", "access_log": false }
EOF

# Starts the server (environment: extra VAR=value words); sets server_pid and url.
start_server() {
  # The previous server's stdout must be gone before this one starts: otherwise the loop below can
  # read its stale "listening on" line (and port) before the new process truncates the file.
  rm -f "$work/server.out"
  env "$@" "$server" --config "$work/server.json" >"$work/server.out" 2>"$work/server.log" &
  server_pid=$!
  local line=
  for _ in $(seq 1 600); do  # the "listening on" line, within 60 s
    line=$(grep -m1 '^listening on ' "$work/server.out" 2>/dev/null || true)
    [[ -n $line ]] && break
    kill -0 "$server_pid" 2>/dev/null || fail "the server exited at start"
    sleep 0.1
  done
  [[ -n $line ]] || fail "the server did not start listening"
  url="http://${line#listening on }"
}
stop_server() {
  kill -KILL "$server_pid" 2>/dev/null || true
  wait "$server_pid" 2>/dev/null || true
  server_pid=
}
submit() {  # source → job id
  local reply
  reply=$(curl -sS -H "Authorization: Bearer $TINSTREAM_ADMIN_TOKEN" -H 'Content-Type: application/json' \
    -d "{\"layer\":\"crash\",\"sources\":[\"$1\"],\"options\":{\"threads\":2,\"max_points\":2000}}" \
    "$url/admin/ingest") || fail "POST /admin/ingest: curl failed"
  local id
  id=$(grep -o '"job":"[^"]*"' <<<"$reply" | cut -d'"' -f4)
  [[ -n $id ]] || fail "POST /admin/ingest: no job in the reply: $reply"
  echo "$id"
}
job_state() {  # id → queued/running/succeeded/failed/cancelled
  curl -sS -H "Authorization: Bearer $TINSTREAM_ADMIN_TOKEN" "$url/admin/jobs/$1" >"$work/job.json" \
    || fail "GET /admin/jobs/$1: curl failed"
  grep -o '"state":"[a-z]*"' "$work/job.json" | cut -d'"' -f4
}
wait_job() {  # id → its final state (within 5 minutes)
  local state
  for _ in $(seq 1 3000); do
    state=$(job_state "$1")
    case $state in succeeded|failed|cancelled) echo "$state"; return ;; esac
    sleep 0.1
  done
  fail "job $1 did not finish within 5 minutes"
}
healthy() {
  curl -sS -o /dev/null -w '%{http_code}' "$url/healthz" 2>/dev/null | grep -qx 200
}
fingerprint() {
  sqlite3 "$1" "SELECT z, x, y, hex(data) FROM published_tiles WHERE layer = 'crash' ORDER BY z, x, y" \
    2>/dev/null | md5sum | cut -d' ' -f1
}
layers() { sqlite3 "$work/store.sqlite" "SELECT count(*) FROM layers WHERE name = 'crash'" 2>/dev/null || echo 0; }

"$tinstream" sample --out "$work/data/a.las" --points 20000 --seed 1 >/dev/null
"$tinstream" sample --out "$work/data/b.las" --points 150000 --seed 2 >/dev/null
for input in a b; do
  "$tinstream" ingest -q --store "$work/ref_$input.sqlite" --layer crash --threads 2 \
    --max-points 2000 --tmp "$work/tmp" "$work/data/$input.las" >/dev/null
done
ref_a=$(fingerprint "$work/ref_a.sqlite")
ref_b=$(fingerprint "$work/ref_b.sqlite")

# 1. Failures inside the ingest's workers fail the job, not the server.
for fault in pass3.tile@2 pass3.tile.spawn@1:no_thread lod.tile@1:oom; do
  start_server TINSTREAM_FAULT="$fault"
  id=$(submit a.las)
  state=$(wait_job "$id")
  [[ $state == failed ]] || fail "fault $fault: job $state, expected failed"
  grep -q 'injected fault\|out of memory\|cannot start a thread' "$work/job.json" \
    || fail "fault $fault: the job's error does not say what failed: $(cat "$work/job.json")"
  kill -0 "$server_pid" 2>/dev/null || fail "fault $fault: the server process died"
  healthy || fail "fault $fault: /healthz is not 200 after the failed job"
  [[ $(layers) == 0 ]] || fail "fault $fault: a layer was published"
  stop_server
done
echo "admin_crash_safety: worker failures fail their jobs; the server keeps serving"

# 2. #22's reproduction: a VRT under the data root whose source is outside it.
cp "$work/ref_a.sqlite" "$work/outside/secret.sqlite"  # any file outside; GDAL must not open it
gdal_source="$work/outside/secret.tif"
"$tinstream" sample --out "$work/outside/x.las" --points 10 --seed 3 >/dev/null
cat >"$work/data/escape.vrt" <<EOF
<VRTDataset rasterXSize="4" rasterYSize="3">
  <SRS>EPSG:4326</SRS>
  <GeoTransform>8.5, 0.001, 0, 47.4, 0, -0.001</GeoTransform>
  <VRTRasterBand dataType="Float32" band="1">
    <SimpleSource><SourceFilename relativeToVRT="0">$gdal_source</SourceFilename>
      <SourceBand>1</SourceBand></SimpleSource>
  </VRTRasterBand>
</VRTDataset>
EOF
if command -v gdal_create >/dev/null; then
  gdal_create -q -of GTiff -outsize 4 3 -ot Float32 -a_srs EPSG:4326 -a_ullr 8.5 47.4 8.504 47.397 \
    -burn 500 "$gdal_source"
else
  cp "$work/outside/x.las" "$gdal_source"  # refused before GDAL reads it anyway
fi
start_server
id=$(submit escape.vrt)
state=$(wait_job "$id")
[[ $state == failed ]] || fail "a VRT reaching outside the data root: job $state, expected failed"
grep -q 'outside the data root' "$work/job.json" || fail "the VRT job's error: $(cat "$work/job.json")"
[[ $(layers) == 0 ]] || fail "the escaping VRT was published"
stop_server
rm -f "$work/data/escape.vrt"
echo "admin_crash_safety: a VRT naming a file outside the data root is refused"

# 3. Kills. The reference duration: one uninterrupted admin ingest of b.
start_server
start=$(date +%s%N)
id=$(submit b.las)
[[ $(wait_job "$id") == succeeded ]] || fail "the reference admin ingest failed: $(cat "$work/job.json")"
duration_ms=$((($(date +%s%N) - start) / 1000000))
[[ $(fingerprint "$work/store.sqlite") == "$ref_b" ]] || fail "the admin ingest differs from the CLI's"
stop_server
echo "admin_crash_safety: an admin ingest of b takes ${duration_ms} ms; $kills kills, seed $seed"
current=b
before=0
after=0
for ((k = 1; k <= kills; k++)); do
  if [[ $current == a ]]; then target=b; else target=a; fi
  declare -n ref_current=ref_$current ref_target=ref_$target
  start_server
  delay_ms=$(((RANDOM * 32768 + RANDOM) % (duration_ms * 115 / 100 + 1)))
  submit "$target.las" >/dev/null
  sleep "$(printf '%d.%03d' $((delay_ms / 1000)) $((delay_ms % 1000)))"
  stop_server
  check=$(sqlite3 "$work/store.sqlite" "PRAGMA integrity_check")
  [[ $check == ok ]] || fail "kill $k at ${delay_ms} ms: integrity_check says: $check"
  now=$(fingerprint "$work/store.sqlite")
  if [[ $now == "$ref_current" ]]; then
    before=$((before + 1))
  elif [[ $now == "$ref_target" ]]; then
    after=$((after + 1))
    current=$target
  else
    fail "kill $k at ${delay_ms} ms: the layer is neither the version before nor the new one complete"
  fi
  unset -n ref_current ref_target
done

# A restarted server serves the layer and a re-submitted job succeeds with the reference bytes.
if [[ $current == a ]]; then target=b; else target=a; fi
start_server
healthy || fail "/healthz after the kills"
id=$(submit "$target.las")
[[ $(wait_job "$id") == succeeded ]] || fail "the re-submitted job: $(cat "$work/job.json")"
declare -n ref_final=ref_$target
[[ $(fingerprint "$work/store.sqlite") == "$ref_final" ]] || fail "the re-run published other tiles"
building=$(sqlite3 "$work/store.sqlite" "SELECT count(*) FROM layer_versions WHERE status = 'building'")
[[ $building == 0 ]] || fail "$building abandoned versions left after the re-run"
stop_server
[[ $(sqlite3 "$work/store.sqlite" "PRAGMA integrity_check") == ok ]] || fail "integrity_check at the end"
echo "admin_crash_safety: ok: $kills kills ($before left the version before, $after the new one complete), re-run ok"
