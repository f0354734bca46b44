#!/usr/bin/env bash
# bench/laz: LAZ decode throughput, our decoder (core/sources/laz) beside laz-perf 0.0.7 (LASzip
# compiled to WASM, in Node), every record of each file decoded; and the wall time of
# `tinstream ingest` of a LAZ file against the same points as LAS. Not a test.
#
#   bench/laz/run.sh                      # defaults below; prints markdown tables
#   ROUNDS=7 RUNS=5 bench/laz/run.sh
#   FILES="lone_star_tls.laz" INGEST=0 bench/laz/run.sh
#
# Each round runs laz-perf, then ours on 1 thread, then ours on 2 threads, one after the other
# (alternating, so that the shared machine's load hits all alike); each process decodes the file
# RUNS times and reports its median run. The tables give the median over ROUNDS of those, wall
# and process CPU (all threads), the records' sha256 check, and the load average before/after.
#
# Needs: node + npm (laz-perf is installed here by `npm install` into bench/laz/node_modules),
# the tinstream build dependencies, and ../shared/data.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
DATA=${DATA:-$root/../shared/data}
BUILD=${BUILD_DIR:-$root/build-bench}
FULL_BUILD=${FULL_BUILD_DIR:-$root/build}
ROUNDS=${ROUNDS:-5}
RUNS=${RUNS:-3}
FILES=${FILES:-"lone_star_tls.laz laz_las_with_several_extra_byte_bloc.laz"}
INGEST=${INGEST:-1}
JOBS=${JOBS:-2}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

(cd "$here" && npm install --no-audit --no-fund --silent)
if [ ! -f "$BUILD/build.ninja" ]; then
  cmake -S "$root" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DTINSTREAM_BUILD_BENCH=ON \
    -DTINSTREAM_ONLY_MODULES="base;sources" -DTINSTREAM_BUILD_TESTS=OFF \
    -DTINSTREAM_BUILD_SERVER=OFF -DTINSTREAM_BUILD_CLIENT=OFF >&2
fi
cmake --build "$BUILD" --target laz_bench -j"$JOBS" >&2

echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores;" \
     "HEAD $(git -C "$root" rev-parse --short HEAD); $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
for f in $FILES; do
  for ((r = 1; r <= ROUNDS; r++)); do
    node "$here/lazperf_decode.mjs" "$DATA/$f" "$RUNS" >> "$out/lazperf.jsonl"
    "$BUILD/bin/laz_bench" "$DATA/$f" 1 "$RUNS" >> "$out/ours1.jsonl"
    "$BUILD/bin/laz_bench" "$DATA/$f" 2 "$RUNS" >> "$out/ours2.jsonl"
  done
done
echo "load after decode: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$out" <<'EOF'
import json, statistics, sys, os
out = sys.argv[1]
def load(name):
    rows = {}
    for line in open(os.path.join(out, name)):
        j = json.loads(line)
        rows.setdefault(os.path.basename(j['file']), []).append(j)
    return rows
lp, o1, o2 = load('lazperf.jsonl'), load('ours1.jsonl'), load('ours2.jsonl')
med = statistics.median
print()
print('| file | points | laz-perf wall / CPU ms | ours 1 thread wall / CPU ms | ours 2 threads wall / CPU ms | '
      'wall ratio laz-perf / ours 1T | CPU ratio | 2T speed-up (wall) | sha256 equal |')
print('|---|---|---|---|---|---|---|---|---|')
for f in lp:
    def per_round(rows, key):
        return med([med(r[key]) for r in rows])
    lw, lc = per_round(lp[f], 'decodeMs'), per_round(lp[f], 'cpuMs')
    w1, c1 = per_round(o1[f], 'decodeMs'), per_round(o1[f], 'cpuMs')
    w2, c2 = per_round(o2[f], 'decodeMs'), per_round(o2[f], 'cpuMs')
    shas = {r['sha256'] for r in lp[f] + o1[f] + o2[f]}
    n = lp[f][0]['records']
    print(f'| {f} | {n:,} | {lw:.0f} / {lc:.0f} | {w1:.0f} / {c1:.0f} ({n / w1 * 1e3 / 1e6:.2f} M/s) | '
          f'{w2:.0f} / {c2:.0f} ({n / w2 * 1e3 / 1e6:.2f} M/s) | **{lw / w1:.2f}×** | {lc / c1:.2f}× | '
          f'**{w1 / w2:.2f}×** | {"yes" if len(shas) == 1 else "NO: " + str(shas)} |')
EOF

[ "$INGEST" = 1 ] || exit 0
# Ingest: the same 110,000 points as LAZ and as LAS (autzen_trim), alternating, default options.
cmake --build "$FULL_BUILD" --target tinstream -j"$JOBS" >&2
tin=$FULL_BUILD/bin/tinstream
for ((r = 1; r <= ROUNDS; r++)); do
  for ext in las laz; do
    rm -rf "$out/store.sqlite"* "$out/tmp"
    /usr/bin/time -f "%e %U %S" -o "$out/time" "$tin" ingest --store "$out/store.sqlite" \
      --layer a --tmp "$out/tmp" -q "$DATA/autzen_trim.$ext" > /dev/null
    echo "$ext $(cat "$out/time")" >> "$out/ingest.txt"
  done
done
echo "load after ingest: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$out/ingest.txt" <<'EOF'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
wall = {e: [float(r[1]) for r in rows if r[0] == e] for e in ('las', 'laz')}
cpu = {e: [float(r[2]) + float(r[3]) for r in rows if r[0] == e] for e in ('las', 'laz')}
med = statistics.median
print()
print('| ingest autzen_trim (110,000 points, full pyramid) | wall s (median) | CPU s (median) | runs |')
print('|---|---|---|---|')
for e in ('las', 'laz'):
    print(f'| .{e} | {med(wall[e]):.2f} | {med(cpu[e]):.2f} | {" ".join(f"{w:.2f}" for w in wall[e])} |')
print(f'| **LAZ / LAS** | **{med(wall["laz"]) / med(wall["las"]):.3f}×** | {med(cpu["laz"]) / med(cpu["las"]):.3f}× | |')
EOF
