# shellcheck shell=bash
# bench/client/store.sh — sourced by run.sh and rss_flight.sh (needs ROOT, BUILD, BIN, OUT).
# pick_store sets `store` and `layer`: STORE_IN + LAYER when given, else the client tests' DEM
# store ($BUILD/tests/client/stores/dem.sqlite, Big Tujunga SRTM 30 m) when built, else
# `tinstream ingest` of ../shared/data's Big Tujunga DEM into $OUT (made once), else of
# `tinstream sample`'s synthetic LiDAR.
pick_store() {
  if [[ -n ${STORE_IN:-} ]]; then
    store=$STORE_IN
    layer=${LAYER:?LAYER= names the layer of STORE_IN}
  elif [[ -f $BUILD/tests/client/stores/dem.sqlite ]]; then
    store=$BUILD/tests/client/stores/dem.sqlite
    layer=dem
  else
    store=$OUT/bench.sqlite
    layer=dem
    if [[ ! -f $store ]]; then
      dem=$ROOT/../shared/data/bigtujunga_srtm30m_utm11.tif
      if [[ -f $dem ]]; then input=$dem; else
        "$BIN/tinstream" sample --out "$OUT/sample.las" --points 1000000 --density 0.05
        input=$OUT/sample.las
      fi
      echo "ingesting $input into $store"
      "$BIN/tinstream" ingest --store "$store.tmp" --layer "$layer" "$input"
      mv "$store.tmp" "$store"
    fi
  fi
}
