// The README's pictures (docs/images/cesium.png, maplibre.png): the two viewers of a store, shot
// in headless Chromium once every tile they asked for has arrived. Not a test.
//
//   TINSTREAM_SERVER=build/bin/tinstream-server TINSTREAM_WEB_ROOT=build/web \
//   TINSTREAM_WEB_NPM=build/web-npm node tests/web/screenshots.mjs STORE LAYER OUT_DIR [WxH]
// (WxH: the viewport, 1100x640 by default; docs/images/demo-cesium.png is `make demo`'s store,
// build/demo/demo.sqlite, layer sample, at 720x420.)
import fs from 'node:fs';
import path from 'node:path';
import { launchBrowser, recordedPage, startServer, waitFor } from './harness.mjs';

const [store, layer, out, size = '1100x640'] = process.argv.slice(2);
const [width, height] = size.split('x').map(Number);
if (!store || !layer || !out || !(width > 0 && height > 0)) {
  console.error('usage: node tests/web/screenshots.mjs STORE LAYER OUT_DIR [WxH]');
  process.exit(2);
}

// Waits until no request has been answered for `quiet` ms (the view has everything it wants).
async function settle(log, quiet = 4000, ms = 240000) {
  let count = -1, since = Date.now();
  await waitFor('the requests to settle', () => {
    if (log.responses.length !== count) {
      count = log.responses.length;
      since = Date.now();
    }
    return Date.now() - since > quiet;
  }, ms, 500);
}

const server = await startServer(path.resolve(store));
const browser = await launchBrowser();
try {
  fs.mkdirSync(out, { recursive: true });
  const viewport = { width, height };
  {
    const { page, log } = await recordedPage(browser, viewport);
    await page.goto(`${server.base}/?layer=${encodeURIComponent(layer)}&fly=0`);
    await waitFor('the viewer', () => page.evaluate(() => Boolean(window.tinstream && window.tinstream.ready)), 30000);
    await page.evaluate(() => window.tinstream.ready);
    await waitFor('globe.tilesLoaded', () => page.evaluate(() => window.tinstream.viewer.scene.globe.tilesLoaded), 240000);
    await settle(log);
    await page.mouse.click(Math.round(width * 0.55), Math.round(height * 0.6));
    await waitFor('a picked height', () => page.getAttribute('#pick-height', 'data-height'), 60000);
    await page.screenshot({ path: path.join(out, 'cesium.png') });
    await page.context().close();
  }
  {
    const { page, log } = await recordedPage(browser, viewport);
    await page.goto(`${server.base}/maplibre?layer=${encodeURIComponent(layer)}`);
    await waitFor('the viewer', () => page.evaluate(() => Boolean(window.tinstream && window.tinstream.ready)), 30000);
    await page.evaluate(() => window.tinstream.ready);
    await settle(log);
    await page.screenshot({ path: path.join(out, 'maplibre.png') });
    await page.context().close();
  }
  console.log(`screenshots in ${out}`);
} finally {
  await browser.close();
  await server.stop();
}
