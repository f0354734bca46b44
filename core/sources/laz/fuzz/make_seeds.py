#!/usr/bin/env python3
"""Writes the laz_fuzzer's small checked-in seeds (corpus/): LAZ files of one point each, built
byte by byte from the LAS 1.2/1.4 and LAZ layouts (no encoder needed: a chunk's first point is
stored raw). Their chunk tables are deliberately absent (offset -1 pointing nowhere), so they
also exercise the table rebuild. The real LAZ files of ../shared/data are the main seeds
(run.sh); these keep the replay test (Fuzz.laz_fuzzer.Replay) meaningful without them. The
corpus's seed_*.laz files are LASzip-written, not from here (core/sources/laz/tests/data/README.md).
    python3 core/sources/laz/fuzz/make_seeds.py"""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def laszip_vlr(compressor, items, chunk_size=50000):
    body = struct.pack('<HHBBHIIqqH', compressor, 0, 3, 4, 3, 0, chunk_size, -1, -1, len(items))
    for t, size, version in items:
        body += struct.pack('<HHH', t, size, version)
    header = struct.pack('<H16sHH32s', 0, b'laszip encoded', 22204, len(body), b'seed')
    return header + body


def las_header(minor, fmt, record_length, count, offset_to_points, vlrs):
    size = 375 if minor == 4 else 227
    h = bytearray(size)
    h[0:4] = b'LASF'
    h[24], h[25] = 1, minor
    struct.pack_into('<HII', h, 94, size, offset_to_points, vlrs)
    h[104] = fmt | 0x80
    struct.pack_into('<HI', h, 105, record_length, count if minor < 4 else 0)
    struct.pack_into('<3d3d', h, 131, 0.01, 0.01, 0.01, 0, 0, 0)
    struct.pack_into('<6d', h, 179, 10, 0, 20, 0, 30, 0)
    if minor == 4:
        struct.pack_into('<Q', h, 247, count)
    return bytes(h)


def write(name, data):
    with open(os.path.join(HERE, 'corpus', name), 'wb') as f:
        f.write(data)


# Format 0, compressor 2 (pointwise chunked), POINT10 v2: one raw point, the 4 bytes the range
# decoder reads at start, no chunk table.
vlr = laszip_vlr(2, [(6, 20, 2)])
offset = 227 + len(vlr)
point = struct.pack('<3iHBBbBH', 1000, 2000, 3000, 7, 0x09, 2, 0, 0, 1)
write('pointwise_one_point.laz',
      las_header(2, 0, 20, 1, offset, 1) + vlr + struct.pack('<q', -1) + point + bytes(4))

# Format 6, compressor 3 (layered), POINT14 v3: one raw point, its count and nine empty layers.
vlr = laszip_vlr(3, [(10, 30, 3)])
offset = 375 + len(vlr)
point = struct.pack('<3iHBBBBhHd', 1000, 2000, 3000, 7, 0x11, 0, 2, 0, 0, 1, 12345.5)
write('layered_one_point.laz',
      las_header(4, 6, 30, 1, offset, 1) + vlr + struct.pack('<q', -1) + point +
      struct.pack('<I', 1) + bytes(4 * 9))
