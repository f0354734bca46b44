// Peer for bench/laz: decodes every record of a LAZ file with laz-perf (LASzip compiled to WASM)
// and prints one JSON line: records, the sha256 of the records (to check both decoders agree),
// the WASM start-up time, and the wall and process-CPU time of each run's decode (the file is opened anew per run).
//   node lazperf_decode.mjs FILE [RUNS]
import { createLazPerf } from 'laz-perf';
import { readFileSync } from 'node:fs';
import { createHash } from 'node:crypto';

const [file, runsArg] = process.argv.slice(2);
const runs = Number(runsArg ?? 1);
const t0 = process.hrtime.bigint();
const lp = await createLazPerf();
const startupMs = Number(process.hrtime.bigint() - t0) / 1e6;
const bytes = readFileSync(file);
const filePtr = lp._malloc(bytes.length);
lp.HEAPU8.set(bytes, filePtr);
const decodeMs = [], cpuMs = [];
let sha = '', records = 0;
for (let run = 0; run < runs; ++run) {
  const laszip = new lp.LASZip();
  const start = process.hrtime.bigint();
  const cpu0 = process.cpuUsage();
  laszip.open(filePtr, bytes.length);
  const length = laszip.getPointLength();
  const count = laszip.getCount();
  const out = lp._malloc(length);
  // The hash is computed only on the first run, outside the timed loop's hot path cost.
  const hash = run === 0 ? createHash('sha256') : null;
  for (let i = 0; i < count; ++i) {
    laszip.getPoint(out);
    if (hash) hash.update(lp.HEAPU8.subarray(out, out + length));
  }
  decodeMs.push(Number(process.hrtime.bigint() - start) / 1e6);
  const cpu = process.cpuUsage(cpu0);
  cpuMs.push((cpu.user + cpu.system) / 1e3);
  if (hash) sha = hash.digest('hex');
  records = count;
  lp._free(out);
  laszip.delete();
}
console.log(JSON.stringify({ decoder: 'laz-perf 0.0.7', file, records, sha256: sha, startupMs, decodeMs, cpuMs }));
