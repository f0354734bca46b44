// What the browser tests share: the real tinstream-server on 127.0.0.1 (port 0), Debian's
// Chromium driven by playwright-core (never a downloaded browser), a record of every request,
// response and page error, and waits that poll a condition until a deadline (never a fixed
// sleep): the tests must hold on a loaded 2-core machine.
//
// Configuration comes from the environment, set by tests/web/CMakeLists.txt:
//   TINSTREAM_SERVER     the tinstream-server executable
//   TINSTREAM_WEB_ROOT   the built viewers (build/web)
//   TINSTREAM_WEB_NPM    the folder whose node_modules hold playwright-core
//   TINSTREAM_FIXTURE    the fixture folder (store.sqlite, points.json; tests/web/prepare.mjs)
//   CHROMIUM             the browser (default /usr/bin/chromium)
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';

export function env(name, fallback) {
  const v = process.env[name] || fallback;
  if (!v) throw new Error(`${name} is not set (run the browser tests through ctest)`);
  return v;
}

export function fail(message) {
  throw new Error(message);
}

export function check(condition, message) {
  if (!condition) fail(message);
}

// Polls `probe` (async, returns a value or a falsy one) every `every` ms until it returns a truthy
// value, which is returned; fails with `what` and the last value seen after `ms`.
export async function waitFor(what, probe, ms, every = 250) {
  const deadline = Date.now() + ms;
  let last;
  for (;;) {
    last = await probe();
    if (last) return last;
    if (Date.now() > deadline) fail(`timed out after ${ms} ms waiting for ${what} (last: ${JSON.stringify(last)})`);
    await new Promise((r) => setTimeout(r, every));
  }
}

// Starts tinstream-server on a free loopback port; resolves once it prints "listening on".
export async function startServer(store) {
  const exe = env('TINSTREAM_SERVER');
  const child = spawn(exe, ['--store', store, '--address', '127.0.0.1', '--port', '0', '--threads', '2'], {
    env: { ...process.env, TINSTREAM_WEB_ROOT: env('TINSTREAM_WEB_ROOT') },
    stdio: ['ignore', 'pipe', 'pipe'],
  });
  let stderr = '';
  child.stderr.on('data', (d) => { stderr = (stderr + d).slice(-4000); });
  const port = await new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error(`tinstream-server did not start in 30 s: ${stderr}`)), 30000);
    child.stdout.on('data', (d) => {
      out += d;
      const m = /listening on [^\s:]+:(\d+)/.exec(out);
      if (m) {
        clearTimeout(timer);
        resolve(Number(m[1]));
      }
    });
    child.on('exit', (code) => {
      clearTimeout(timer);
      reject(new Error(`tinstream-server exited with ${code}: ${stderr}`));
    });
  });
  child.removeAllListeners('exit');
  return {
    base: `http://127.0.0.1:${port}`,
    stderr: () => stderr,
    async stop() {
      if (child.exitCode !== null) return;
      const exited = new Promise((r) => child.once('exit', r));
      child.kill('SIGTERM');
      const timer = setTimeout(() => child.kill('SIGKILL'), 10000);
      await exited;
      clearTimeout(timer);
    },
  };
}

// The flags known to give Chromium a working WebGL (SwiftShader) headless in a container.
const CHROMIUM_ARGS = [
  '--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--disable-dev-shm-usage', '--disable-background-networking', '--disable-component-update',
  '--disable-sync', '--no-first-run',
];

export async function launchBrowser() {
  const require = createRequire(path.resolve(env('TINSTREAM_WEB_NPM'), 'node_modules', 'noop.js'));
  const { chromium } = require('playwright-core');
  const executablePath = env('CHROMIUM', '/usr/bin/chromium');
  check(fs.existsSync(executablePath),
        `${executablePath} is missing: install Debian's chromium (scripts/install-deps.sh)`);
  return chromium.launch({ executablePath, args: CHROMIUM_ARGS, timeout: 60000 });
}

// A page with everything it does on record: requests (URL), responses (URL, status), failed
// requests, uncaught page errors and console errors.
export async function recordedPage(browser, viewport = { width: 1024, height: 700 }) {
  const context = await browser.newContext({ viewport, serviceWorkers: 'block' });
  const page = await context.newPage();
  const log = { requests: [], responses: [], failed: [], pageErrors: [], consoleErrors: [] };
  page.on('request', (r) => log.requests.push(r.url()));
  page.on('response', (r) => log.responses.push({ url: r.url(), status: r.status() }));
  page.on('requestfailed', (r) => log.failed.push({ url: r.url(), error: r.failure()?.errorText }));
  page.on('pageerror', (e) => log.pageErrors.push(String(e && e.stack ? e.stack : e)));
  page.on('console', (m) => { if (m.type() === 'error') log.consoleErrors.push(m.text()); });
  return { page, log };
}

// Every request stayed on the server under test (or was local: data:, blob:).
export function checkNoForeignRequests(log, base) {
  const foreign = log.requests.filter((u) => !u.startsWith(`${base}/`) && !/^(data|blob):/.test(u));
  check(foreign.length === 0, `requests left ${base}: ${foreign.slice(0, 5).join(', ')}`);
}

export function responsesMatching(log, re) {
  return log.responses.filter((r) => re.test(r.url));
}

// Distinct colours in the middle of a PNG screenshot (decoded by the browser itself, in a blank
// page: no request leaves it).
export async function distinctColours(browser, png) {
  const page = await browser.newPage();
  try {
    return await page.evaluate(async (b64) => {
      const img = new Image();
      img.src = `data:image/png;base64,${b64}`;
      await img.decode();
      const canvas = document.createElement('canvas');
      canvas.width = img.width;
      canvas.height = img.height;
      const g = canvas.getContext('2d');
      g.drawImage(img, 0, 0);
      const x0 = Math.floor(img.width * 0.3), y0 = Math.floor(img.height * 0.3);
      const data = g.getImageData(x0, y0, Math.floor(img.width * 0.4), Math.floor(img.height * 0.4)).data;
      const seen = new Set();
      for (let i = 0; i < data.length; i += 4) seen.add((data[i] << 16) | (data[i + 1] << 8) | data[i + 2]);
      return seen.size;
    }, png.toString('base64'));
  } finally {
    await page.close();
  }
}

// Writes a screenshot to $TINSTREAM_SCREENSHOTS/<name>.png when that folder is given (README
// images, debugging).
export function saveScreenshot(name, png) {
  const dir = process.env.TINSTREAM_SCREENSHOTS;
  if (!dir) return;
  fs.mkdirSync(dir, { recursive: true });
  fs.writeFileSync(path.join(dir, `${name}.png`), png);
}

export function fixture() {
  const dir = env('TINSTREAM_FIXTURE');
  const points = JSON.parse(fs.readFileSync(path.join(dir, 'points.json'), 'utf8')).points;
  return { dir, store: path.join(dir, 'store.sqlite'), points };
}

// Runs `body` with a server and a browser, always stopping both, with an overall deadline.
export async function run(name, body, ms = 240000) {
  const started = Date.now();
  let server, browser;
  const timer = setTimeout(() => {
    console.error(`${name}: overall deadline of ${ms} ms passed`);
    process.exit(1);
  }, ms);
  try {
    const { store } = fixture();
    server = await startServer(store);
    browser = await launchBrowser();
    console.log(`${name}: server and browser up after ${((Date.now() - started) / 1000).toFixed(1)} s`);
    await body({ server, browser });
    console.log(`${name}: passed in ${((Date.now() - started) / 1000).toFixed(1)} s`);
  } catch (e) {
    console.error(`${name}: FAILED: ${e.stack || e}`);
    if (server) console.error(`server stderr (tail):\n${server.stderr()}`);
    process.exitCode = 1;
  } finally {
    clearTimeout(timer);
    if (browser) await browser.close().catch(() => {});
    if (server) await server.stop().catch(() => {});
  }
}
