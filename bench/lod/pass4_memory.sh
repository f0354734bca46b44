#!/usr/bin/env bash
# Pass 4's peak memory (#20): ingests a DEM (default Big Tujunga) with each given `tinstream`
# binary in turn, ROUNDS times alternating, and prints the peak RSS (/usr/bin/time) and user
# time of each run; with HEAPTRACK=1 also the peak heap (heaptrack: deterministic for 1 thread,
# where RSS varies by ~20 MB run to run on a busy machine). Not a test.
#   bench/lod/pass4_memory.sh OLD_BIN NEW_BIN            # 2 rounds, --threads 2
#   ROUNDS=3 THREADS=1 HEAPTRACK=1 bench/lod/pass4_memory.sh build/bin/tinstream
#   EXTRA="--max-points 1024" DEM=../shared/data/luxembourg_elev.tif bench/lod/pass4_memory.sh BIN
set -euo pipefail
if [[ $# == 0 || $1 == -h || $1 == --help ]]; then sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; exit 0; fi
here=$(cd "$(dirname "$0")" && pwd)
DEM=${DEM:-$here/../../../shared/data/bigtujunga_srtm30m_utm11.tif}
ROUNDS=${ROUNDS:-2}
THREADS=${THREADS:-2}
[[ -f $DEM ]] || { echo "DEM not found: $DEM" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "$(basename "$DEM") --threads $THREADS ${EXTRA:-}; $(uptime)"
for ((r = 1; r <= ROUNDS; ++r)); do
  for bin in "$@"; do
    rm -f "$work/s.db"
    # shellcheck disable=SC2086
    /usr/bin/time -f "%M %U" -o "$work/time" "$bin" ingest --store "$work/s.db" --layer m -q \
      --threads "$THREADS" ${EXTRA:-} "$DEM" >/dev/null
    read -r rss user <"$work/time"
    line="round $r  $bin  peak RSS $((rss / 1024)) MB  user ${user} s"
    if [[ ${HEAPTRACK:-0} == 1 ]]; then
      rm -f "$work/s.db" "$work"/ht*
      # shellcheck disable=SC2086
      heaptrack -o "$work/ht" "$bin" ingest --store "$work/s.db" --layer m -q \
        --threads "$THREADS" ${EXTRA:-} "$DEM" >/dev/null 2>&1
      peak=$(heaptrack_print -f "$work"/ht*.zst --print-peaks 0 --print-allocators 0 \
        --print-temporary 0 --print-leaks 0 2>/dev/null | sed -n 's/^peak heap memory consumption: //p')
      line+="  peak heap $peak"
    fi
    echo "$line"
  done
done
