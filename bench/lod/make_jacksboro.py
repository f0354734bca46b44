#!/usr/bin/python3
"""Writes a DEM nobody tuned the pyramid on: matplotlib's sample `jacksboro_fault_dem.npz` (a USGS
3-arc-second DEM of the Jacksboro fault, Tennessee, 403 x 344 cells, 236-1,076 m), from Debian's
python-matplotlib-data package, onto its level-11 EPSG:3857 tile (544/800), 256 x 256 cells.

    apt-get install -y python-matplotlib-data gdal-bin
    /usr/bin/python3 bench/lod/make_jacksboro.py OUT
    bench/lod/pyramid_vs_delatin.sh OUT/jacksboro3857_l11.tif 4096

No numpy needed: the .npz is a zip of .npy arrays (a short header, then little-endian values).
Writes OUT/jacksboro.asc (AAIGrid, EPSG:4326, first row north) and warps it with gdalwarp
(bilinear) to OUT/jacksboro3857_l11.tif.
"""
import math
import os
import struct
import subprocess
import sys
import zipfile

NPZ = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz"
OUT = sys.argv[1] if len(sys.argv) > 1 else sys.exit(__doc__)
os.makedirs(OUT, exist_ok=True)
z = zipfile.ZipFile(NPZ)


def npy(name):
    """(header dict text, raw bytes) of one array of the archive."""
    b = z.read(name + ".npy")
    header_len = int.from_bytes(b[8:10], "little")
    return b[10:10 + header_len].decode(), b[10 + header_len:]


def scalar(name):
    return struct.unpack("<d", npy(name)[1][:8])[0]


header, raw = npy("elevation")
assert "'<i2'" in header and "(344, 403)" in header, header
rows, cols = 344, 403
heights = struct.unpack("<%dh" % (rows * cols), raw)
cell = scalar("dx")
xmin = scalar("xmin")
north = max(scalar("ymin"), scalar("ymax"))
asc = os.path.join(OUT, "jacksboro.asc")
with open(asc, "w") as f:
    f.write("ncols %d\nnrows %d\nxllcorner %.10f\nyllcorner %.10f\ncellsize %.12f\n"
            "NODATA_value -32768\n" % (cols, rows, xmin, north - rows * cell, cell))
    for r in range(rows):
        f.write(" ".join(str(h) for h in heights[r * cols:(r + 1) * cols]) + "\n")

# The level-11 Web Mercator tile under the DEM's centre (it lies inside the data).
R = 6378137.0
world = math.pi * R
n = 2 ** 11
lon = xmin + cols * cell / 2
lat = north - rows * cell / 2
tx = int((lon + 180) / 360 * n)
ty = int((1 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2 * n)
size = 2 * world / n
x0, y1 = -world + tx * size, world - ty * size
subprocess.run(["gdalwarp", "-q", "-overwrite", "-s_srs", "EPSG:4326", "-t_srs", "EPSG:3857",
                "-te", "%.6f" % x0, "%.6f" % (y1 - size), "%.6f" % (x0 + size), "%.6f" % y1,
                "-ts", "256", "256", "-r", "bilinear", "-ot", "Float32", "-dstnodata", "-32768",
                asc, os.path.join(OUT, "jacksboro3857_l11.tif")], check=True)
print("tile 11/%d/%d -> %s" % (tx, ty, os.path.join(OUT, "jacksboro3857_l11.tif")))
