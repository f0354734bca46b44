#!/usr/bin/env bash
# Ingest benchmark (issue #4): synthetic LiDAR-like LAS files (`tinstream sample`: fractal
# mountains, 4 points/m², flight strips) of several sizes through `tinstream ingest` with default
# options; records points/s and peak RSS for each size and prints a markdown table.
#   SIZES="1e7 3e7 1e8" BUILD_DIR=build-bench WORK=/tmp/tinstream-ingest-bench bench/ingest/run.sh
# EXTRA=--no-pyramid measures the finest level only (passes 1–3 and the store: issue #4's end to
# end); without it the default ingest also builds the LOD pyramid.
# Needs free disk: about 20 bytes per point for the LAS file (point format 0), ~40 bytes per point
# of temporary run files during the ingest and ~20 for the store.
set -euo pipefail
cd "$(dirname "$0")/../.."
SIZES=${SIZES:-"1e7 3e7 1e8"}
BUILD_DIR=${BUILD_DIR:-build-bench}
WORK=${WORK:-/tmp/tinstream-ingest-bench}
EXTRA=${EXTRA:-}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release -DTINSTREAM_BUILD_TESTS=OFF \
  -DTINSTREAM_BUILD_SERVER=OFF -DTINSTREAM_BUILD_CLIENT=OFF >/dev/null
cmake --build "$BUILD_DIR" --target tinstream >/dev/null
bin="$BUILD_DIR/bin/tinstream"
mkdir -p "$WORK"
echo "| points | tiles | finest level | seconds | points/s | peak RSS (MB) | halo overhead |"
echo "|---:|---:|---:|---:|---:|---:|---:|"
for n in $SIZES; do
  las="$WORK/sample-$n.las"
  [[ -f $las ]] || "$bin" sample --out "$las" --points "$n" --density 4 >/dev/null
  rm -f "$WORK/store.sqlite"*
  json=$("$bin" ingest --store "$WORK/store.sqlite" --layer bench --tmp "$WORK" --json -q $EXTRA "$las")
  python3 - "$json" <<'PY'
import json, sys
j = json.loads(sys.argv[1])
print(f"| {j['points_accepted']:,} | {j['tiles']:,} | {j['finest_level']} | {j['seconds']:.1f} | "
      f"{j['points_per_second']:,.0f} | {j['peak_rss_mb']:.0f} | {j['halo_overhead']:.2f} |")
PY
done
