// The browser tests' fixture (CTest FIXTURES_SETUP web_store): generated rasters
// (tinstream-test-rasters), their terrain and imagery ingested with the real CLI into one store.
//   node tests/web/prepare.mjs   (TINSTREAM_FIXTURE, TINSTREAM_CLI, TINSTREAM_TEST_RASTERS set)
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { env } from './harness.mjs';

const dir = env('TINSTREAM_FIXTURE');
const cli = env('TINSTREAM_CLI');
fs.rmSync(dir, { recursive: true, force: true });
fs.mkdirSync(dir, { recursive: true });
const runs = [
  [env('TINSTREAM_TEST_RASTERS'), ['--out', dir]],
  [cli, ['ingest', '--quiet', '--store', path.join(dir, 'store.sqlite'), '--layer', 'demo',
         '--threads', '2', path.join(dir, 'dem.tif')]],
  // A second terrain layer (the same DEM, coarser: 5 m error) for the CesiumJS layer picker.
  [cli, ['ingest', '--quiet', '--store', path.join(dir, 'store.sqlite'), '--layer', 'coarse',
         '--epsilon', '5', '--threads', '2', path.join(dir, 'dem.tif')]],
  [cli, ['ingest-imagery', '--quiet', '--store', path.join(dir, 'store.sqlite'), '--layer', 'demo',
         '--format', 'jpeg', '--threads', '2', path.join(dir, 'ortho.tif')]],
];
for (const [exe, args] of runs) {
  execFileSync(exe, args, { stdio: 'inherit', timeout: 180000 });
}
console.log(`web fixture ready in ${dir}`);
