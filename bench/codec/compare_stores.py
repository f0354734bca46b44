#!/usr/bin/env python3
"""Checks that two tile stores hold the same decoded tiles, whatever blob version each wrote.

    python3 bench/codec/compare_stores.py [--triangle-sets] OLD.tinstream NEW.tinstream

Decodes every published tile of every layer of both stores with a decoder written from
docs/tile-format.md (§3 version 1, §4 version 2; independent of core/tile/src/codec.cpp) and
compares header fields (all but the version), every vertex value bit for bit and every triangle
index. With --triangle-sets the triangles are compared as a set (each counter-clockwise triple
rotated to start at its smallest index), so the same triangulation listed in another order or
with its triangles' corners rotated counts as the same. Prints one line per layer and exits 1 on
the first difference.
"""
import sqlite3
import struct
import sys
import zlib

HEADER = struct.Struct("<4sHBB3I6I4dQ")
MASK64 = (1 << 64) - 1


def unzigzag(e, mask):
    return ((e >> 1) ^ (mask if e & 1 else 0)) & mask


def decode(blob):
    """(header fields without the version, vertex bit patterns x…, y…, z…, w…, indices)."""
    raw = zlib.decompress(blob)
    h = HEADER.unpack_from(raw, 0)
    assert h[0] == b"TINT", "bad magic"
    version, width = h[1], h[2]
    v = 4 + sum(h[7:12])
    n = 3 * h[12]
    assert len(raw) == 84 + 32 * v + width * n, "size"
    ifmt = "H" if width == 2 else "I"
    if version == 1:
        words = struct.unpack_from("<%dQ" % (4 * v), raw, 84)
        columns = [words[c::4] for c in range(4)]  # records (x, y, z, w) → columns
        values = [b for column in columns for b in column]
        indices = list(struct.unpack_from("<%d%s" % (n, ifmt), raw, 84 + 32 * v))
    elif version == 2:
        interleaved = bytearray(32 * v)
        for p in range(8):  # plane p → byte p of every word
            interleaved[p::8] = raw[84 + p * 4 * v: 84 + (p + 1) * 4 * v]
        codes = struct.unpack("<%dQ" % (4 * v), bytes(interleaved))
        values = []
        for c in range(4):
            previous = 0
            for e in codes[c * v:(c + 1) * v]:
                previous = (previous + unzigzag(e, MASK64)) & MASK64
                values.append(previous)
        base = 84 + 32 * v
        interleaved = bytearray(width * n)
        for p in range(width):
            interleaved[p::width] = raw[base + p * n: base + (p + 1) * n]
        mask = (1 << (8 * width)) - 1
        indices = []
        previous = 0
        for e in struct.unpack("<%d%s" % (n, ifmt), bytes(interleaved)):
            previous = (previous + unzigzag(e, mask)) & mask
            indices.append(previous)
    else:
        raise ValueError("unknown version %d" % version)
    return (h[:1] + h[2:]), values, indices, version


def tiles(path):
    db = sqlite3.connect("file:%s?mode=ro" % path, uri=True)
    out = {}
    for layer, z, x, y, data in db.execute("SELECT layer, z, x, y, data FROM published_tiles"):
        out.setdefault(layer, {})[(z, x, y)] = data
    return out


def triangle_set(indices):
    out = set()
    for i in range(0, len(indices), 3):
        t = indices[i:i + 3]
        k = t.index(min(t))
        out.add(tuple(t[k:] + t[:k]))
    assert len(out) * 3 == len(indices), "a triangle listed twice"
    return out


def main():
    args = sys.argv[1:]
    as_sets = "--triangle-sets" in args
    args = [a for a in args if a != "--triangle-sets"]
    old, new = tiles(args[0]), tiles(args[1])
    if sorted(old) != sorted(new):
        print("layers differ: %s vs %s" % (sorted(old), sorted(new)))
        return 1
    for layer in sorted(old):
        a, b = old[layer], new[layer]
        if sorted(a) != sorted(b):
            print("%s: tile ids differ" % layer)
            return 1
        versions = {1: 0, 2: 0}
        old_bytes = new_bytes = vertices = 0
        for key in sorted(a):
            da, db = decode(a[key]), decode(b[key])
            versions[db[3]] += 1
            same = da[:2] == db[:2] and (
                triangle_set(da[2]) == triangle_set(db[2]) if as_sets else da[2] == db[2])
            if not same:
                print("%s tile %s: decoded tiles differ" % (layer, key))
                return 1
            old_bytes += len(a[key])
            new_bytes += len(b[key])
            vertices += len(da[1]) // 4
        print("%s: %d tiles identical (%d vertices); stored bytes %d -> %d (%.3fx); "
              "second store's versions %s" % (layer, len(a), vertices, old_bytes, new_bytes,
                                               new_bytes / old_bytes, versions))
    return 0


if __name__ == "__main__":
    sys.exit(main())
