#!/usr/bin/env bash
# Behaviour-preserving changes to the ingest (refactors, speed-ups) must leave every store
# byte-identical. This ingests a fixed set of inputs with a given `tinstream` binary and dumps every
# row of every table of each store (blobs as hashes, timestamps masked) to OUTDIR/NAME.txt; run it
# with the binary before and after the change, then compare the two folders.
#   scripts/store_identity.sh dump BIN OUTDIR       ingest and dump (needs ../shared/data)
#   scripts/store_identity.sh compare OLD NEW       exit 1 when any dump differs
# Inputs: autzen_trim.las (default and --max-points 2048), nm_4_6_crop.las, Big Tujunga DEM
# (default and --max-points 1024), luxembourg_elev.tif (2048), boulder_srtmgl3.asc (4096), and a
# generated 2e5-point LAS (`tinstream sample`). About a minute on 2 cores.
set -euo pipefail
usage() { sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; }
case ${1:-} in
  -h|--help|"") usage; exit 0 ;;
  dump) [[ $# == 3 ]] || { usage; exit 2; } ;;
  compare)
    [[ $# == 3 ]] || { usage; exit 2; }
    rc=0
    for f in "$2"/*.txt; do
      n=$(basename "$f")
      if [[ ! -f $3/$n ]]; then echo "missing $n in $3"; rc=1; continue; fi
      if cmp -s "$f" "$3/$n"; then echo "same $n"; else echo "DIFFERENT $n"; { diff "$f" "$3/$n" || true; } | head -5; rc=1; fi
    done
    exit $rc ;;
  *) usage; exit 2 ;;
esac
bin=$(realpath "$2"); out=$3
data=$(cd "$(dirname "$0")/.." && realpath -m ../shared/data)
[[ -d $data ]] || { echo "store_identity: no $data (the real datasets)" >&2; exit 2; }
mkdir -p "$out"
rm -f "$out"/*.tinstream "$out"/*.tinstream-* "$out"/*.txt
dump_store() {
  python3 - "$1" "$(realpath "$out")" <<'PY'
import hashlib, re, sqlite3, sys
db = sqlite3.connect(sys.argv[1])
folder = sys.argv[2]  # the generated input's path is recorded in the layer: not compared
stamp = re.compile(r"\b1[0-9]{9}\b")  # unix times (creation, publish)
for (table,) in db.execute("select name from sqlite_master where type='table' order by name"):
    rows = []
    for row in db.execute(f'select * from "{table}"'):
        cells = [hashlib.sha256(v).hexdigest()[:24] if isinstance(v, bytes) else v for v in row]
        rows.append(stamp.sub("T", " ".join(map(str, cells))).replace(folder, "OUT"))
    for r in sorted(rows):
        print(table, r)
PY
}
run() {
  local name=$1; shift
  "$bin" ingest -q --threads 2 --store "$out/$name.tinstream" --layer t "$@" >/dev/null
  dump_store "$out/$name.tinstream" >"$out/$name.txt"
  echo "$name: $(wc -l <"$out/$name.txt") rows"
}
"$bin" sample --out "$out/sample.las" --points 2e5 --seed 7 >/dev/null
run sample "$out/sample.las"
run autzen "$data/autzen_trim.las"
run autzen2k "$data/autzen_trim.las" --max-points 2048
run nm "$data/nm_4_6_crop.las"
run tujunga "$data/bigtujunga_srtm30m_utm11.tif"
run tujunga1k "$data/bigtujunga_srtm30m_utm11.tif" --max-points 1024
run luxembourg "$data/luxembourg_elev.tif" --max-points 2048
run boulder "$data/boulder_srtmgl3.asc" --crs EPSG:4326 --max-points 4096
rm -f "$out"/*.tinstream "$out"/*.tinstream-* "$out/sample.las"
