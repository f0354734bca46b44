#!/usr/bin/env python3
"""Writes the version-2 seed tiles of core/tile/fuzz/corpus/ from docs/tile-format.md alone.

An encoder independent of core/tile/src/codec.cpp: it reads the version-1 seeds with the layout of
§3, re-encodes them as version 2 following §4, and adds a tile of adversarial doubles, the
worked example of §5 and a data-edge tile with a NODATA corner (§2.1). The values the C++ test (core/tile/tests/codec_v2_seed_test.cpp) checks are
printed by this script; run it from the repository root:

    python3 core/tile/fuzz/make_v2_seeds.py
"""
import os
import struct
import zlib

CORPUS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")
HEADER = struct.Struct("<4sHBB3I6I4dQ")  # §3: 84 bytes
assert HEADER.size == 84
MASK64 = (1 << 64) - 1


def bits(value):
    return struct.unpack("<Q", struct.pack("<d", value))[0]


def zigzag(d, width):
    """§4: d is a difference modulo 2^width; signed s -> 2s (s >= 0) or -2s - 1 (s < 0)."""
    s = d - (1 << width) if d >> (width - 1) else d
    return 2 * s if s >= 0 else -2 * s - 1


def read_v1(blob):
    """A version-1 blob (§3) as (header fields, vertices [(x, y, z, w)], flat index list)."""
    h = list(HEADER.unpack_from(blob, 0))
    assert h[0] == b"TINT" and h[1] == 1
    counts = h[7:12]
    triangles = h[12]
    v = 4 + sum(counts)
    vertices = [struct.unpack_from("<4d", blob, 84 + 32 * k) for k in range(v)]
    fmt = "<%d%s" % (3 * triangles, "H" if h[2] == 2 else "I")
    indices = list(struct.unpack_from(fmt, blob, 84 + 32 * v))
    assert len(blob) == 84 + 32 * v + 3 * h[2] * triangles
    return h, vertices, indices


def write_v2(h, vertices, indices):
    """§4: same header with version 2, then the vertex planes, then the index planes."""
    v = len(vertices)
    h = list(h)
    h[1] = 2
    h[2] = 2 if v <= 65536 else 4  # §3 rule, unchanged
    out = bytearray(HEADER.pack(*h))
    words = []
    for column in range(4):  # x, y, z, weight: column order
        previous = 0
        for vertex in vertices:
            b = bits(vertex[column])
            words.append(zigzag((b - previous) & MASK64, 64))
            previous = b
    for p in range(8):
        out += bytes((w >> (8 * p)) & 0xFF for w in words)
    width = 8 * h[2]
    iwords = []
    previous = 0
    for index in indices:
        iwords.append(zigzag((index - previous) % (1 << width), width))
        previous = index
    for p in range(h[2]):
        out += bytes((w >> (8 * p)) & 0xFF for w in iwords)
    assert len(out) == 84 + 32 * v + h[2] * len(indices)
    return bytes(out)


def header(level, column, row, counts, triangles, min_z, max_z, nodata=0, source_points=0,
           errors=(0.0, 0.0)):
    return [b"TINT", 2, 2, nodata, level, column, row, *counts, triangles, min_z, max_z,
            errors[0], errors[1], source_points]


def save(name, blob):
    with open(os.path.join(CORPUS, name), "wb") as f:
        f.write(blob)
    print("wrote %s (%d bytes)" % (name, len(blob)))


def main():
    # 1. The version-1 seeds, re-encoded: the test decodes both and expects identical tiles.
    for name in ("world_two_triangles", "level3_fan", "level3_north_edge"):
        with open(os.path.join(CORPUS, name + ".tint"), "rb") as f:
            h, vertices, indices = read_v1(f.read())
        save("v2_from_v1_" + name + ".tint", write_v2(h, vertices, indices))

    # 2. The worked example of §5: level 0, two triangles, heights 100, weights 1.
    corners = [(-1.0, 1.0, 100.0, 1.0), (1.0, 1.0, 100.0, 1.0), (-1.0, -1.0, 100.0, 1.0),
               (1.0, -1.0, 100.0, 1.0)]
    blob = write_v2(header(0, 0, 0, (0, 0, 0, 0, 0), 2, 100.0, 100.0), corners,
                    [2, 3, 1, 2, 1, 0])
    save("v2_world_two_triangles.tint", blob)
    print("  plane 0:", blob[84:100].hex(" "))
    print("  plane 7:", blob[196:212].hex(" "))
    print("  index planes:", blob[212:224].hex(" "))

    # 3. Adversarial doubles in a valid level-0 tile: NE corner NODATA (z = 0), one north edge
    #    point, one interior point at (subnormal, -0.0); fan of CCW triangles around it.
    tiny = 5e-324  # the smallest subnormal
    vertices = [
        (-1.0, 1.0, -0.0, 0.0),           # 0 NW, height -0.0
        (1.0, 1.0, 0.0, 0.0),             # 1 NE, NODATA
        (-1.0, -1.0, 1e300, 2.5),         # 2 SW
        (1.0, -1.0, -1e-310, tiny),       # 3 SE, subnormal height and weight
        (0.25, 1.0, -8848.86, 1e-300),    # 4 north edge point
        (tiny, -0.0, 2.2250738585072014e-308, 1.7976931348623157e308),  # 5 interior
    ]
    triangles = [(2, 3, 5), (3, 1, 5), (1, 4, 5), (4, 0, 5), (0, 2, 5)]
    indices = [i for t in triangles for i in t]
    zs = [v[2] for k, v in enumerate(vertices) if k != 1]
    blob = write_v2(header(0, 0, 0, (1, 0, 0, 0, 1), len(triangles), min(zs), max(zs),
                           nodata=0b0010, source_points=2**64 - 1, errors=(1e-310, 0.0)),
                    vertices, indices)
    save("v2_adversarial.tint", blob)
    save("v2_adversarial.tint.zlib", zlib.compress(blob, 9))
    print("  min_z %r max_z %r" % (min(zs), max(zs)))
    for k, v in enumerate(vertices):
        print("  vertex %d bits %s" % (k, " ".join("%016x" % bits(c) for c in v)))

    # 4. A tile at the data's edge (§2.1): the NW corner is NODATA and carries a height continued
    #    from the data (not 0). Level 12, column 100, row 200, bounds from §1; one north and one
    #    west edge point at the sides' midpoints, one interior point at the centre. The two
    #    triangles using vertex 0 are NODATA triangles, the other four the data footprint.
    n = 1 << 12
    min_x, max_x = -1 + 2 * 100 / n, -1 + 2 * 101 / n
    max_y, min_y = 1 - 2 * 200 / n, 1 - 2 * 201 / n
    mid_x, mid_y = (min_x + max_x) / 2, (min_y + max_y) / 2
    vertices = [
        (min_x, max_y, 3105.25, 0.0),  # 0 NW, NODATA: the nearest input point's height
        (max_x, max_y, 3131.0, 0.0),   # 1 NE
        (min_x, min_y, 3140.5, 0.0),   # 2 SW
        (max_x, min_y, 3150.0, 0.0),   # 3 SE
        (mid_x, max_y, 3120.0, 0.0),   # 4 north edge point
        (min_x, mid_y, 3122.0, 0.0),   # 5 west edge point
        (mid_x, mid_y, 3125.5, 1.0),   # 6 interior
    ]
    triangles = [(0, 5, 6), (0, 6, 4), (4, 6, 1), (6, 3, 1), (5, 2, 6), (2, 3, 6)]
    footprint = [0 if 0 in t else 1 for t in triangles]  # §2.1: no NODATA vertex
    zs = [v[2] for k, v in enumerate(vertices) if k != 0]
    blob = write_v2(header(12, 100, 200, (1, 0, 0, 1, 1), len(triangles), min(zs), max(zs),
                           nodata=0b0001, source_points=1, errors=(0.0, 0.0)),
                    vertices, [i for t in triangles for i in t])
    save("v2_nodata_footprint.tint", blob)
    print("  footprint (1 = data triangle):", footprint)


if __name__ == "__main__":
    main()
