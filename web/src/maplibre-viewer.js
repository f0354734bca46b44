// The MapLibre GL JS viewer of tinstream-server: the layer in 3D from raster-DEM tiles rendered
// out of its TIN (/tiles/{layer}/{z}/{x}/{y}.png?encoding=terrarium|mapbox), hillshaded, with
// the layer's imagery draped when there is some.
//
// URL parameters: ?layer=NAME, &encoding=terrarium|mapbox. window.tinstream exposes the map and
// a `ready` promise (terrain on, first tiles drawn) for the end-to-end tests (tests/web).
import * as maplibregl from '/web/maplibre/maplibre-gl.mjs';

const params = new URLSearchParams(window.location.search);
const statusLine = document.getElementById('status');
const layerSelect = document.getElementById('layer');
const encodingSelect = document.getElementById('encoding');
const app = { map: null, layer: null, errors: [], ready: null };
window.tinstream = app;

function status(text, isError = false) {
  statusLine.textContent = text;
  statusLine.classList.toggle('error', isError);
  if (isError) app.errors.push(text);
}

// An absolute URL template (concatenated: `new URL` would percent-encode its `{z}`).
function absolute(path) {
  return window.location.origin + path;
}

function styleFor(layer, imagery, encoding) {
  const b = layer.bounds;
  const bounds = [b.west, b.south, b.east, b.north];
  const dem = {
    type: 'raster-dem',
    tiles: [absolute(layer.raster_dem[encoding])],
    encoding,
    tileSize: 256,
    minzoom: layer.min_level,
    maxzoom: layer.max_level,
    bounds,
  };
  const style = {
    version: 8,
    sources: {
      // Two sources of the same tiles: MapLibre advises one for the terrain mesh and one for
      // hillshading, which it prepares differently.
      terrain: dem,
      shading: { ...dem },
    },
    layers: [{ id: 'background', type: 'background', paint: { 'background-color': '#e8ecef' } }],
    terrain: { source: 'terrain', exaggeration: 1 },
  };
  if (imagery) {
    const ib = imagery.bounds;
    style.sources.imagery = {
      type: 'raster',
      tiles: [absolute(imagery.tiles)],
      tileSize: imagery.tile_size,
      minzoom: imagery.min_level,
      maxzoom: imagery.max_level,
      bounds: [ib.west, ib.south, ib.east, ib.north],
      attribution: imagery.attribution || undefined,
    };
    style.layers.push({ id: 'imagery', type: 'raster', source: 'imagery' });
  }
  style.layers.push({
    id: 'hillshade',
    type: 'hillshade',
    source: 'shading',
    paint: { 'hillshade-exaggeration': imagery ? 0.3 : 0.6 },
  });
  return style;
}

async function start() {
  const response = await fetch('/layers');
  if (!response.ok) throw new Error(`/layers: HTTP ${response.status}`);
  const doc = await response.json();
  const layers = (doc.layers || []).filter((l) => l.raster_dem);
  for (const l of layers) {
    const option = document.createElement('option');
    option.value = l.name;
    option.textContent = l.name;
    layerSelect.append(option);
  }
  const name = params.get('layer') || (layers[0] && layers[0].name);
  const layer = layers.find((l) => l.name === name);
  if (!layer) {
    status(name ? `no spherical terrain layer "${name}"` : 'The store has no spherical terrain layer yet.', true);
    return;
  }
  app.layer = layer;
  layerSelect.value = layer.name;
  const encoding = params.get('encoding') === 'mapbox' ? 'mapbox' : 'terrarium';
  encodingSelect.value = encoding;
  document.getElementById('cesium-link').href = `/?layer=${encodeURIComponent(layer.name)}`;
  const imagery = layer.imagery && layer.imagery.projection === 'spherical' ? layer.imagery : null;
  const b = layer.bounds;
  const map = new maplibregl.Map({
    container: 'map',
    style: styleFor(layer, imagery, encoding),
    bounds: [[b.west, b.south], [b.east, b.north]],
    // Room for the panel on the left; pitched after fitting, so the layer fills the view.
    fitBoundsOptions: { padding: { top: 60, bottom: 60, left: 300, right: 60 } },
    pitch: 45,
    maxPitch: 80,
  });
  app.map = map;
  map.addControl(new maplibregl.NavigationControl({ visualizePitch: true }));
  map.addControl(new maplibregl.TerrainControl({ source: 'terrain', exaggeration: 1 }));
  map.on('error', (e) => status(`map error: ${e.error ? e.error.message : e}`, true));
  map.on('click', (e) => {
    const height = map.queryTerrainElevation(e.lngLat);
    document.getElementById('pick-where').textContent =
        `${e.lngLat.lng.toFixed(6)}°, ${e.lngLat.lat.toFixed(6)}°`;
    const cell = document.getElementById('pick-height');
    cell.textContent = height === null ? '–' : `${height.toFixed(2)} m`;
    cell.dataset.height = height === null ? '' : String(height);
  });
  await new Promise((resolve) => map.once('idle', resolve));
  status(`${layer.name}: ${encoding} raster-DEM, levels ${layer.min_level}–${layer.max_level}` +
         (imagery ? `, imagery ${imagery.name}` : ''));
}

function reload() {
  const q = new URLSearchParams({ layer: layerSelect.value, encoding: encodingSelect.value });
  window.location.search = q.toString();
}
layerSelect.addEventListener('change', reload);
encodingSelect.addEventListener('change', reload);

app.ready = start().catch((e) => {
  status(e.message, true);
  throw e;
});
