#!/usr/bin/env bash
# Builds the tile stores that the client's integration tests look at (CTest fixture
# "client_stores"), with the real `tinstream ingest`:
#   dem.sqlite    layer "dem"        <- ../shared/data/bigtujunga_srtm30m_utm11.tif (SRTM 30 m, UTM 11)
#   lidar.sqlite  layer "lidar"      <- ../shared/data/autzen_trim.las (ground points, Oregon ft)
#                 layer "lidar_ell"  <- the same points in ellipsoidal Mercator
# Without ../shared/data the layers come from `tinstream sample` (synthetic LiDAR) instead, so the
# tests still run on real stores. A store is rebuilt only when missing or when its stamp
# (STORE.stamp: the sha256 of `tinstream` and of this script, the input's real path and size)
# differs from what it would be now. Not by modification times: the tests' servers write to the
# stores (SQLite WAL checkpoints), which made a store look newer than a rebuilt `tinstream`.
# Usage: make_stores.sh BIN_DIR DATA_DIR OUT_DIR
set -euo pipefail
bin=$1
data=$2
out=$3
mkdir -p "$out"

# stamp INPUT: what a store built now from INPUT would be stamped with.
stamp() {
  sha256sum "$bin/tinstream" "${BASH_SOURCE[0]}" | cut -d' ' -f1
  echo "$(realpath -m "$1") $(stat -c %s "$1" 2>/dev/null || echo absent)"
}
# fresh STORE INPUT: STORE exists and was built by this tinstream and script from INPUT.
fresh() { [[ -f $out/$1 && -f $out/$1.stamp ]] && [[ $(stamp "$2") == "$(cat "$out/$1.stamp")" ]]; }

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

# replace STORE: the freshly ingested STORE.tmp becomes STORE (its old WAL files go first, and the
# stamp is written last, so an interrupted run rebuilds).
replace() {
  rm -f "$out/$1" "$out/$1-wal" "$out/$1-shm" "$out/$1.stamp"
  mv "$out/$1.tmp" "$out/$1"
  stamp "$2" > "$out/$1.stamp"
}

dem=$data/bigtujunga_srtm30m_utm11.tif
if ! fresh dem.sqlite "$dem"; then
  rm -f "$out"/dem.sqlite.tmp*
  if [[ -f $dem ]]; then
    ingest dem.sqlite dem "$dem"
    echo "dem: $dem" > "$out/dem.source"
  else
    ingest dem.sqlite dem "$(sample)"
    echo "dem: synthetic (tinstream sample)" > "$out/dem.source"
  fi
  replace dem.sqlite "$dem"
fi

lidar=$data/autzen_trim.las
if ! fresh lidar.sqlite "$lidar"; then
  rm -f "$out"/lidar.sqlite.tmp*
  input=$lidar
  [[ -f $input ]] || input=$(sample)
  ingest lidar.sqlite lidar "$input"
  ingest lidar.sqlite lidar_ell --projection ellipsoidal "$input"
  echo "lidar: $input" > "$out/lidar.source"
  replace lidar.sqlite "$lidar"
fi
cat "$out/dem.source" "$out/lidar.source"
