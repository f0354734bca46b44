// End to end: the CesiumJS page of tinstream-server in Debian's Chromium (headless, SwiftShader
// WebGL). The page must load the fixture's terrain layer and its imagery from the server alone,
// without a page error or Cesium's error panel; its terrain must give the generated DEM's
// heights at known ground points (sampleTerrainMostDetailed); a click must put a height in the
// panel; and the rendering must show the draped imagery (many distinct colours).
//
// Pitfalls this test avoids: `globe.tilesLoaded` is true even when every terrain tile failed
// (so terrain responses are counted, by status), and a 404 layer.json does not reject
// CesiumTerrainProvider.fromUrl (so the page's own readiness and error list are checked).
import {
  check, checkNoForeignRequests, distinctColours, fixture, recordedPage, responsesMatching, run,
  saveScreenshot, waitFor,
} from './harness.mjs';

const HEIGHT_TOLERANCE = 0.25;  // metres: quantized-mesh keeps about 1 cm on this height range

await run('web_cesium', async ({ server, browser }) => {
  const { points } = fixture();
  const { page, log } = await recordedPage(browser, { width: 800, height: 520 });
  const t0 = Date.now();
  const mark = (what) => console.log(`web_cesium: ${what} after ${((Date.now() - t0) / 1000).toFixed(1)} s`);
  await page.goto(`${server.base}/?layer=demo&fly=0`, { waitUntil: 'load', timeout: 60000 });

  // The page's own start: /layers read, layer.json checked, terrain and imagery set, camera placed.
  await waitFor('window.tinstream.ready', () => page.evaluate(() => Boolean(window.tinstream && window.tinstream.ready)), 30000);
  const started = await page.evaluate(() => window.tinstream.ready.then(() => 'ok', (e) => `failed: ${e.message}`));
  check(started === 'ok', `the viewer did not start: ${started}`);
  mark('viewer ready');
  const errors = await page.evaluate(() => window.tinstream.errors);
  check(errors.length === 0, `the viewer reported errors: ${errors.join('; ')}`);
  const status = await page.textContent('#status');
  check(/^demo: levels 0–\d+/.test(status), `status line: ${status}`);

  // Terrain and imagery tiles arrive with 200, and the globe settles.
  await waitFor('terrain tiles (200)', () => responsesMatching(log, /\/tiles\/demo\/\d+\/\d+\/\d+\.terrain/)
    .filter((r) => r.status === 200).length >= 4, 120000);
  await waitFor('imagery tiles (200)', () => responsesMatching(log, /\/imagery\/demo\/\d+\/\d+\/\d+\.jpg/)
    .filter((r) => r.status === 200).length >= 2, 120000);
  await waitFor('globe.tilesLoaded', () => page.evaluate(() => window.tinstream.viewer.scene.globe.tilesLoaded), 120000);
  mark('tiles loaded');
  const layerJson = responsesMatching(log, /\/tiles\/demo\/layer\.json/);
  check(layerJson.length > 0 && layerJson.every((r) => r.status === 200), `layer.json: ${JSON.stringify(layerJson)}`);
  const badTerrain = responsesMatching(log, /\.terrain/).filter((r) => r.status !== 200);
  check(badTerrain.length === 0, `terrain tiles that failed: ${JSON.stringify(badTerrain.slice(0, 5))}`);
  const badImagery = responsesMatching(log, /\/imagery\//).filter((r) => r.status !== 200);
  check(badImagery.length === 0, `imagery tiles that failed: ${JSON.stringify(badImagery.slice(0, 5))}`);
  check((await page.$('.cesium-widget-errorPanel')) === null, 'Cesium shows its error panel');

  // Heights at the DEM's own cell centres, from the most detailed tiles.
  const sampled = await page.evaluate(async (pts) => {
    const C = window.Cesium;
    const carto = pts.map((p) => C.Cartographic.fromDegrees(p.lon, p.lat));
    const result = await C.sampleTerrainMostDetailed(window.tinstream.terrainProvider, carto);
    return result.map((c) => c.height);
  }, points);
  points.forEach((p, i) => {
    check(Number.isFinite(sampled[i]) && Math.abs(sampled[i] - p.height) <= HEIGHT_TOLERANCE,
          `ground point ${p.lon},${p.lat}: Cesium samples ${sampled[i]} m, the DEM says ${p.height} m`);
  });

  // The panel: a click in the middle of the view gives a height within the layer's range.
  const layer = await page.evaluate(() => window.tinstream.layer);
  await page.mouse.click(400, 300);
  const picked = Number(await waitFor('a picked height', () => page.getAttribute('#pick-height', 'data-height'), 30000));
  check(picked >= layer.min_z - 1 && picked <= layer.max_z + 1,
        `picked height ${picked} m outside ${layer.min_z}–${layer.max_z} m`);

  // What is on screen: the imagery draped on the terrain, i.e. many colours in the middle.
  const shot = await page.screenshot();
  saveScreenshot('cesium', shot);
  const colours = await distinctColours(browser, shot);
  check(colours >= 1000, `only ${colours} distinct colours in the middle of the view`);

  // The layer picker: filled from /layers, switching loads the other layer's terrain (its
  // layer.json and tiles, 200) and points the MapLibre link at it.
  const options = await page.$$eval('#layer option', (os) => os.map((o) => o.value));
  check(options.includes('demo') && options.includes('coarse'), `layer picker offers ${options}`);
  await page.selectOption('#layer', 'coarse');
  await waitFor('the coarse layer shown', async () => /^coarse: levels/.test(await page.textContent('#status')), 60000);
  await waitFor('coarse terrain tiles (200)', () => responsesMatching(log, /\/tiles\/coarse\/\d+\/\d+\/\d+\.terrain/)
    .filter((r) => r.status === 200).length >= 1, 60000);
  const coarseJson = responsesMatching(log, /\/tiles\/coarse\/layer\.json/);
  check(coarseJson.length > 0 && coarseJson.every((r) => r.status === 200), `coarse layer.json: ${JSON.stringify(coarseJson)}`);
  const link = await page.getAttribute('#maplibre-link', 'href');
  check(link === '/maplibre?layer=coarse', `MapLibre link after switching: ${link}`);
  check(responsesMatching(log, /\.terrain/).every((r) => r.status === 200), 'a terrain tile failed after switching');
  mark('layer switched');

  // From space, with a whole hemisphere in view, the globe must settle too. CesiumJS cannot stand
  // in for a missing level-1 tile (180° wide) by upsampling its parent — it gets no horizon-
  // occlusion point, the tile stays failed and queued and tilesLoaded never holds — so the server
  // lists and serves every tile of levels 0 and 1 (terrain::kWholeLevels).
  await page.evaluate(() => new Promise((resolve) => {
    const C = window.Cesium;
    const scene = window.tinstream.viewer.scene;
    scene.camera.setView({ destination: C.Cartesian3.fromDegrees(-118.2, 34.3, 2.0e7) });
    let frames = 0;
    const stop = scene.postRender.addEventListener(() => { if (++frames >= 3) { stop(); resolve(); } });
    setTimeout(resolve, 5000);
    scene.requestRender();
  }));
  await waitFor('globe.tilesLoaded from space', () => page.evaluate(() => window.tinstream.viewer.scene.globe.tilesLoaded), 60000);
  const spaceBad = responsesMatching(log, /\.terrain/).filter((r) => r.status !== 200);
  check(spaceBad.length === 0, `terrain tiles that failed from space: ${JSON.stringify(spaceBad.slice(0, 5))}`);
  // No globe tile left failed (Cesium's TerrainState.FAILED is 0; tilesLoaded alone can hold
  // while a failed tile is no longer queued).
  const failedTiles = await page.evaluate(() => {
    const failed = [];
    const stack = [...window.tinstream.viewer.scene.globe._surface._levelZeroTiles];
    while (stack.length) {
      const t = stack.pop();
      if (t.data && t.data.terrainState === 0) failed.push(`${t.level}/${t.x}/${t.y}`);
      for (const c of [t._northwestChild, t._northeastChild, t._southwestChild, t._southeastChild]) {
        if (c) stack.push(c);
      }
    }
    return failed;
  });
  check(failedTiles.length === 0, `globe tiles whose terrain failed: ${failedTiles.join(', ')}`);
  check(new Set(responsesMatching(log, /\/tiles\/coarse\/1\/\d+\/\d+\.terrain/).map((r) => r.url)).size >= 2,
        'no level-1 terrain tile was requested from space');
  mark('tiles loaded from space');

  checkNoForeignRequests(log, server.base);
  check(log.pageErrors.length === 0, `page errors: ${log.pageErrors.join('\n')}`);
  check(log.failed.length === 0, `failed requests: ${JSON.stringify(log.failed.slice(0, 5))}`);
  console.log(`web_cesium: ${log.requests.length} requests, heights within ${HEIGHT_TOLERANCE} m at ` +
              `${points.length} points, picked ${picked.toFixed(2)} m, ${colours} colours`);
});
