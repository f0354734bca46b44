#include <gdal.h>
#include <gtest/gtest.h>
#include <ogr_srs_api.h>

#include <cmath>
#include <fstream>

#include "las_writer.hpp"
#include "read_all.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {
namespace {

using testing::kData;
using testing::read_all;

// A 4 × 3 Float32 GeoTIFF in UTM 33N: origin (500000, 4000300), 10 m × -100 m cells;
// value = 10·row + col, NODATA -9999 at (0,1), NaN at (2,3).
std::filesystem::path make_geotiff(const std::filesystem::path& dir) {
  GDALAllRegister();
  auto path = dir / "small.tif";
  GDALDriverH drv = GDALGetDriverByName("GTiff");
  GDALDatasetH ds = GDALCreate(drv, path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
  double gt[6] = {500000, 10, 0, 4000300, 0, -100};
  GDALSetGeoTransform(ds, gt);
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, 32633);
  GDALSetSpatialRef(ds, srs);
  OSRDestroySpatialReference(srs);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  GDALSetRasterNoDataValue(band, -9999);
  float values[12];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) values[r * 4 + c] = static_cast<float>(10 * r + c);
  }
  values[1] = -9999;
  values[2 * 4 + 3] = std::nanf("");
  EXPECT_EQ(GDALRasterIO(band, GF_Write, 0, 0, 4, 3, values, 4, 3, GDT_Float32, 0, 0), CE_None);
  GDALClose(ds);
  return path;
}

TEST(RasterSource, CellCentresSkippingNodataAndNan) {
  auto dir = testing::scratch_dir("raster_small");
  auto path = make_geotiff(dir);
  auto src = open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().crs, "EPSG:32633");
  EXPECT_EQ((*src)->info().format, "GDAL GTiff");
  EXPECT_EQ((*src)->info().record_count, 12u);
  auto pts = read_all(**src, 5);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  ASSERT_EQ(pts->size(), 10u);
  // First point: row 0, col 0 → centre (500005, 4000250), value 0.
  EXPECT_DOUBLE_EQ((*pts)[0].x, 500005);
  EXPECT_DOUBLE_EQ((*pts)[0].y, 4000250);
  EXPECT_DOUBLE_EQ((*pts)[0].z, 0);
  // Second point skips the NODATA cell (0,1): it is (0,2).
  EXPECT_DOUBLE_EQ((*pts)[1].x, 500025);
  EXPECT_DOUBLE_EQ((*pts)[1].z, 2);
  EXPECT_EQ((*pts)[1].record, 3u);
  // Last point: (2,2), value 22, centre (500025, 4000050).
  EXPECT_DOUBLE_EQ(pts->back().x, 500025);
  EXPECT_DOUBLE_EQ(pts->back().y, 4000050);
  EXPECT_DOUBLE_EQ(pts->back().z, 22);
  EXPECT_EQ((*src)->counters().rejected_nodata, 2u);
  std::filesystem::remove_all(dir);
}

TEST(RasterSource, BandScaleAndOffsetAreApplied) {
  auto dir = testing::scratch_dir("raster_scale");
  GDALAllRegister();
  const auto path = dir / "scaled.tif";
  GDALDatasetH ds =
      GDALCreate(GDALGetDriverByName("GTiff"), path.c_str(), 2, 1, 1, GDT_Int16, nullptr);
  double gt[6] = {10, 1, 0, 20, 0, -1};
  GDALSetGeoTransform(ds, gt);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  GDALSetRasterScale(band, 0.5);
  GDALSetRasterOffset(band, 100);
  GDALSetRasterNoDataValue(band, -1);
  std::int16_t values[2] = {-1, 7};  // NODATA is the raw value
  ASSERT_EQ(GDALRasterIO(band, GF_Write, 0, 0, 2, 1, values, 2, 1, GDT_Int16, 0, 0), CE_None);
  GDALClose(ds);
  auto src = open_raster(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  auto pts = read_all(**src, 4096);
  ASSERT_TRUE(pts.ok());
  ASSERT_EQ(pts->size(), 1u);
  EXPECT_EQ((*pts)[0].z, 103.5);
  EXPECT_EQ((*pts)[0].x, 11.5);
  std::filesystem::remove_all(dir);
}

TEST(RasterSource, NotARasterGivesAnErrorNamingTheFile) {
  auto dir = testing::scratch_dir("raster_bad");
  auto p = dir / "junk.dat";
  std::ofstream(p) << "this is not elevation data\n";
  auto src = open_source(p);
  ASSERT_FALSE(src.ok());
  EXPECT_NE(src.error().message.find(p.string()), std::string::npos) << src.error().message;
  std::filesystem::remove_all(dir);
}

TEST(RasterSource, BadBandIsRejected) {
  auto dir = testing::scratch_dir("raster_band");
  auto path = make_geotiff(dir);
  SourceOptions o;
  o.raster_band = 2;
  auto src = open_raster(path, o);
  ASSERT_FALSE(src.ok());
  EXPECT_EQ(src.error().code, ErrorCode::invalid_argument);
  std::filesystem::remove_all(dir);
}

TEST(RasterRealData, LuxembourgSkipsItsNodataCells) {
  const auto path = kData / "luxembourg_elev.tif";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().crs, "EPSG:4326");
  EXPECT_EQ((*src)->info().record_count, 95u * 90u);
  auto pts = read_all(**src, 1000);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  EXPECT_EQ(pts->size(), 4608u);
  EXPECT_EQ((*src)->counters().rejected_nodata, 3942u);
  for (const auto& p : *pts) {
    ASSERT_GT(p.x, 5.741667);
    ASSERT_LT(p.x, 6.533333);
    ASSERT_GT(p.y, 49.441667);
    ASSERT_LT(p.y, 50.191667);
    ASSERT_GE(p.z, 141);
    ASSERT_LE(p.z, 547);
  }
}

TEST(RasterRealData, SrtmHgtTileHasEveryCell) {
  const auto path = kData / "N00E010.hgt";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().crs, "EPSG:4326");
  std::vector<SourcePoint> batch;
  std::uint64_t n = 0;
  double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9, zmin = 1e9, zmax = -1e9;
  while (true) {
    batch.clear();
    auto got = (*src)->read(batch, 65536);
    ASSERT_TRUE(got.ok()) << got.error().message;
    if (*got == 0) break;
    n += *got;
    for (const auto& p : batch) {
      xmin = std::min(xmin, p.x), xmax = std::max(xmax, p.x);
      ymin = std::min(ymin, p.y), ymax = std::max(ymax, p.y);
      zmin = std::min(zmin, p.z), zmax = std::max(zmax, p.z);
    }
  }
  EXPECT_EQ(n, 1201u * 1201u);
  // Samples are centred on whole degrees: 10°E … 11°E, 0°N … 1°N.
  EXPECT_NEAR(xmin, 10.0, 1e-9);
  EXPECT_NEAR(xmax, 11.0, 1e-9);
  EXPECT_NEAR(ymin, 0.0, 1e-9);
  EXPECT_NEAR(ymax, 1.0, 1e-9);
  EXPECT_EQ(zmin, 1);
  EXPECT_EQ(zmax, 1005);
}

TEST(RasterRealData, EsriAsciiGridHasNoCrs) {
  const auto path = kData / "boulder_srtmgl3.asc";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_TRUE((*src)->info().crs.empty());
  EXPECT_EQ((*src)->info().format, "GDAL AAIGrid");
  auto pts = read_all(**src, 10000);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 240u * 144u);
  double zmin = 1e9, zmax = -1e9;
  for (const auto& p : *pts) {
    zmin = std::min(zmin, p.z);
    zmax = std::max(zmax, p.z);
    ASSERT_GT(p.x, -105.550417);
    ASSERT_LT(p.x, -105.350417);
    ASSERT_GT(p.y, 40.090417);
    ASSERT_LT(p.y, 40.210417);
  }
  EXPECT_EQ(zmin, 1943);
  EXPECT_EQ(zmax, 3286);
}

}  // namespace
}  // namespace tinstream::sources
