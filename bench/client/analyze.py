#!/usr/bin/env python3
"""bench/client helpers (run.sh calls them).

  analyze.py cameras LAYER_JSON FLIGHT_FILE FLIGHT_S STREAM_FILE
      prints CAM_FAR=… CAM_NEAR=… (shell assignments) and writes the two camera paths:
      STREAM_FILE: cold at the near view, `wait complete`, then 5 s more on it (loaded);
      FLIGHT_FILE: FLIGHT_S seconds back and forth over the layer at three heights.
  analyze.py report OUT LAYER STORE DELAY_MS SIZE SSE FLIGHT_S
      reads OUT/cold.jsonl, OUT/stream.jsonl, OUT/flight.jsonl, OUT/flight.maxrss_kb,
      OUT/cesium.jsonl and prints the Markdown tables of RESULTS.md.
  analyze.py rss OUT STORE LAYER SIZE SSE STARTED
      (rss_flight.sh) reads OUT/rss.tsv (seconds, VmRSS kB, VmHWM kB sampled from outside) and
      OUT/flight.jsonl, and prints the RSS over the flight against the tiers' budgets.
  analyze.py heaviest FLIGHT_JSONL FLIGHT_FILE N
      (rss_flight.sh) the cameras of the N frames of the flight that drew the most triangles
      (at least 2 s apart; FLIGHT_FILE's path interpolated at the frames' times), one per line:
      the restated target's reference views.
  analyze.py ab AB_JSONL
      (ab.sh) medians per viewer and thread count of a run-by-run alternating A/B, the 8-vs-1
      ratio of each viewer, and B − A per round.
"""
import json
import math
import statistics
import sys


def pct(values, p):
    """The p-th percentile, nearest rank (no interpolation)."""
    s = sorted(values)
    if not s:
        return float('nan')
    k = max(0, min(len(s) - 1, math.ceil(p / 100 * len(s)) - 1))
    return s[k]


def cameras(layer_json, flight_file, flight_s, stream_file):
    layer = json.load(open(layer_json))
    b = layer['bounds']
    lon = (b['west'] + b['east']) / 2
    lat = (b['south'] + b['north']) / 2
    # Extent in metres (spherical approximation, only to place the cameras).
    width = max((b['east'] - b['west']) * 111320 * math.cos(math.radians(lat)),
                (b['north'] - b['south']) * 110540, 100.0)
    top = layer.get('max_z', 0.0)
    far = f'{lon:.6f},{lat:.6f},{top + 1.2 * width:.1f},0,-90'
    # Close and oblique: looking north-east over the layer from its south-west quarter.
    near_lon = b['west'] + 0.3 * (b['east'] - b['west'])
    near_lat = b['south'] + 0.25 * (b['north'] - b['south'])
    near = f'{near_lon:.6f},{near_lat:.6f},{top + 0.12 * width:.1f},30,-30'
    with open(stream_file, 'w') as f:
        f.write(f'# cold at the near view, until complete, then 5 s loaded\n0 {near}\n'
                f'wait complete\n5 {near}\n')
    legs = []
    heights = [top + 0.6 * width, top + 0.2 * width, top + 0.06 * width]
    corners = [(b['west'], b['south']), (b['east'], b['north']), (b['east'], b['south']),
               (b['west'], b['north'])]
    i = 0
    while sum(s for s, _ in legs) < flight_s:
        cx, cy = corners[i % len(corners)]
        x = lon + 0.8 * (cx - lon)
        y = lat + 0.8 * (cy - lat)
        h = heights[i % len(heights)]
        legs.append((10.0, f'{x:.6f},{y:.6f},{h:.1f},{(45 * i) % 360},-40'))
        i += 1
    with open(flight_file, 'w') as f:
        f.write(f'# {flight_s} s over the layer, three heights\n0 {far}\n')
        for s, pose in legs:
            f.write(f'{s} {pose}\n')
    print(f'CAM_FAR={far}')
    print(f'CAM_NEAR={near}')


def read_jsonl(path):
    try:
        with open(path) as f:
            return [json.loads(line) for line in f if line.strip()]
    except FileNotFoundError:
        return []


def report(out, layer, store, delay_ms, size, sse, flight_s):
    print(f'store `{store}`, layer `{layer}`, {size}, max SSE {sse} px, '
          f'+{delay_ms} ms per request (proxy)\n')
    cold = read_jsonl(f'{out}/cold.jsonl')
    if cold:  # (PARTS= may leave it out)
        print('### Cold time to a complete view (fresh process, no disk tier)\n')
        print('| threads | run | complete | time to complete (s) | tiles loaded | requests | bytes '
              '(proxy) | most in flight | CPU until complete: process / render thread (s) | '
              'decoding: CPU / wall (s) | server / proxy CPU (s) | load |')
        print('|---|---|---|---|---|---|---|---|---|---|---|---|')
    by_t = {}
    for c in cold:
        v, p = c['viewer'], c['proxy']
        by_t.setdefault(c['threads'], []).append(v['time_to_complete_s'])
        # (viewers before the "cpu" statistics: n/a)
        cpu, req = v.get('cpu'), v['requests']
        cpu_s = f"{cpu['process_s']:.3f} / {cpu['render_thread_s']:.3f}" if cpu else 'n/a'
        o = c.get('cpu_others')  # (run.sh before 2026-11-28 14:00: n/a)
        others = f"{o['server_s']:.2f} / {o['proxy_s']:.2f}" if o else 'n/a'
        dec_s = (f"{req['decode_cpu_seconds']:.3f} / {req['decode_seconds']:.3f}"
                 if 'decode_cpu_seconds' in req else f"n/a / {req['decode_seconds']:.3f}")
        print(f"| {c['threads']} | {c['run']} | {v['complete']} | {v['time_to_complete_s']:.2f} | "
              f"{v['tiles']['loaded']} | {p['requests']} | {p['bytes']} | {p['max_in_flight']} | "
              f"{cpu_s} | {dec_s} | {others} | {c.get('load', 'n/a')} |")
    if 1 in by_t and 8 in by_t:
        m1, m8 = statistics.median(by_t[1]), statistics.median(by_t[8])
        pairs = [a / b for a, b in zip(by_t[1], by_t[8]) if b]
        print(f'\nmedian 1 thread {m1:.2f} s, 8 threads {m8:.2f} s: **{m1 / m8:.2f}×** '
              f'(per run pair: {", ".join(f"{r:.2f}" for r in pairs)}); target ≥ 5×\n')

    frames = [f for f in read_jsonl(f'{out}/stream.jsonl') if 'frame' in f]
    if frames:
        streaming = [f['frame_ms'] for f in frames if not f['complete']]
        first_complete = next((f['t'] for f in frames if f['complete']), None)
        loaded = [f['frame_ms'] for f in frames
                  if f['complete'] and first_complete is not None and f['t'] > first_complete + 0.5]
        tiles = max(f['loaded'] for f in frames)
        print('### Render thread while tiles stream in (near view, 8 threads)\n')
        print(f'{tiles} tiles decoded; {len(streaming)} frames streaming, {len(loaded)} frames '
              f'loaded (from 0.5 s after complete)\n')
        print('| frames | median ms | p95 ms | p99 ms | worst ms |')
        print('|---|---|---|---|---|')
        for name, v in (('streaming', streaming), ('loaded (same view)', loaded)):
            if v:
                print(f'| {name} | {statistics.median(v):.2f} | {pct(v, 95):.2f} | '
                      f'{pct(v, 99):.2f} | {max(v):.2f} |')
        upd = [f['update_ms'] for f in frames if not f['complete']]
        tri = max(f['triangles'] for f in frames)
        if upd:
            print(f'| streaming: update only (take results, select, upload) | '
                  f'{statistics.median(upd):.2f} | {pct(upd, 95):.2f} | {pct(upd, 99):.2f} | '
                  f'{max(upd):.2f} |')
        print(f'\nat most {tri} triangles drawn in a frame')
        if streaming and loaded:
            print(f'\nworst streaming frame / median loaded frame = '
                  f'**{max(streaming) / statistics.median(loaded):.2f}×** (target ≤ 1.5×); '
                  f'p99 streaming / median loaded = {pct(streaming, 99) / statistics.median(loaded):.2f}×\n')

    flight_lines = read_jsonl(f'{out}/flight.jsonl')
    flight = [f for f in flight_lines if 'frame' in f]
    if flight:
        rss = [f['rss_bytes'] for f in flight]
        ft = [f['frame_ms'] for f in flight]
        # The budgets from the summary line (GPU_MB, CACHE_MB of run.sh).
        tiers = next((f['cache'] for f in flight_lines if 'cache' in f), None)
        gpu_mb, ram_mb = ((tiers['gpu']['budget'] >> 20, tiers['ram']['budget'] >> 20) if tiers
                          else (64, 64))
        budget = (gpu_mb + ram_mb) << 20
        base = rss[0]
        try:
            maxrss = int(open(f'{out}/flight.maxrss_kb').read().split()[-1]) * 1024
        except (OSError, ValueError, IndexError):
            maxrss = 0
        mb = 1 << 20
        print(f'### Memory over a scripted flight ({flight[-1]["t"]:.0f} s, {len(flight)} frames, '
              f'--gpu-mb {gpu_mb} --cache-mb {ram_mb})\n')
        print('| RSS first frame | RSS median | RSS max (frames) | max RSS (time -f %M) | '
              'budgets | max − first frame | peak GPU tier | peak RAM tier |')
        print('|---|---|---|---|---|---|---|---|')
        print(f'| {base / mb:.0f} MB | {statistics.median(rss) / mb:.0f} MB | {max(rss) / mb:.0f} MB | '
              f'{maxrss / mb:.0f} MB | {budget / mb:.0f} MB | {(max(rss) - base) / mb:.0f} MB | '
              f'{max(f["gpu_bytes"] for f in flight) / mb:.0f} MB | '
              f'{max(f["ram_bytes"] for f in flight) / mb:.0f} MB |')
        print(f'\nframe times over the flight: median {statistics.median(ft):.2f} ms, '
              f'p95 {pct(ft, 95):.2f}, p99 {pct(ft, 99):.2f}, worst {max(ft):.2f} ms\n')

    cesium = read_jsonl(f'{out}/cesium.jsonl')
    if cesium:
        print('### CesiumJS, same layer (Cesium terrain endpoint), camera, size, max SSE\n')
        print('| run | time to complete (s) | requests | bytes (proxy) | error |')
        print('|---|---|---|---|---|')
        for i, c in enumerate(cesium, 1):
            p = c.get('proxy', {})
            ms = c.get('ms')
            print(f"| {i} | {ms / 1000 if ms else float('nan'):.2f} | {p.get('requests', '')} | "
                  f"{p.get('bytes', '')} | {c.get('error', '')[:80]} |")
        print()


def slope_mb_per_min(points):
    """Least-squares slope of (seconds, bytes) points, in MB per minute."""
    if len(points) < 2:
        return float('nan')
    mt = statistics.fmean(t for t, _ in points)
    mv = statistics.fmean(v for _, v in points)
    den = sum((t - mt) ** 2 for t, _ in points)
    if den == 0:
        return float('nan')
    return sum((t - mt) * (v - mv) for t, v in points) / den * 60 / (1 << 20)


def rss(out, store, layer, size, sse, started):
    mb = 1 << 20
    samples = []  # (seconds, VmRSS bytes, VmHWM bytes)
    with open(f'{out}/rss.tsv') as f:
        for line in f:
            t, r, h = line.split()
            samples.append((float(t), int(r) * 1024, int(h) * 1024))
    lines = read_jsonl(f'{out}/flight.jsonl')
    frames = [f for f in lines if 'frame' in f]
    summary = next(f for f in lines if 'cache' in f)
    gpu, ram = summary['cache']['gpu'], summary['cache']['ram']
    budgets = gpu['budget'] + ram['budget']
    end_t = samples[-1][0]
    first, peak, end = samples[0][1], samples[-1][2], samples[-1][1]
    thirds = [[r for t, r, _ in samples if k * end_t / 3 <= t <= (k + 1) * end_t / 3]
              for k in range(3)]
    later = [(t, r) for t, r, _ in samples if t >= end_t / 3]
    slope = slope_mb_per_min(later)
    earlier = max(thirds[0] + thirds[1])
    # Bounded: the last third peaks no higher than the first two thirds did (5 % allowed: on a
    # software rasteriser a frame's memory follows its triangles), and RSS does not trend
    # upwards over the last two thirds (< 1 MB a minute).
    bounded = max(thirds[2]) <= 1.05 * earlier and slope < 1.0
    filled = gpu['evictions'] > 0 or ram['evictions'] > 0
    verdict = (('bounded' if bounded else 'NOT bounded') if filled
               else 'not tested (tiers still filling)')
    print(f'### RSS over a {end_t:.0f} s flight (rss_flight.sh, started {started})\n')
    print(f'store `{store}`, layer `{layer}`, {size}, max SSE {sse} px, 8 threads, '
          f'`--gpu-mb {gpu["budget"] // mb} --cache-mb {ram["budget"] // mb}`, '
          f'{len(samples)} samples of /proc/PID/status, {len(frames)} frames, '
          f'{summary["tiles"]["loaded"]} tiles loaded, '
          f'{summary["requests"]["downloaded_bytes"] / mb:.1f} MB downloaded; '
          f'renderer {summary.get("renderer", "?")}\n')
    print('| RSS first sample | peak (VmHWM) | RSS at the end | budgets | peak − first sample | '
          'peak GPU tier (evictions) | peak RAM tier (evictions) |')
    print('|---|---|---|---|---|---|---|')
    print(f'| {first / mb:.0f} MB | {peak / mb:.0f} MB | {end / mb:.0f} MB | {budgets / mb:.0f} MB | '
          f'{(peak - first) / mb:.0f} MB | {gpu["peak_bytes"] / mb:.1f} MB ({gpu["evictions"]}) | '
          f'{ram["peak_bytes"] / mb:.1f} MB ({ram["evictions"]}) |')
    print('\n| minute | RSS min | RSS max | VmHWM at its end | tiles loaded by its end |')
    print('|---|---|---|---|---|')
    for m in range(int(end_t // 60) + 1):
        in_m = [(r, h) for t, r, h in samples if m * 60 <= t < (m + 1) * 60]
        if not in_m:
            continue
        loaded = max((f['loaded'] for f in frames if f['t'] < (m + 1) * 60), default=0)
        print(f'| {m} | {min(r for r, _ in in_m) / mb:.0f} MB | {max(r for r, _ in in_m) / mb:.0f} MB '
              f'| {in_m[-1][1] / mb:.0f} MB | {loaded} |')
    print(f'\npeak RSS by third of the flight: {", ".join(f"{max(t) / mb:.0f} MB" for t in thirds)}; '
          f'slope over the last two thirds {slope:+.2f} MB/min; '
          f'**{verdict}** (last third ≤ 1.05 × the peak '
          f'before it, slope < 1 MB/min)')
    if not filled:
        print('\nneither tier evicted: the flight never filled them, so RSS still grows with '
              'the tiles it loads and the LRU bound is not reached (smaller budgets, lower '
              'max SSE)')
    target = budgets + first
    print(f'\nissue #17 target, budgets + the first sample as the fixed overhead: '
          f'{target / mb:.0f} MB; peak {"within" if peak <= target else "over"} it by '
          f'{abs(peak - target) / mb:.0f} MB\n')
    heaviest_frame = max((f['triangles'] for f in frames), default=0)
    overhead = reference(out, budgets)
    if overhead is not None:
        slack = 16 * mb  # decode scratch and queued payloads (16 waiting, ~0.7 MB each at most)
        restated = budgets + overhead + slack
        print(f'\nrestated target (bench/client/RESULTS.md, "RSS target on a software renderer"): '
              f'budgets {budgets / mb:.0f} MB + the largest reference peak less its tiers '
              f'{overhead / mb:.0f} MB + 16 MB slack = {restated / mb:.0f} MB; the flight\'s peak '
              f'{peak / mb:.0f} MB is {"within" if peak <= restated else "over"} it by '
              f'{abs(peak - restated) / mb:.0f} MB (the flight\'s heaviest frame drew '
              f'{heaviest_frame:,} triangles)\n')


def pose_at(steps, t):
    """The camera of a camera path (steps: (seconds, [lon, lat, height, heading, pitch])) t
    seconds after its start, interpolated as client/src/camera_path.cpp does."""
    def short_way(a, b, period):
        d = math.fmod(b - a, period)
        if d > period / 2:
            d -= period
        if d < -period / 2:
            d += period
        return d
    frm = steps[0][1]
    for seconds, to in steps[1:]:
        if t < seconds:
            u = t / seconds
            lon = frm[0] + short_way(frm[0], to[0], 360) * u
            lon = lon - 360 if lon > 180 else lon + 360 if lon < -180 else lon
            h = (frm[2] * (to[2] / frm[2]) ** u if frm[2] > 1 and to[2] > 1
                 else frm[2] + (to[2] - frm[2]) * u)
            heading = math.fmod(frm[3] + short_way(frm[3], to[3], 360) * u + 360, 360)
            return [lon, frm[1] + (to[1] - frm[1]) * u, h, heading, frm[4] + (to[4] - frm[4]) * u]
        t -= seconds
        frm = to
    return frm


def heaviest(flight_jsonl, flight_file, n):
    """The cameras of the N frames that drew the most triangles (at least 2 s apart)."""
    frames = [f for f in read_jsonl(flight_jsonl) if 'frame' in f]
    steps = []
    for line in open(flight_file):
        if line.strip() and not line.startswith('#'):
            seconds, camera = line.split()[:2]
            steps.append((float(seconds), [float(v) for v in camera.split(',')]))
    picked = []
    for f in sorted(frames, key=lambda f: -f['triangles']):
        if len(picked) == int(n):
            break
        if all(abs(f['t'] - t) >= 2 for t in picked):
            picked.append(f['t'])
            print(','.join(f'{v:.6f}' for v in pose_at(steps, f['t'])))


def reference(out, budgets):
    """The restated target's reference runs (rss_flight.sh: OUT/ref-K.jsonl, OUT/ref-K.time):
    for each, its peak RSS, its tiers' bytes and the triangles of its frame; returns the largest
    peak less its tiers (the process's memory beside the tiers with a full frame)."""
    mb = 1 << 20
    rows = []
    k = 0
    while True:
        stats = read_jsonl(f'{out}/ref-{k}.jsonl')
        try:
            with open(f'{out}/ref-{k}.time') as f:
                peak_kb = int(f.read().split()[-1])
        except (FileNotFoundError, ValueError, IndexError):
            break
        last = stats[-1] if stats else {}
        cache = last.get('cache', {})
        tiers = cache.get('gpu', {}).get('bytes', 0) + cache.get('ram', {}).get('bytes', 0)
        rows.append((last.get('camera', '?'), peak_kb * 1024, tiers,
                     last.get('tiles', {}).get('triangles', 0), last.get('complete')))
        k += 1
    if not rows:
        return None
    print('\nReference runs (restated target): the same viewer options, one complete view each '
          '(`--camera`, snapshot mode), peak RSS from `/usr/bin/time -f %M`:\n')
    print('| camera | triangles drawn | complete | peak RSS | tiers at the end | peak − tiers |')
    print('|---|---|---|---|---|---|')
    for camera, peak, tiers, triangles, complete in rows:
        print(f'| `{camera}` | {triangles:,} | {complete} | {peak / mb:.0f} MB | {tiers / mb:.1f} MB '
              f'| {(peak - tiers) / mb:.0f} MB |')
    return max(peak - tiers for _, peak, tiers, _, _ in rows)


def ab(path):
    """ab.sh's runs: medians per viewer and thread count, the 8-vs-1 ratio, per-run pairs."""
    runs = [json.loads(line) for line in open(path) if line.strip()]
    threads = sorted({r['threads'] for r in runs}, reverse=True)
    print('| viewer | threads | runs | median (s) | min (s) | max (s) | load |')
    print('|---|---|---|---|---|---|---|')
    med = {}
    for v in ('A', 'B'):
        for t in threads:
            rs = [r for r in runs if r['viewer'] == v and r['threads'] == t]
            if not rs:
                continue
            xs = [r['time_to_complete_s'] for r in rs]
            loads = [r['load'] for r in rs]
            med[v, t] = statistics.median(xs)
            print(f'| {v} | {t} | {len(xs)} | {med[v, t]:.3f} | {min(xs):.3f} | {max(xs):.3f} | '
                  f'{min(loads):.1f}–{max(loads):.1f} |')
    print()
    for v in ('A', 'B'):
        if (v, 8) in med and (v, 1) in med:
            print(f'{v}: 8 vs 1 threads {med[v, 1] / med[v, 8]:.2f}× (medians)')
    for t in threads:
        a = [r['time_to_complete_s'] for r in runs if r['viewer'] == 'A' and r['threads'] == t]
        b = [r['time_to_complete_s'] for r in runs if r['viewer'] == 'B' and r['threads'] == t]
        if a and b:
            d = [y - x for x, y in zip(a, b)]
            print(f'{t} threads: B − A per round, median {statistics.median(d) * 1000:+.0f} ms; '
                  f'B faster in {sum(x < 0 for x in d)} of {len(d)}')
    print(f'requests per run: {sorted({r["requests"] for r in runs})}; '
          f'bytes: {sorted({r["bytes"] for r in runs})}; '
          f'incomplete runs: {sum(1 for r in runs if r.get("complete") is False)}')


if __name__ == '__main__':
    if sys.argv[1] == 'cameras':
        cameras(sys.argv[2], sys.argv[3], float(sys.argv[4]), sys.argv[5])
    elif sys.argv[1] == 'report':
        report(*sys.argv[2:9])
    elif sys.argv[1] == 'rss':
        rss(*sys.argv[2:8])
    elif sys.argv[1] == 'heaviest':
        heaviest(*sys.argv[2:5])
    elif sys.argv[1] == 'ab':
        ab(sys.argv[2])
    else:
        sys.exit(__doc__)
