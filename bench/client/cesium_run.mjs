// Runs cesium.html once in Debian's headless Chromium (playwright-core, no browser download) and
// prints one JSON line: CesiumJS's time to a complete view and what crossed the proxy.
//   node cesium_run.mjs --proxy http://127.0.0.1:P --layer L --camera lon,lat,h,heading,pitch
//                       [--sse 2] [--size 1280x720] [--fov 60] [--timeout-s 300] [--shot file.png]
// The proxy's counters are reset before the page loads; only /tiles and /layers are counted, so
// the bytes are terrain (and layer.json), not CesiumJS's own scripts.
import { chromium } from 'playwright-core';

function arg(name, fallback) {
  const i = process.argv.indexOf(name);
  return i > 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
}

const proxy = arg('--proxy');
const [width, height] = arg('--size', '1280x720').split('x').map(Number);
const timeoutMs = Number(arg('--timeout-s', '300')) * 1000;
const shot = arg('--shot', '');
const query = new URLSearchParams({ layer: arg('--layer'), camera: arg('--camera'),
                                    sse: arg('--sse', '2'), fov: arg('--fov', '60') });

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
         '--disable-dev-shm-usage', '--disable-background-networking', '--disable-component-update',
         '--disable-sync', '--no-first-run'],
});
let out;
try {
  const page = await browser.newPage({ viewport: { width, height }, deviceScaleFactor: 1 });
  const console_ = [];
  page.on('console', (m) => { if (m.type() === 'error') console_.push(m.text()); });
  await fetch(`${proxy}/__reset`);
  const wall = Date.now();
  await page.goto(`${proxy}/cesium.html?${query}`);
  await page.waitForFunction(() => window.benchResult !== undefined, null,
                             { timeout: timeoutMs, polling: 100 });
  const result = await page.evaluate(() => window.benchResult);
  const proxyStats = await (await fetch(`${proxy}/__stats`)).json();
  if (shot) await page.screenshot({ path: shot });
  out = { client: 'cesium', ...result, page_wall_ms: Date.now() - wall, proxy: proxyStats,
          console_errors: console_.slice(0, 5) };
} catch (e) {
  let progress = null;
  try { progress = await browser.contexts()[0].pages()[0].evaluate(() => window.benchProgress); }
  catch { /* the page is gone */ }
  out = { client: 'cesium', error: String(e && e.message || e), progress };
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
process.exit(out.error ? 1 : 0);
