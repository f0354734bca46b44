// Greedy insertion (Delatin) on a float32 height grid, refined to each requested vertex count.
// usage: node delatin_run.mjs <grid.f32> <W> <H> <N,N,...> <out dir>
// Writes <out>/delatin_<N>.txt ("nv nt", then "col row" per vertex, then triangles) and
// <out>/delatin_times.txt ("N milliseconds cpu_milliseconds" per line: construction + refinement
// up to N vertices, file writing excluded; wall time, and the process's CPU time by
// process.cpuUsage(), so that a loaded machine can be compared with our CPU time).
import fs from 'node:fs';
import Delatin from 'delatin';

const [file, W, H, counts, out] = process.argv.slice(2);
const buf = fs.readFileSync(file);
const data = new Float32Array(buf.buffer.slice(buf.byteOffset, buf.byteOffset + buf.byteLength));
const w = Number(W), h = Number(H);
const targets = counts.split(',').map(Number).sort((a, b) => a - b);
const times = [];
const ms = (ns) => Number(ns) / 1e6;
const cpuMs = (u) => (u.user + u.system) / 1000;
let t = process.hrtime.bigint();
let c = process.cpuUsage();
const tin = new Delatin(data, w, h);
let spent = process.hrtime.bigint() - t;
let cpu = cpuMs(process.cpuUsage(c));
for (const n of targets) {
  t = process.hrtime.bigint();
  c = process.cpuUsage();
  while (tin.coords.length / 2 < n && tin.getMaxError() > 0) tin.refine();
  spent += process.hrtime.bigint() - t;
  cpu += cpuMs(process.cpuUsage(c));
  times.push(`${n} ${ms(spent)} ${cpu}`);
  const nv = tin.coords.length / 2, nt = tin.triangles.length / 3;
  const lines = [`${nv} ${nt}`];
  for (let i = 0; i < nv; i++) lines.push(`${tin.coords[2 * i]} ${tin.coords[2 * i + 1]}`);
  for (let i = 0; i < nt; i++) lines.push(`${tin.triangles[3 * i]} ${tin.triangles[3 * i + 1]} ${tin.triangles[3 * i + 2]}`);
  fs.writeFileSync(`${out}/delatin_${n}.txt`, lines.join('\n') + '\n');
  console.log(`delatin ${nv} vertices: max ${tin.getMaxError().toFixed(3)} m, rmsd ${tin.getRMSD().toFixed(3)} m, ${ms(spent).toFixed(1)} ms`);
}
fs.writeFileSync(`${out}/delatin_times.txt`, times.join('\n') + '\n');
