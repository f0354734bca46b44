#!/usr/bin/env python3
"""Passes 1+2 of two tinstream binaries, alternately, on one input.

Times each ingest from its start to its first "triangulate" progress line (wall) and reads the
process CPU then (/proc), then stops it with SIGINT (the ingest cancels cleanly), so that many
rounds fit where whole ingests (pass 3 dominates) would not. Alternating the order per round
spreads a shared machine's noise over both binaries.

  bench/ingest/pass12_ab.py OLD_BIN NEW_BIN INPUT [ROUNDS]
"""
import os
import signal
import subprocess
import sys
import tempfile
import time


def passes12(binary, source, store):
    for suffix in ("", "-wal", "-shm"):
        if os.path.exists(store + suffix):
            os.remove(store + suffix)
    start = time.monotonic()
    p = subprocess.Popen([binary, "ingest", "--store", store, "--layer", "p", "--no-pyramid", source],
                         stderr=subprocess.PIPE, stdout=subprocess.DEVNULL)
    seen, wall, cpu = b"", None, None
    while True:
        chunk = p.stderr.read1(4096)
        if not chunk:
            break
        seen = (seen + chunk)[-256:]
        if b"triangulate:" in seen:
            wall = time.monotonic() - start
            stat = open(f"/proc/{p.pid}/stat").read().rsplit(")", 1)[1].split()
            cpu = (int(stat[11]) + int(stat[12])) / os.sysconf("SC_CLK_TCK")
            p.send_signal(signal.SIGINT)
            break
    p.wait()
    return wall, cpu


def main():
    old, new, source = sys.argv[1:4]
    rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 3
    store = os.path.join(tempfile.gettempdir(), "pass12_ab.sqlite")
    for r in range(rounds):
        for name, binary in ((("old", old), ("new", new)) if r % 2 == 0 else
                             (("new", new), ("old", old))):
            wall, cpu = passes12(binary, source, store)
            load = open("/proc/loadavg").read().split()[0]
            print(f"{name} round {r + 1}: passes 1+2 wall {wall:.2f} s, CPU {cpu:.2f} s, load {load}",
                  flush=True)
            time.sleep(1)


if __name__ == "__main__":
    main()
