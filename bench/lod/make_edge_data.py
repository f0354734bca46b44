#!/usr/bin/python3
"""Writes the inputs of the #20 measurements (data-edge terrain, pyramid quality) into OUT.

    /usr/bin/python3 bench/lod/make_edge_data.py OUT [DATA]

Equivalents of the issue's public datasets, made from ../shared/data with GDAL and numpy (the
system Python: `apt-get install python3-gdal python3-numpy`):

  lidar_crop.xyz      autzen_trim.las, every point (110,000, classes 1 and 2), in UTM 10N metres
                      (EPSG:32610), heights raised by 2976 m: a ~360 x 170 m LiDAR crop at
                      3,100-3,135 m (the issue's: 300 x 200 m at 3,100-3,210 m)
  alps250.tif         Big Tujunga's relief (315-2,295 m) resampled to 250 m cells and placed in
                      UTM 32N (EPSG:32632, the Alps' zone), with NoData outside an irregular outline
                      and in three holes (the issue's: a 250 m Alps DEM with NoData, UTM 32N)
  lux250.tif          luxembourg_elev.tif warped to UTM 32N at 250 m (NoData outside the country)
  dem3857_l10.tif     N00E010.hgt warped to one level-10 EPSG:3857 tile, 512 x 512 cells (cell
                      centres half a cell inside the tile, so the tile's corners are NODATA)
  rgb3857_z14.tif     terrainrgb_14-2625-6369.png decoded as heights (-10000 + 0.1 x RGB) on its
                      z14 EPSG:3857 tile, 512 x 512
"""
import math
import os
import struct
import subprocess
import sys

import numpy as np
from osgeo import gdal, osr

gdal.UseExceptions()
OUT = sys.argv[1]
DATA = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared", "data")
os.makedirs(OUT, exist_ok=True)
R = 6378137.0
WORLD = math.pi * R  # half the EPSG:3857 extent


def las_points(path):
    """(x, y, z, class) of every record of a LAS 1.0-1.4 file (point formats 0-10)."""
    b = open(path, "rb").read()
    offset, = struct.unpack_from("<I", b, 96)
    fmt, size = b[104], struct.unpack_from("<H", b, 105)[0]
    count, = struct.unpack_from("<I", b, 107)
    sx, sy, sz, ox, oy, oz = struct.unpack_from("<6d", b, 131)
    rec = np.frombuffer(b, dtype=np.uint8, count=count * size, offset=offset).reshape(count, size)
    xyz = rec[:, :12].copy().view("<i4").astype(np.float64)
    cls = rec[:, 15] & (0x1F if fmt < 6 else 0xFF) if fmt < 6 else rec[:, 16]
    return xyz[:, 0] * sx + ox, xyz[:, 1] * sy + oy, xyz[:, 2] * sz + oz, cls


def lidar_crop():
    x, y, z, _ = las_points(os.path.join(DATA, "autzen_trim.las"))
    src = osr.SpatialReference()
    src.ImportFromEPSG(2994)  # NAD83(HARN) / Oregon GIC Lambert (ft), SOURCES.md
    dst = osr.SpatialReference()
    dst.ImportFromEPSG(32610)
    for s in (src, dst):
        s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    t = osr.CoordinateTransformation(src, dst)
    pts = np.array(t.TransformPoints(np.column_stack([x, y])))
    zm = z * 0.3048 + 2976.0
    with open(os.path.join(OUT, "lidar_crop.xyz"), "w") as f:
        for (e, n, _), h in zip(pts, zm):
            f.write("%.3f %.3f %.3f\n" % (e, n, h))


def write_tif(path, z, x0, y0, cell, epsg, nodata):
    ds = gdal.GetDriverByName("GTiff").Create(path, z.shape[1], z.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform((x0, cell, 0, y0, 0, -cell))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(epsg)
    ds.SetProjection(srs.ExportToWkt())
    band = ds.GetRasterBand(1)
    if nodata is not None:
        band.SetNoDataValue(nodata)
    band.WriteArray(z.astype(np.float32))
    ds = None


def alps(cell, name):
    src = gdal.Open(os.path.join(DATA, "bigtujunga_srtm30m_utm11.tif"))
    warped = gdal.Warp("", src, format="MEM", xRes=cell, yRes=cell, resampleAlg="average")
    z = warped.ReadAsArray().astype(np.float64)
    h, w = z.shape
    rows, cols = np.mgrid[0:h, 0:w]
    u, v = (cols + 0.5) / w * 2 - 1, (rows + 0.5) / h * 2 - 1
    angle = np.arctan2(v, u)
    radius = 0.92 + 0.08 * np.sin(5 * angle) + 0.05 * np.cos(11 * angle)
    outside = u * u + v * v > radius * radius
    for cu, cv, r in ((-0.3, 0.2, 0.12), (0.35, -0.25, 0.08), (0.1, 0.5, 0.05)):
        outside |= (u - cu) ** 2 + ((v - cv) * 1.6) ** 2 < r * r
    z[outside] = -9999
    write_tif(os.path.join(OUT, name), z, 420000.0, 5180000.0, float(cell), 32632, -9999)


def lux():
    gdal.Warp(os.path.join(OUT, "lux250.tif"), os.path.join(DATA, "luxembourg_elev.tif"),
              dstSRS="EPSG:32632", xRes=250, yRes=250, resampleAlg="bilinear",
              dstNodata=-32768)


def tile_3857(z, x, y):
    size = 2 * WORLD / (1 << z)
    return -WORLD + x * size, WORLD - (y + 1) * size, -WORLD + (x + 1) * size, WORLD - y * size


def dem3857():
    z = 10
    lon, lat = 10.5, 0.5
    x = int((lon + 180) / 360 * (1 << z))
    y = int((1 - math.log(math.tan(math.radians(lat)) + 1 / math.cos(math.radians(lat))) / math.pi)
            / 2 * (1 << z))
    gdal.Warp(os.path.join(OUT, "dem3857_l10.tif"), os.path.join(DATA, "N00E010.hgt"),
              dstSRS="EPSG:3857", outputBounds=tile_3857(z, x, y), width=512, height=512,
              resampleAlg="bilinear", outputType=gdal.GDT_Float32)
    print("dem3857_l10.tif: level-10 tile x=%d y=%d" % (x, y))


def rgb():
    ds = gdal.Open(os.path.join(DATA, "terrainrgb_14-2625-6369.png"))
    r, g, b = (ds.GetRasterBand(k).ReadAsArray().astype(np.float64) for k in (1, 2, 3))
    h = -10000 + (r * 65536 + g * 256 + b) * 0.1
    x0, y0, x1, y1 = tile_3857(14, 2625, 6369)
    write_tif(os.path.join(OUT, "rgb3857_z14.tif"), h, x0, y1, (x1 - x0) / 512, 3857, None)


lidar_crop()
alps(250, "alps250.tif")
alps(30, "alps30.tif")
lux()
dem3857()
rgb()
print("written to", OUT)
