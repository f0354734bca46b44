#!/usr/bin/env bash
# Pass 3 identity check: ingests every check input with one tinstream binary (`--no-pyramid
# --threads 1`) and writes, per input, the stored tiles' (z, x, y, blob length, etag) to
# OUT/<input>.tiles and a sha256 of all blobs in (z, x, y) order to OUT/hashes. Run it for the
# binary before and after a change and compare: `diff -r OUT_BEFORE OUT_AFTER` must be empty.
#   bench/ingest/pass3_identity.sh build/bin/tinstream /tmp/pass3-after
# Inputs: ../shared/data (DATA), the 2e6-point `tinstream sample` (seed 1) and the adversarial
# XYZ of pass3_adversarial.py, both generated into WORK when absent.
set -euo pipefail
BIN=$(realpath "$1")
OUT=$(mkdir -p "$2" && realpath "$2")
HERE=$(dirname "$(realpath "$0")")
DATA=${DATA:-$(realpath "$HERE/../../../shared/data")}
WORK=${WORK:-/tmp/tinstream-pass3-identity}
mkdir -p "$WORK"
[ -f "$WORK/sample-2e6.las" ] || "$BIN" sample --out "$WORK/sample-2e6.las" --points 2e6 --seed 1
[ -f "$WORK/adversarial.xyz" ] || python3 "$HERE/pass3_adversarial.py" "$WORK/adversarial.xyz"
: >"$OUT/hashes"
run() {
  local name=$1
  shift
  rm -f "$WORK/$name.db"*
  "$BIN" ingest --store "$WORK/$name.db" --layer t --no-pyramid --threads 1 -q "$@" >/dev/null
  python3 - "$WORK/$name.db" "$OUT/$name.tiles" "$name" >>"$OUT/hashes" <<'PY'
import hashlib, sqlite3, sys
db = sqlite3.connect(sys.argv[1])
version = db.execute("SELECT version FROM layers WHERE name = 't'").fetchone()[0]
digest, rows = hashlib.sha256(), []
for z, x, y, data, etag in db.execute(
        "SELECT z, x, y, data, etag FROM tiles WHERE version = ? ORDER BY z, x, y", (version,)):
    digest.update(data)
    rows.append(f"{z} {x} {y} {len(data)} {etag}\n")
open(sys.argv[2], "w").writelines(rows)
print(sys.argv[3], len(rows), digest.hexdigest())
PY
  rm -f "$WORK/$name.db"*
}
run sample2e6 "$WORK/sample-2e6.las"
run adv4000 "$WORK/adversarial.xyz" --crs EPSG:32632 --max-points 4000
run adv300 "$WORK/adversarial.xyz" --crs EPSG:32632 --max-points 300
run autzen "$DATA/autzen_trim.las"
run autzen500 "$DATA/autzen_trim.las" --max-points 500
run nm1000 "$DATA/nm_4_6_crop.las" --max-points 1000
run bigtujunga "$DATA/bigtujunga_srtm30m_utm11.tif"
run n00e010 "$DATA/N00E010.hgt"
run boulder "$DATA/boulder_srtmgl3.asc" --crs EPSG:4326 --max-points 2000
run luxembourg "$DATA/luxembourg_elev.tif" --max-points 200
cat "$OUT/hashes"
