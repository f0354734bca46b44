#!/usr/bin/env python3
"""Abuse and load harness for tinstream-server (#22), loopback only, bounded in time and sockets.

  bench/server/abuse.py --server BIN --bench-store BIN [--short] [--gate-p99] [--json FILE]

Starts its own tinstream-server on 127.0.0.1 (any free port) over a synthetic store
(tinstream-bench-store), then:
  1. baseline: normal clients (keep-alive, gzip, from 127.0.0.2) fetch tiles; their latencies.
  2. attack: the same clients fetch while
       - slowloris: 300 sockets (127.0.0.1) trickle a request header, a byte every 0.5 s, and
         reconnect when cut off;
       - close-trickle (finding 1): 100 sockets (127.0.0.3) send a request with
         `Connection: close`, then a byte every 0.5 s while the server lingers;
       - flood: 2 processes (127.0.0.4) send malformed requests (bad request lines, bad
         targets, oversized headers, garbage, truncated bodies) on new connections, flat out.
  3. load: wrk at 256 connections over the tile list (when wrk is installed).
The server's RSS and open descriptors are sampled every 0.2 s throughout.

Fails (exit 1) when: a normal request fails (any status but 200, or no answer in 10 s); the
server's descriptors exceed max_connections + 64 or are not back to the baseline + 16 within
5 s of the attack's end; its RSS grows by more than 256 MiB; wrk reports a socket error or a
non-2xx/3xx answer; or, with --gate-p99, the attack's p99 latency exceeds 5 times the
baseline's (a timing figure: gated in the benchmark run, reported in the CI run).
--short (CI, ctest Server.Abuse): 2 s baseline, 5 s attack, 2 s wrk; default 10 s, 30 s, 60 s.
"""
import argparse
import json
import multiprocessing as mp
import os
import random
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

HOST = "127.0.0.1"
MAX_CONNECTIONS = 1024


def connect(port, source, timeout=10.0):
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.settimeout(timeout)
    s.bind((source, 0))
    s.connect((HOST, port))
    return s


def read_response(sock, buf):
    """Reads one response (Content-Length bodies) from sock: (status, body, rest of buf)."""
    while b"\r\n\r\n" not in buf:
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError("closed before the head")
        buf += chunk
    head, buf = buf.split(b"\r\n\r\n", 1)
    lines = head.split(b"\r\n")
    status = int(lines[0].split()[1])
    length = 0
    for line in lines[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"content-length":
            length = int(value.strip())
    while len(buf) < length:
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError("closed in the body")
        buf += chunk
    return status, buf[:length], buf[length:]


def normal_client(port, paths, stop, latencies, failures, seed):
    rng = random.Random(seed)
    sock, buf = None, b""
    while not stop.is_set():
        path = paths[rng.randrange(len(paths))]
        req = (f"GET {path} HTTP/1.1\r\nHost: x\r\nAccept-Encoding: gzip\r\n"
               "Accept: application/vnd.quantized-mesh;extensions=octvertexnormals\r\n\r\n").encode()
        t0 = time.perf_counter()
        try:
            if sock is None:
                sock, buf = connect(port, "127.0.0.2"), b""
            sock.sendall(req)
            status, _, buf = read_response(sock, buf)
            latencies.append(time.perf_counter() - t0)
            if status != 200:
                failures.append(f"{path}: status {status}")
        except (OSError, ConnectionError, ValueError, IndexError) as e:
            failures.append(f"{path}: {e}")
            if sock:
                sock.close()
            sock = None
    if sock:
        sock.close()


def run_clients(port, paths, seconds, n=4):
    stop, latencies, failures = threading.Event(), [], []
    threads = [threading.Thread(target=normal_client,
                                args=(port, paths, stop, latencies, failures, i))
               for i in range(n)]
    for t in threads:
        t.start()
    time.sleep(seconds)
    stop.set()
    for t in threads:
        t.join()
    return latencies, failures


def percentile(values, p):
    if not values:
        return float("nan")
    v = sorted(values)
    return v[min(len(v) - 1, int(p / 100.0 * len(v)))]


def trickler(port, source, count, close_first, stop_at, counter):
    """count sockets, each sending a byte every 0.5 s; reconnects when the server cuts one."""
    header = b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: " + b"a" * 4000
    closing = b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
    socks = {}
    reconnects = 0
    while time.time() < stop_at:
        for i in range(count):
            s = socks.get(i)
            try:
                if s is None:
                    s = connect(port, source, timeout=2.0)
                    s.setblocking(False)
                    if close_first:
                        s.send(closing)
                    socks[i] = s
                    reconnects += 1
                s.send(b"a")
            except (BlockingIOError, InterruptedError):
                pass
            except OSError:
                if s:
                    s.close()
                socks.pop(i, None)
            if close_first and i in socks:
                try:  # the answer: read and drop it, as a client that keeps the socket open would
                    socks[i].recv(65536)
                except (BlockingIOError, OSError):
                    pass
        time.sleep(0.5)
    for s in socks.values():
        s.close()
    counter.value = reconnects


MALFORMED = [
    b"GARBAGE\r\n\r\n",
    b"GET\r\n\r\n",
    b"GET /tiles/../../etc/passwd HTTP/1.1\r\nHost: x\r\n\r\n",
    b"GET /tiles/lux/%zz HTTP/1.1\r\nHost: x\r\n\r\n",
    b"GET http://evil/ HTTP/1.1\r\nHost: x\r\n\r\n",
    b"GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + b"b" * 20000 + b"\r\n\r\n",
    b"POST /admin/ingest HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\n{\"la",
    b"GET /tiles/lux/0 HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n",
    b"\x00\x01\x02\xff" * 64,
    b"GET /healthz HTTP/9.9\r\n\r\n",
    b"DELETE /admin/layers/lux HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer wrong\r\n\r\n",
]


def flooder(port, stop_at, counter):
    n, rng = 0, random.Random(os.getpid())
    while time.time() < stop_at:
        try:
            s = connect(port, "127.0.0.4", timeout=2.0)
            s.sendall(MALFORMED[rng.randrange(len(MALFORMED))])
            try:
                s.recv(4096)
            except OSError:
                pass
            s.close()
            n += 1
        except OSError:
            time.sleep(0.01)
    counter.value = n


class Sampler(threading.Thread):
    def __init__(self, pid):
        super().__init__(daemon=True)
        self.pid, self.samples, self.stop = pid, [], threading.Event()

    def sample(self):
        try:
            fds = len(os.listdir(f"/proc/{self.pid}/fd"))
            with open(f"/proc/{self.pid}/status") as f:
                rss = next(int(l.split()[1]) for l in f if l.startswith("VmRSS:")) * 1024
        except (OSError, StopIteration):
            return None
        return time.time(), fds, rss

    def run(self):
        while not self.stop.is_set():
            s = self.sample()
            if s:
                self.samples.append(s)
            time.sleep(0.2)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--server", required=True, help="tinstream-server binary")
    ap.add_argument("--bench-store", required=True, help="tinstream-bench-store binary")
    ap.add_argument("--short", action="store_true", help="CI durations (seconds, not minutes)")
    ap.add_argument("--gate-p99", action="store_true", help="fail when p99 under attack > 5x baseline")
    ap.add_argument("--json", help="write the figures here")
    a = ap.parse_args()
    base_s, attack_s, wrk_s = (2, 5, 2) if a.short else (10, 30, 60)

    work = tempfile.mkdtemp(prefix=f"tinstream-abuse-{os.getpid()}-")
    server = None
    try:
        store = os.path.join(work, "store.db")
        subprocess.run([a.bench_store, store, "bench"], check=True, stdout=subprocess.DEVNULL)
        config = os.path.join(work, "server.json")
        with open(config, "w") as f:
            json.dump({"address": HOST, "port": 0, "store": store, "threads": 2,
                       "access_log": False, "log_level": "error", "read_timeout_ms": 2000,
                       "linger_ms": 1000, "max_connections": MAX_CONNECTIONS,
                       "max_connections_per_ip": 512}, f)
        # Under AddressSanitizer freed blocks wait in a quarantine of 256 MiB by default: resident
        # memory the server no longer holds, which the RSS gate below would count as growth (CI's
        # asan step failed on exactly that). A small quarantine keeps the gate about the server.
        asan = " ".join(x for x in (os.environ.get("ASAN_OPTIONS", ""),
                                    "quarantine_size_mb=16 thread_local_quarantine_size_kb=256") if x)
        server = subprocess.Popen([a.server, "--config", config], stdout=subprocess.PIPE,
                                  stderr=subprocess.DEVNULL, text=True,
                                  env=dict(os.environ, ASAN_OPTIONS=asan))
        line = server.stdout.readline()  # "listening on 127.0.0.1:PORT"
        if "listening on" not in line:
            print(f"abuse: the server did not start: {line!r}", file=sys.stderr)
            return 1
        port = int(line.strip().rsplit(":", 1)[1])
        s = connect(port, "127.0.0.2")
        s.sendall(b"GET /tiles/bench/layer.json HTTP/1.1\r\nHost: x\r\n\r\n")
        status, body, _ = read_response(s, b"")
        s.close()
        doc = json.loads(body)
        paths = [f"/tiles/bench/{z}/{r['startX'] + dx}/{r['startY'] + dy}.terrain"
                 for z, ranges in enumerate(doc["available"]) for r in ranges
                 for dx in range(r["endX"] - r["startX"] + 1)
                 for dy in range(r["endY"] - r["startY"] + 1)]
        # The tile list: what layer.json says is available and the server has (levels below
        # the layer's first stored one answer 404 beyond the filler tiles the server makes).
        # Asked as the normal clients ask, so the baseline is measured on a warm tile cache.
        s = connect(port, "127.0.0.2")
        served, buf = [], b""
        for p in paths:
            s.sendall(f"GET {p} HTTP/1.1\r\nHost: x\r\nAccept-Encoding: gzip\r\n"
                      "Accept: application/vnd.quantized-mesh;extensions=octvertexnormals\r\n\r\n"
                      .encode())
            status, _, buf = read_response(s, buf)
            if status == 200:
                served.append(p)
        s.close()
        paths = served
        if not paths:
            print("abuse: the server has no tile of layer.json's list", file=sys.stderr)
            return 1
        sampler = Sampler(server.pid)
        sampler.start()
        time.sleep(0.5)
        idle_fds = sampler.sample()[1]
        rss0 = sampler.sample()[2]

        base_lat, base_fail = run_clients(port, paths, base_s)

        stop_at = time.time() + attack_s
        counters = [mp.Value("l", 0) for _ in range(4)]
        attackers = [mp.Process(target=trickler, args=(port, "127.0.0.1", 300, False, stop_at, counters[0])),
                     mp.Process(target=trickler, args=(port, "127.0.0.3", 100, True, stop_at, counters[1])),
                     mp.Process(target=flooder, args=(port, stop_at, counters[2])),
                     mp.Process(target=flooder, args=(port, stop_at, counters[3]))]
        for p in attackers:
            p.start()
        time.sleep(1.0)  # the sockets are open and trickling
        attack_lat, attack_fail = run_clients(port, paths, max(1.0, stop_at - time.time()))
        for p in attackers:
            p.join(timeout=30)
        attack_end = time.time()
        back = None
        while time.time() < attack_end + 5:
            smp = sampler.sample()
            if smp and smp[1] <= idle_fds + 16:
                back = time.time() - attack_end
                break
            time.sleep(0.1)

        wrk = {}
        if shutil.which("wrk"):
            with open(os.path.join(work, "paths.txt"), "w") as f:
                f.write("\n".join(p[len("/tiles/bench"):] for p in paths) + "\n")
            env = dict(os.environ, TILE_PATHS=os.path.join(work, "paths.txt"), PREFIX="/tiles/bench")
            out = subprocess.run(["wrk", "-t2", "-c256", f"-d{wrk_s}s", "--timeout", "10s",
                                  "-s", os.path.join(os.path.dirname(os.path.abspath(__file__)), "urls.lua"),
                                  f"http://{HOST}:{port}/"], capture_output=True, text=True, env=env)
            text = out.stdout
            socket_errors = 0
            for l in text.splitlines():
                if "Socket errors" in l:
                    socket_errors = sum(int(x.split()[-1]) for x in l.split(":", 1)[1].split(","))
            non2xx = 0
            for l in text.splitlines():
                if "Non-2xx or 3xx responses" in l:
                    non2xx = int(l.split(":")[1])
            rps = next((float(l.split(":")[1]) for l in text.splitlines() if l.startswith("Requests/sec")), 0.0)
            wrk = {"seconds": wrk_s, "connections": 256, "requests_per_s": rps,
                   "socket_errors": socket_errors, "non_2xx_3xx": non2xx, "rc": out.returncode}
        sampler.stop.set()
        sampler.join()
        peak_fds = max(s[1] for s in sampler.samples)
        peak_rss = max(s[2] for s in sampler.samples)
        final_rss = sampler.samples[-1][2]
        base_p99, attack_p99 = percentile(base_lat, 99), percentile(attack_lat, 99)
        ratio = attack_p99 / base_p99 if base_p99 > 0 else float("inf")
        result = {
            "baseline": {"requests": len(base_lat), "failed": len(base_fail),
                         "p50_ms": percentile(base_lat, 50) * 1e3, "p99_ms": base_p99 * 1e3},
            "attack": {"requests": len(attack_lat), "failed": len(attack_fail),
                       "p50_ms": percentile(attack_lat, 50) * 1e3, "p99_ms": attack_p99 * 1e3,
                       "p99_ratio": ratio,
                       "slowloris_connects": counters[0].value,
                       "close_trickle_connects": counters[1].value,
                       "malformed_requests": counters[2].value + counters[3].value},
            "server": {"idle_fds": idle_fds, "peak_fds": peak_fds,
                       "fds_back_after_s": back, "rss0_mib": rss0 / 2**20,
                       "peak_rss_mib": peak_rss / 2**20, "final_rss_mib": final_rss / 2**20},
            "wrk": wrk,
        }
        problems = []
        if base_fail or attack_fail:
            problems.append(f"failed normal requests: {(base_fail + attack_fail)[:5]}")
        if not base_lat or not attack_lat:
            problems.append("no normal request completed")
        if peak_fds > MAX_CONNECTIONS + 64:
            problems.append(f"descriptors peaked at {peak_fds} (limit {MAX_CONNECTIONS} + 64)")
        if back is None:
            problems.append(f"descriptors not back to {idle_fds} + 16 within 5 s of the attack")
        if peak_rss - rss0 > 256 * 2**20:
            problems.append(f"RSS grew by {(peak_rss - rss0) / 2**20:.0f} MiB")
        if wrk and (wrk["socket_errors"] or wrk["non_2xx_3xx"] or wrk["rc"]):
            problems.append(f"wrk: {wrk}")
        if a.gate_p99 and not ratio <= 5.0:
            problems.append(f"p99 under attack is {ratio:.1f}x the baseline (limit 5x)")
        result["problems"] = problems
        print(json.dumps(result, indent=1))
        if a.json:
            with open(a.json, "w") as f:
                json.dump(result, f, indent=1)
        for p in problems:
            print(f"abuse: FAILED: {p}", file=sys.stderr)
        return 1 if problems else 0
    finally:
        if server:
            server.terminate()
            try:
                server.wait(timeout=15)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
