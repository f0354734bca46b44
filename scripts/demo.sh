#!/usr/bin/env bash
# The main job on the built-in sample (what `make demo` runs after installing and building):
#   1. generate a synthetic LiDAR point cloud (fractal mountains, LAS, EPSG:32632) and an
#      orthophoto of the same mountains (RGB GeoTIFF),
#   2. ingest both into an SQLite tile store (TIN tiles + LOD pyramid, imagery tiles on the same
#      quadtree) and verify the terrain,
#   3. serve it with tinstream-server and show what a client gets (layers, a native tile,
#      Cesium layer.json and a quantized-mesh tile, an OBJ export),
#   4. render it with tinstream-viewer --headless (EGL on Mesa) into $build/demo/snapshot.png and
#      print its path (and open the viewer's window when there is a display and a terminal),
#   5. keep serving until Ctrl-C when run from a terminal (stop at once otherwise).
set -euo pipefail
build=${1:-build}
bin="$build/bin"
out="$build/demo"
port=${TINSTREAM_DEMO_PORT:-8080}
mkdir -p "$out"

step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

step "1. Sample data: synthetic LiDAR over fractal mountains"
"$bin/tinstream" sample --out "$out/sample.las" --points 300000 --density 0.05 \
  --ortho "$out/sample-ortho.tif"

step "2. Ingest into $out/demo.sqlite (finest TIN tiles + level-of-detail pyramid)"
rm -f "$out/demo.sqlite" "$out/demo.sqlite-wal" "$out/demo.sqlite-shm"
"$bin/tinstream" ingest --store "$out/demo.sqlite" --layer sample --epsilon 0.5 "$out/sample.las"
"$bin/tinstream" verify --store "$out/demo.sqlite" --layer sample -q | head -12
echo "its imagery (layer of the same name: the browser viewers drape it):"
"$bin/tinstream" ingest-imagery --store "$out/demo.sqlite" --layer sample --format webp \
  "$out/sample-ortho.tif"

if [[ ! -x "$bin/tinstream-server" ]]; then
  echo "tinstream-server was not built; stopping after the ingest."
  exit 0
fi

step "3. Serve it: tinstream-server on 127.0.0.1:$port"
rm -f "$out/server.out"  # a stale "listening" line of an earlier demo must not be read as this one's
"$bin/tinstream-server" --config config/server.json --store "$out/demo.sqlite" --address 127.0.0.1 \
  --port "$port" > "$out/server.out" 2> "$out/server.log" &
server=$!
trap 'kill $server 2>/dev/null || true; wait $server 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q "listening" "$out/server.out" 2>/dev/null && break
  kill -0 $server 2>/dev/null || break
  sleep 0.1
done
if ! grep -q "listening" "$out/server.out" 2>/dev/null; then
  echo "tinstream-server did not start listening on 127.0.0.1:$port (TINSTREAM_DEMO_PORT picks another port):" >&2
  tail -n 20 "$out/server.log" >&2
  exit 1
fi
base="http://127.0.0.1:$port"
echo "GET $base/healthz"; curl -fsS "$base/healthz"; echo
echo "GET $base/layers/sample"; curl -fsS "$base/layers/sample" | head -c 800; echo
quadkey=$(sqlite3 "$out/demo.sqlite" "SELECT quadkey FROM published_tiles WHERE layer = 'sample' ORDER BY z DESC LIMIT 1" 2>/dev/null || true)
if [[ -n $quadkey ]]; then
  echo "GET $base/tiles/sample/$quadkey (native TIN tile, deflate)"
  curl -fsS --compressed -o "$out/tile.bin" -D - "$base/tiles/sample/$quadkey" | grep -iE '^(HTTP|etag|content-)'
  echo "export as OBJ (lon lat height; NODATA corners at the data's edge left out):"
  "$bin/tinstream" export --store "$out/demo.sqlite" --layer sample --tile "$quadkey" --format obj \
    --drop-nodata --out "$out/tile.obj"
  head -3 "$out/tile.obj"; echo "… $(grep -c '^f' "$out/tile.obj") triangles in $out/tile.obj"
fi
echo "GET $base/tiles/sample/layer.json (Cesium terrain)"
curl -fsS --compressed "$base/tiles/sample/layer.json" | head -c 400; echo

if [[ -x "$bin/tinstream-viewer" ]]; then
  step "4. Look at it: tinstream-viewer, headless (EGL on Mesa), streaming from $base"
  rm -f "$out/snapshot.png"
  if "$bin/tinstream-viewer" --headless --url "$base" --layer sample --imagery sample --size 1280x720 --timeout 300 \
      --out "$out/snapshot.png" --stats "$out/snapshot.json"; then
    echo "statistics: $(head -c 300 "$out/snapshot.json") … (all of it in $out/snapshot.json)"
  else
    echo "tinstream-viewer did not finish the view (exit status $?); see above"
  fi
  if [[ -f $out/snapshot.png ]]; then echo "snapshot: $(realpath "$out/snapshot.png")"; fi
  if [[ -t 0 && ( -n ${DISPLAY:-} || -n ${WAYLAND_DISPLAY:-} ) ]]; then
    echo "opening the viewer window (close it to go on)"
    "$bin/tinstream-viewer" --url "$base" --layer sample --imagery sample || true
  fi
fi

echo
echo "server: $base  (layers: $base/layers, native tiles: $base/tiles/sample/{quadkey},"
echo "        Cesium terrain: $base/tiles/sample/)"
if [[ -t 0 ]]; then
  step "Serving $base until Ctrl-C (Cesium terrain URL: $base/tiles/sample/)"
  echo "In a browser: $base/ (CesiumJS) or $base/maplibre (MapLibre GL JS, raster-DEM terrain)"
  wait $server
fi
