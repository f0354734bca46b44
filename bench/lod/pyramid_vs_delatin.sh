#!/usr/bin/env bash
# bench/lod: the *stored* pyramid's levels against greedy insertion (Delatin) from the source
# cells at equal vertex count (#20), for DEMs that are one EPSG:3857 tile at some level (so that
# one stored tile and the whole grid cover the same cells). Not a test; prints a markdown table.
#
#   bench/lod/pyramid_vs_delatin.sh DEM.tif [MAX_POINTS]      (default 4096)
#   BUILD_DIR=build bench/lod/pyramid_vs_delatin.sh /tmp/edge-data/dem3857_l10.tif
#
# Inputs: make_edge_data.py writes dem3857_l10.tif (N00E010.hgt on a level-10 tile) and
# rgb3857_z14.tif (terrainrgb_14-2625-6369.png decoded as heights on its z14 tile).
# Per level from the finest up: tiles, vertices of the largest tile, the stored tile's measured
# maximum error against the finest data (pyramid_quality: the input cells and the finest edge
# points on the data) and its recorded error; where one tile holds the whole grid, Delatin's
# maximum error over the grid cells with as many vertices as that tile, and the ratio ours /
# Delatin. Beside it the single-tile figure: lod::thin_tile on the whole grid (lod_vs_greedy).
# Needs: the tinstream, pyramid_quality and lod_vs_greedy targets built in BUILD_DIR, node + npm.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
DEM=${1:?usage: pyramid_vs_delatin.sh DEM.tif [MAX_POINTS]}
MAXP=${2:-4096}
BIN=${BUILD_DIR:-$root/build}/bin
out=$here/out/pyramid_$(basename "$DEM" .tif)_$MAXP
mkdir -p "$out"
(cd "$here" && npm install --no-audit --no-fund --silent)

rm -f "$out"/store.db*
"$BIN"/tinstream ingest --store "$out/store.db" --layer t -q --max-points "$MAXP" "$DEM" >&2
"$BIN"/pyramid_quality "$out/store.db" t > "$out/quality.md"
read -r W H < <("$BIN"/lod_vs_greedy dump "$DEM" "$out/grid.f32")

# Levels whose single tile holds the whole grid: one tile at that level and every level above.
levels=$(awk -F'|' '/^\| [0-9]/ { gsub(/ /, ""); print $2, $3, $4, $5, $6 }' "$out/quality.md")
counts=$(echo "$levels" | awk '$2 == 1 { print $3 }' | sort -un | paste -sd,)
[ -n "$counts" ] || { echo "no level holds the grid in one tile" >&2; exit 1; }
node "$here/delatin_run.mjs" "$out/grid.f32" "$W" "$H" "$counts" "$out" > "$out/delatin.txt"
"$BIN"/lod_vs_greedy compare "$DEM" "$out" "$counts" > "$out/single.md" 2>/dev/null

echo "$(basename "$DEM"), ${W} x ${H} cells, --max-points $MAXP"
echo
echo "| level | tiles | vertices/tile | recorded max (m) | stored tile's max (m) | Delatin max (m), same vertices | stored / Delatin | single-tile thin_tile / Delatin |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
echo "$levels" | while read -r z tiles verts recorded measured; do
  d="—"; r="—"; s="—"
  if [ "$tiles" = 1 ]; then
    d=$(awk -v n="$verts" '$1 == "delatin" && $2 == n { print $5 }' "$out/delatin.txt")
    r=$(awk -v a="$measured" -v b="$d" 'BEGIN { printf "%.3f", a / b }')
    s=$(awk -F'|' -v n="$verts / $verts" '{ v = $2; gsub(/^ +| +$/, "", v) } v == n { gsub(/ /, "", $5); print $5 }' "$out/single.md")
  fi
  echo "| $z | $tiles | $verts | $recorded | $measured | $d | $r | $s |"
done
