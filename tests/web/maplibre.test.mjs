// End to end: the MapLibre GL JS page of tinstream-server in Debian's Chromium (headless,
// SwiftShader WebGL). The page must show the fixture's layer in 3D from raster-DEM tiles
// rendered out of its TIN, with hillshade and the draped imagery, loaded from the server alone;
// queryTerrainElevation at known ground points must give the generated DEM's heights, in both
// encodings (Terrarium and Mapbox Terrain-RGB).
import {
  check, checkNoForeignRequests, distinctColours, fixture, recordedPage, responsesMatching, run,
  saveScreenshot, waitFor,
} from './harness.mjs';

// MapLibre interpolates bilinearly between the raster's pixel centres (2.4 m apart at level 16,
// on hills of 10 m cells): well under a metre of difference to the TIN on this smooth surface,
// plus the encoding's half step.
const HEIGHT_TOLERANCE = 1.0;

async function checkEncoding(browser, server, encoding) {
  const { points } = fixture();
  const { page, log } = await recordedPage(browser);
  const t0 = Date.now();
  const mark = (what) => console.log(`web_maplibre ${encoding}: ${what} after ${((Date.now() - t0) / 1000).toFixed(1)} s`);
  await page.goto(`${server.base}/maplibre?layer=demo&encoding=${encoding}`, { waitUntil: 'load', timeout: 60000 });
  await waitFor('window.tinstream.ready', () => page.evaluate(() => Boolean(window.tinstream && window.tinstream.ready)), 30000);
  const started = await page.evaluate(() => window.tinstream.ready.then(() => 'ok', (e) => `failed: ${e.message}`));
  check(started === 'ok', `the viewer did not start: ${started}`);
  mark('map idle');
  const demTiles = new RegExp(`/tiles/demo/\\d+/\\d+/\\d+\\.png\\?encoding=${encoding}`);
  await waitFor('raster-DEM tiles (200)', () => responsesMatching(log, demTiles).filter((r) => r.status === 200).length >= 1, 60000);
  await waitFor('imagery tiles (200)', () => responsesMatching(log, /\/imagery\/demo\/\d+\/\d+\/\d+\.jpg/)
    .filter((r) => r.status === 200).length >= 1, 60000);
  const colours = await (async () => {
    const shot = await page.screenshot();
    saveScreenshot(`maplibre-${encoding}`, shot);
    return distinctColours(browser, shot);
  })();
  check(colours >= 1000, `only ${colours} distinct colours in the middle of the view`);

  // Heights: the map shows the whole layer from above at one zoom below the finest level, where
  // MapLibre (512-pixel zoom levels) reads the finest 256-pixel raster-DEM tiles.
  const layer = await page.evaluate(() => window.tinstream.layer);
  const heights = await page.evaluate(async ({ pts, zoom, b }) => {
    const map = window.tinstream.map;
    map.jumpTo({ center: [(b.west + b.east) / 2, (b.south + b.north) / 2], zoom, pitch: 0, bearing: 0 });
    await new Promise((resolve) => map.once('idle', resolve));
    return pts.map((p) => map.queryTerrainElevation([p.lon, p.lat]));
  }, { pts: points, zoom: layer.max_level - 1, b: layer.bounds });
  points.forEach((p, i) => {
    const h = heights[i];
    check(h !== null && Math.abs(h - p.height) <= HEIGHT_TOLERANCE,
          `${encoding}: queryTerrainElevation at ${p.lon},${p.lat} is ${h} m, the DEM says ${p.height} m`);
  });
  // No wall at the data's edge: the layer's bounding box (lon/lat) reaches past the UTM
  // rectangle of the DEM, into the NODATA triangles of the edge tiles. Seen whole, every point of
  // it must stand within the layer's height range (a transparent NODATA pixel, premultiplied by
  // the browser, would read as −32768 m in Terrarium, −10000 m in Terrain-RGB).
  const edge = await page.evaluate(async ({ b }) => {
    const map = window.tinstream.map;
    map.fitBounds([[b.west, b.south], [b.east, b.north]], { pitch: 0, bearing: 0, padding: 20, duration: 0 });
    await new Promise((resolve) => map.once('idle', resolve));
    const out = [];
    for (let i = 0; i <= 12; ++i) {
      for (let j = 0; j <= 12; ++j) {
        const lon = b.west + (b.east - b.west) * (0.001 + 0.998 * i / 12);
        const lat = b.south + (b.north - b.south) * (0.001 + 0.998 * j / 12);
        out.push({ lon, lat, h: map.queryTerrainElevation([lon, lat]) });
      }
    }
    return out;
  }, { b: layer.bounds });
  const walls = edge.filter((p) => p.h === null || p.h < layer.min_z - 1 || p.h > layer.max_z + 1);
  check(walls.length === 0, `${encoding}: heights outside ${layer.min_z}–${layer.max_z} m in the ` +
        `layer's bounds: ${JSON.stringify(walls.slice(0, 4))}`);
  const finest = new RegExp(`/tiles/demo/${layer.max_level}/\\d+/\\d+\\.png`);
  check(responsesMatching(log, finest).length > 0, `no raster-DEM tile of level ${layer.max_level} was read`);
  mark('heights checked');
  const badDem = responsesMatching(log, /\/tiles\/demo\//).filter((r) => r.status !== 200);
  check(badDem.length === 0, `raster-DEM tiles that failed: ${JSON.stringify(badDem.slice(0, 5))}`);
  const errors = await page.evaluate(() => window.tinstream.errors);
  check(errors.length === 0, `the viewer reported errors: ${errors.join('; ')}`);
  checkNoForeignRequests(log, server.base);
  check(log.pageErrors.length === 0, `page errors: ${log.pageErrors.join('\n')}`);
  check(log.failed.length === 0, `failed requests: ${JSON.stringify(log.failed.slice(0, 5))}`);
  console.log(`web_maplibre ${encoding}: ${log.requests.length} requests, ${points.length} heights ` +
              `within ${HEIGHT_TOLERANCE} m, ${colours} colours`);
  await page.context().close();
}

await run('web_maplibre', async ({ server, browser }) => {
  await checkEncoding(browser, server, 'terrarium');
  await checkEncoding(browser, server, 'mapbox');
});
