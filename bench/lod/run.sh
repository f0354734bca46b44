#!/usr/bin/env bash
# bench/lod: our thinning (core/lod, Lee's drop heuristic) vs greedy insertion (Delatin) on a real
# DEM at equal vertex counts. Prints a markdown table (append it to RESULTS.md with the date and
# machine). Not a test.
#
#   bench/lod/run.sh                      # defaults below
#   COUNTS=1000,20000 BUILD_DIR=build-lod bench/lod/run.sh
#   LOD_GREEDY_FACTOR=1.2 bench/lod/run.sh   # LodOptions::greedy_factor (0 = drop from all points)
#   LOD_LATTICE_SCAN=0 bench/lod/run.sh      # file every point (the general path), no lattice scan
#
# Needs: node + npm (Delatin is installed here by `npm install` into bench/lod/node_modules),
# GDAL, a C++20 compiler, and the tinstream_lod library built (done here with CMake).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
DEM=${DEM:-$root/../shared/data/bigtujunga_srtm30m_utm11.tif}
BUILD=${BUILD_DIR:-$root/build-lod}
COUNTS=${COUNTS:-1000,5000,20000,50000}
JOBS=${JOBS:-2}
out=$here/out
mkdir -p "$out"

[ -f "$DEM" ] || { echo "DEM not found: $DEM" >&2; exit 1; }
(cd "$here" && npm install --no-audit --no-fund --silent)

if [ ! -f "$BUILD/build.ninja" ]; then
  cmake -S "$root" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DTINSTREAM_ONLY_MODULES="base;geo;kernel;tile;store;lod" -DTINSTREAM_BUILD_TESTS=OFF \
    -DTINSTREAM_BUILD_SERVER=OFF -DTINSTREAM_BUILD_CLIENT=OFF >&2
fi
cmake --build "$BUILD" --target tinstream_lod -j"$JOBS" >&2

inc=()
for m in base geo kernel tile store lod; do inc+=(-I"$root/core/$m/include"); done
libs=("$BUILD/core/lod/libtinstream_lod.a" "$BUILD/core/store/libtinstream_store.a"
      "$BUILD/core/tile/libtinstream_tile.a" "$BUILD/core/kernel/libtinstream_kernel.a"
      "$BUILD/core/geo/libtinstream_geo.a")
[ -f "$BUILD/core/base/libtinstream_base.a" ] && libs+=("$BUILD/core/base/libtinstream_base.a")
g++ -O2 -std=c++20 -Wall -Wextra "${inc[@]}" $(gdal-config --cflags) "$here/lod_vs_greedy.cpp" \
  "${libs[@]}" $(gdal-config --libs) -lsqlite3 -lz -lGeographicLib -pthread -o "$out/lod_vs_greedy"

read -r W H < <("$out/lod_vs_greedy" dump "$DEM" "$out/grid.f32")
echo "grid ${W}x${H} ($(basename "$DEM"))" >&2
node "$here/delatin_run.mjs" "$out/grid.f32" "$W" "$H" "$COUNTS" "$out" >&2
"$out/lod_vs_greedy" compare "$DEM" "$out" "$COUNTS"
