// The CesiumJS viewer of tinstream-server: a layer picker fed by /layers, the layer's
// quantized-mesh terrain (/tiles/{layer}/layer.json) with its imagery (/imagery/...), the camera
// flown to the layer's bounds, and a panel with the height of the clicked point.
//
// URL parameters: ?layer=NAME (terrain layer), &imagery=NAME|none, &fly=0 (jump, no flight).
// window.tinstream exposes the viewer and a `ready` promise (the layer is shown and the camera
// in place) for the end-to-end tests (tests/web).
const Cesium = window.Cesium;
Cesium.Ion.defaultAccessToken = '';  // no Cesium ion: every resource comes from this server

const params = new URLSearchParams(window.location.search);
const statusLine = document.getElementById('status');
const layerSelect = document.getElementById('layer');
const imagerySelect = document.getElementById('imagery');

const app = {
  viewer: null,
  layers: [],
  imagery: [],
  layer: null,
  imageryLayer: null,
  terrainProvider: null,
  errors: [],
  ready: null,
};
window.tinstream = app;

function status(text, isError = false) {
  statusLine.textContent = text;
  statusLine.classList.toggle('error', isError);
  if (isError) app.errors.push(text);
}

// The Natural Earth II texture shipped inside CesiumJS (served from here) under everything.
const baseLayer = Cesium.ImageryLayer.fromProviderAsync(
  Cesium.TileMapServiceImageryProvider.fromUrl(Cesium.buildModuleUrl('Assets/Textures/NaturalEarthII')));

const viewer = new Cesium.Viewer('viewer', {
  baseLayer,
  baseLayerPicker: false,
  geocoder: false,
  homeButton: false,
  sceneModePicker: false,
  navigationHelpButton: false,
  animation: false,
  timeline: false,
  fullscreenButton: false,
  infoBox: false,
  selectionIndicator: false,
  requestRenderMode: false,
});
viewer.scene.globe.enableLighting = false;
viewer.scene.globe.depthTestAgainstTerrain = true;
app.viewer = viewer;

function rectangleOf(b) {
  return Cesium.Rectangle.fromDegrees(b.west, b.south, b.east, b.north);
}

// Terrain: CesiumTerrainProvider.fromUrl does not reject on a 404 layer.json, so layer.json is
// fetched first and its failure reported.
async function terrainFor(layer) {
  const url = `/tiles/${encodeURIComponent(layer.name)}`;
  const check = await fetch(`${url}/layer.json`);
  if (!check.ok) {
    const body = await check.json().catch(() => ({}));
    throw new Error(`terrain of "${layer.name}": ${body.error || check.statusText} (HTTP ${check.status})`);
  }
  return Cesium.CesiumTerrainProvider.fromUrl(url, { requestVertexNormals: true });
}

function imageryProviderFor(im) {
  return new Cesium.UrlTemplateImageryProvider({
    url: im.tiles,  // XYZ rows: {y} counts from the north
    tilingScheme: new Cesium.WebMercatorTilingScheme(),
    rectangle: rectangleOf(im.bounds),
    minimumLevel: im.min_level,
    maximumLevel: im.max_level,
    tileWidth: im.tile_size,
    tileHeight: im.tile_size,
    credit: im.attribution || undefined,
  });
}

function setImagery(name) {
  if (app.imageryLayer) {
    viewer.imageryLayers.remove(app.imageryLayer, true);
    app.imageryLayer = null;
  }
  const im = app.imagery.find((i) => i.name === name);
  if (!im) return;
  app.imageryLayer = viewer.imageryLayers.addImageryProvider(imageryProviderFor(im));
}

// Flies (or jumps, fly=0) to an oblique view of the layer's bounds, looking north.
function flyTo(layer) {
  const b = layer.bounds;
  const centre = Cesium.Cartographic.fromDegrees((b.west + b.east) / 2, (b.south + b.north) / 2,
                                                 (layer.min_z + layer.max_z) / 2);
  const corner = Cesium.Cartographic.fromDegrees(b.west, b.south, centre.height);
  const ellipsoid = viewer.scene.globe.ellipsoid;
  const radius = Cesium.Cartesian3.distance(ellipsoid.cartographicToCartesian(centre),
                                            ellipsoid.cartographicToCartesian(corner));
  const sphere = new Cesium.BoundingSphere(ellipsoid.cartographicToCartesian(centre), radius);
  const offset = new Cesium.HeadingPitchRange(0, Cesium.Math.toRadians(-40), radius * 2.2);
  const duration = params.get('fly') === '0' ? 0 : 2;
  return new Promise((resolve) => {
    viewer.camera.flyToBoundingSphere(sphere, { offset, duration, complete: resolve, cancel: resolve });
  });
}

async function showLayer(name) {
  const layer = app.layers.find((l) => l.name === name);
  if (!layer) throw new Error(`no terrain layer "${name}"`);
  status(`Loading ${name}…`);
  app.terrainProvider = await terrainFor(layer);
  viewer.terrainProvider = app.terrainProvider;
  app.layer = layer;
  document.getElementById('maplibre-link').href = `/maplibre?layer=${encodeURIComponent(name)}`;
  await flyTo(layer);
  const range = `${layer.min_z.toFixed(1)}–${layer.max_z.toFixed(1)} m`;
  status(`${name}: levels ${layer.min_level}–${layer.max_level}, heights ${range}`);
}

function fillSelect(select, entries, selected) {
  select.replaceChildren();
  for (const { value, label, disabled } of entries) {
    const option = document.createElement('option');
    option.value = value;
    option.textContent = label;
    option.disabled = Boolean(disabled);
    select.append(option);
  }
  select.value = selected;
}

// The height panel: the clicked point on the globe, then its terrain height sampled from the
// most detailed tiles (what the layer says there, not the rendered level's).
const pickWhere = document.getElementById('pick-where');
const pickHeight = document.getElementById('pick-height');
const handler = new Cesium.ScreenSpaceEventHandler(viewer.scene.canvas);
handler.setInputAction(async (click) => {
  const ray = viewer.camera.getPickRay(click.position);
  const hit = ray && viewer.scene.globe.pick(ray, viewer.scene);
  if (!hit) {
    pickWhere.textContent = 'off the globe';
    pickHeight.textContent = '–';
    return;
  }
  const c = Cesium.Cartographic.fromCartesian(hit);
  const lon = Cesium.Math.toDegrees(c.longitude);
  const lat = Cesium.Math.toDegrees(c.latitude);
  pickWhere.textContent = `${lon.toFixed(6)}°, ${lat.toFixed(6)}°`;
  pickHeight.textContent = `${c.height.toFixed(2)} m (rendered)`;
  pickHeight.dataset.lon = String(lon);
  pickHeight.dataset.lat = String(lat);
  if (app.terrainProvider) {
    const [sampled] = await Cesium.sampleTerrainMostDetailed(app.terrainProvider,
                                                             [Cesium.Cartographic.fromDegrees(lon, lat)]);
    if (sampled && Number.isFinite(sampled.height)) {
      pickHeight.textContent = `${sampled.height.toFixed(2)} m`;
      pickHeight.dataset.height = String(sampled.height);
    }
  }
}, Cesium.ScreenSpaceEventType.LEFT_CLICK);

async function start() {
  const response = await fetch('/layers');
  if (!response.ok) throw new Error(`/layers: HTTP ${response.status}`);
  const doc = await response.json();
  app.layers = doc.layers || [];
  app.imagery = (doc.imagery || []).filter((i) => i.projection === 'spherical');
  const usable = app.layers.filter((l) => l.projection === 'spherical');
  fillSelect(layerSelect, app.layers.map((l) => ({
    value: l.name,
    label: l.projection === 'spherical' ? l.name : `${l.name} (ellipsoidal: native client only)`,
    disabled: l.projection !== 'spherical',
  })), '');
  const wanted = params.get('layer') || (usable[0] && usable[0].name);
  if (!wanted) {
    status('The store has no spherical terrain layer yet: ingest one with `tinstream ingest`.', true);
    return;
  }
  layerSelect.value = wanted;
  const wantedImagery = params.get('imagery') ||
      (app.imagery.some((i) => i.name === wanted) ? wanted : 'none');
  fillSelect(imagerySelect, [{ value: 'none', label: '(none)' }].concat(
    app.imagery.map((i) => ({ value: i.name, label: `${i.name} (${i.format})` }))), wantedImagery);
  setImagery(wantedImagery);
  await showLayer(wanted);
}

layerSelect.addEventListener('change', () => {
  const name = layerSelect.value;
  if (app.imagery.some((i) => i.name === name)) {
    imagerySelect.value = name;
    setImagery(name);
  }
  showLayer(name).catch((e) => status(e.message, true));
});
imagerySelect.addEventListener('change', () => setImagery(imagerySelect.value));

app.ready = start().catch((e) => {
  status(e.message, true);
  throw e;
});
