#!/usr/bin/env bash
# Builds the tile stores that the client's integration tests look at (CTest fixture
# "client_stores"), with the real `tinstream ingest`:
#   dem.sqlite    layer "dem"        <- ../shared/data/bigtujunga_srtm30m_utm11.tif (SRTM 30 m, UTM 11)
#   lidar.sqlite  layer "lidar"      <- ../shared/data/autzen_trim.las (ground points, Oregon ft)
#                 layer "lidar_ell"  <- the same points in ellipsoidal Mercator
# Without ../shared/data the layers come from `tinstream sample` (synthetic LiDAR) instead, so the
# tests still run on real stores. A store is rebuilt only when missing or older than `tinstream`.
# Usage: make_stores.sh BIN_DIR DATA_DIR OUT_DIR
set -euo pipefail
bin=$1
data=$2
out=$3
mkdir -p "$out"

fresh() { [[ -f $out/$1 && $out/$1 -nt $bin/tinstream ]]; }

# ingest STORE LAYER [OPTIONS...] INPUT: into STORE.tmp (renamed once every layer is in).
ingest() {
  local store=$1 layer=$2
  shift 2
  "$bin/tinstream" ingest --store "$out/$store.tmp" --layer "$layer" "$@" > "$out/$store.$layer.log" 2>&1 ||
    { cat "$out/$store.$layer.log"; exit 1; }
}

sample() {  # a synthetic LAS, made once
  [[ -f $out/sample.las ]] || "$bin/tinstream" sample --out "$out/sample.las" --points 200000 --density 0.05
  echo "$out/sample.las"
}

if ! fresh dem.sqlite; then
  rm -f "$out"/dem.sqlite.tmp*
  if [[ -f $data/bigtujunga_srtm30m_utm11.tif ]]; then
    ingest dem.sqlite dem "$data/bigtujunga_srtm30m_utm11.tif"
    echo "dem: $data/bigtujunga_srtm30m_utm11.tif" > "$out/dem.source"
  else
    ingest dem.sqlite dem "$(sample)"
    echo "dem: synthetic (tinstream sample)" > "$out/dem.source"
  fi
  mv "$out/dem.sqlite.tmp" "$out/dem.sqlite"
fi

if ! fresh lidar.sqlite; then
  rm -f "$out"/lidar.sqlite.tmp*
  input=$data/autzen_trim.las
  [[ -f $input ]] || input=$(sample)
  ingest lidar.sqlite lidar "$input"
  ingest lidar.sqlite lidar_ell --projection ellipsoidal "$input"
  echo "lidar: $input" > "$out/lidar.source"
  mv "$out/lidar.sqlite.tmp" "$out/lidar.sqlite"
fi
cat "$out/dem.source" "$out/lidar.source"
