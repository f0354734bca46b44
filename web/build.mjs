#!/usr/bin/env node
// Builds tinstream's browser viewers into one folder that tinstream-server serves (route family
// "web": `/` → index.html, `/maplibre` → maplibre.html, `/web/<path>` → <out>/<path>):
//
//   1. installs the npm packages of web/package-lock.json (cesium, maplibre-gl, and
//      playwright-core for the tests) into <npm-dir> with `npm ci`, when they are missing or
//      older than the lock file;
//   2. copies CesiumJS's Build/Cesium to <out>/cesium and MapLibre GL JS's dist to
//      <out>/maplibre, and the pages of web/src to <out>;
//   3. writes a .gz beside every compressible file over 1 KiB (the server sends it to clients
//      that take gzip);
//   4. writes <out>/build.json (versions, file count) last, as the build's stamp.
//
// Nothing is loaded from another host at run time: every script, style, worker, wasm and
// texture the pages use is in <out>.
//
//   node web/build.mjs --npm-dir build/web-npm --out build/web
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import zlib from 'node:zlib';

const here = path.dirname(fileURLToPath(import.meta.url));

function parseArgs(argv) {
  const args = { npmDir: null, out: null };
  for (let i = 2; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--npm-dir') args.npmDir = argv[++i];
    else if (a === '--out') args.out = argv[++i];
    else if (a === '--help' || a === '-h') {
      console.log('usage: node web/build.mjs --npm-dir DIR --out DIR');
      process.exit(0);
    } else {
      console.error(`web/build.mjs: unknown argument ${a}`);
      process.exit(2);
    }
  }
  if (!args.npmDir || !args.out) {
    console.error('web/build.mjs: --npm-dir and --out are required');
    process.exit(2);
  }
  return { npmDir: path.resolve(args.npmDir), out: path.resolve(args.out) };
}

function mtime(p) {
  try {
    return fs.statSync(p).mtimeMs;
  } catch {
    return -1;
  }
}

// npm ci into npmDir when its node_modules are absent or older than the lock file.
function installPackages(npmDir) {
  const lock = path.join(here, 'package-lock.json');
  const stamp = path.join(npmDir, 'node_modules', '.package-lock.json');
  if (mtime(stamp) >= mtime(lock) && mtime(stamp) >= mtime(path.join(npmDir, 'package-lock.json'))) {
    return;
  }
  fs.mkdirSync(npmDir, { recursive: true });
  fs.copyFileSync(path.join(here, 'package.json'), path.join(npmDir, 'package.json'));
  fs.copyFileSync(lock, path.join(npmDir, 'package-lock.json'));
  console.log(`web: npm ci in ${npmDir}`);
  try {
    execFileSync('npm', ['ci', '--no-audit', '--no-fund', '--loglevel=error', '--engine-strict=false'], {
      cwd: npmDir,
      stdio: 'inherit',
    });
  } catch (e) {
    console.error('web: npm ci failed: the npm registry must be reachable to build the web viewer ' +
                  '(or configure with -DTINSTREAM_BUILD_WEB=OFF)');
    process.exit(1);
  }
  fs.utimesSync(stamp, new Date(), new Date());
}

function copyTree(from, to, filter = () => true) {
  let count = 0;
  fs.mkdirSync(to, { recursive: true });
  for (const entry of fs.readdirSync(from, { withFileTypes: true })) {
    const src = path.join(from, entry.name);
    const dst = path.join(to, entry.name);
    if (entry.isDirectory()) {
      count += copyTree(src, dst, filter);
    } else if (entry.isFile() && filter(entry.name)) {
      fs.copyFileSync(src, dst);
      count++;
    }
  }
  return count;
}

const compressible = /\.(html|js|mjs|cjs|css|json|svg|xml|wasm|txt)$/;

function gzipTree(dir) {
  let count = 0;
  for (const entry of fs.readdirSync(dir, { withFileTypes: true })) {
    const p = path.join(dir, entry.name);
    if (entry.isDirectory()) {
      count += gzipTree(p);
    } else if (compressible.test(entry.name) && fs.statSync(p).size > 1024) {
      fs.writeFileSync(`${p}.gz`, zlib.gzipSync(fs.readFileSync(p), { level: 9 }));
      count++;
    }
  }
  return count;
}

function version(modules, name) {
  return JSON.parse(fs.readFileSync(path.join(modules, name, 'package.json'), 'utf8')).version;
}

const { npmDir, out } = parseArgs(process.argv);
installPackages(npmDir);
const modules = path.join(npmDir, 'node_modules');
const staging = `${out}.tmp`;
fs.rmSync(staging, { recursive: true, force: true });
let files = 0;
// CesiumJS: the prebuilt UMD bundle with its workers, assets, widgets and third-party wasm
// (index.js / index.cjs are the same library as modules for bundlers: not needed).
files += copyTree(path.join(modules, 'cesium', 'Build', 'Cesium'), path.join(staging, 'cesium'),
                  (name) => name !== 'index.js' && name !== 'index.cjs');
// MapLibre GL JS: the ES module, its worker module and the stylesheet (no source maps).
files += copyTree(path.join(modules, 'maplibre-gl', 'dist'), path.join(staging, 'maplibre'),
                  (name) => /^maplibre-gl(-worker)?\.mjs$|^maplibre-gl-shared\.mjs$|\.css$/.test(name));
files += copyTree(path.join(here, 'src'), staging);
const zipped = gzipTree(staging);
const info = {
  cesium: version(modules, 'cesium'),
  'maplibre-gl': version(modules, 'maplibre-gl'),
  files,
  gzipped: zipped,
};
fs.writeFileSync(path.join(staging, 'build.json'), `${JSON.stringify(info, null, 2)}\n`);
fs.rmSync(out, { recursive: true, force: true });
fs.renameSync(staging, out);
console.log(`web: ${files} files in ${out} (CesiumJS ${info.cesium}, MapLibre GL JS ${info['maplibre-gl']})`);
