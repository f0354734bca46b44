// Ingest confinement of GDAL rasters (#22, open door 2) and NODATA compared in the band's type.
// Every hostile file here is one the reader accepted before: a VRT naming files outside the data
// root, raw and derived bands, /vsi and URL sources, formats outside the allow-list, rasters too
// big to allocate, a NODATA written as text that no cell equals as a double.
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

using testing::read_all;

namespace fs = std::filesystem;

// A w × h GeoTIFF in EPSG:4326 near Zürich, cell value = row * w + col, band type `type`, with
// `nodata` set (unless NaN) and written into the cells listed in `nodata_cells`.
fs::path write_tif(const fs::path& path, int w, int h, GDALDataType type, double nodata,
                   const std::vector<int>& nodata_cells = {}, const char* const* create = nullptr) {
  GDALAllRegister();
  GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), path.c_str(), w, h, 1, type,
                               const_cast<char**>(create));
  EXPECT_NE(ds, nullptr);
  double gt[6] = {8.5, 0.001, 0, 47.4, 0, -0.001};
  GDALSetGeoTransform(ds, gt);
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, 4326);
  GDALSetSpatialRef(ds, srs);
  OSRDestroySpatialReference(srs);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  if (!std::isnan(nodata)) GDALSetRasterNoDataValue(band, nodata);
  std::vector<double> v(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = 400.0 + static_cast<double>(i);
  for (int c : nodata_cells) v[static_cast<std::size_t>(c)] = nodata;
  EXPECT_EQ(GDALRasterIO(band, GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0), CE_None);
  GDALClose(ds);
  return path;
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

// A VRT of one Float32 band over `source` (as written in the file: relative or absolute).
std::string vrt_over(const std::string& source, bool relative, int w = 4, int h = 3,
                     const std::string& band_extra = "", const std::string& source_extra = "",
                     const std::string& type = "Float32") {
  return "<VRTDataset rasterXSize=\"" + std::to_string(w) + "\" rasterYSize=\"" +
         std::to_string(h) +
         "\">\n"
         "  <SRS>EPSG:4326</SRS>\n"
         "  <GeoTransform>8.5, 0.001, 0, 47.4, 0, -0.001</GeoTransform>\n"
         "  <VRTRasterBand dataType=\"" +
         type + "\" band=\"1\">\n" + band_extra +
         "    <SimpleSource>\n"
         "      <SourceFilename relativeToVRT=\"" +
         (relative ? "1" : "0") + "\">" + source +
         "</SourceFilename>\n"
         "      <SourceBand>1</SourceBand>\n" +
         source_extra +
         "    </SimpleSource>\n"
         "  </VRTRasterBand>\n"
         "</VRTDataset>\n";
}

class RasterPolicyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("policy_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    root_ = dir_ / "root";
    outside_ = dir_ / "outside";
    fs::create_directories(root_);
    fs::create_directories(outside_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  SourceOptions confined() const {
    SourceOptions o;
    o.raster = RasterPolicy::confined(root_);
    return o;
  }
  static void expect_refused(const Result<std::unique_ptr<PointSource>>& r,
                             const std::string& why) {
    ASSERT_FALSE(r.ok()) << "accepted; expected a refusal mentioning '" << why << "'";
    EXPECT_EQ(r.error().code, ErrorCode::unsupported) << r.error().message;
    EXPECT_NE(r.error().message.find(why), std::string::npos) << r.error().message;
  }
  fs::path dir_, root_, outside_;
};

TEST_F(RasterPolicyTest, VrtSourceOutsideTheDataRootIsRefusedWhenConfined) {
  // The reproduction of #22: a VRT under the data root whose source is an absolute path outside.
  const fs::path secret = write_tif(outside_ / "secret.tif", 4, 3, GDT_Float32, NAN);
  write_text(root_ / "escape.vrt", vrt_over(secret.string(), false));
  expect_refused(open_source(root_ / "escape.vrt", confined()), "outside the data root");
  // The same through a relative path with .., and through a symlink under the root.
  write_text(root_ / "dotdot.vrt", vrt_over("../outside/secret.tif", true));
  expect_refused(open_source(root_ / "dotdot.vrt", confined()), "outside the data root");
  fs::create_symlink(secret, root_ / "link.tif");
  write_text(root_ / "link.vrt", vrt_over("link.tif", true));
  expect_refused(open_source(root_ / "link.vrt", confined()), "outside the data root");
  expect_refused(open_source(root_ / "link.tif", confined()), "outside the data root");
  // A VRT whose sources are under the root reads; the CLI's policy reads the escaping one.
  write_tif(root_ / "inside.tif", 4, 3, GDT_Float32, NAN);
  write_text(root_ / "fine.vrt", vrt_over("inside.tif", true));
  auto fine = open_source(root_ / "fine.vrt", confined());
  ASSERT_TRUE(fine.ok()) << fine.error().message;
  auto pts = read_all(**fine, 4096);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  EXPECT_EQ(pts->size(), 12u);
  auto local = open_source(root_ / "escape.vrt");
  ASSERT_TRUE(local.ok()) << local.error().message;
  // Confined without VRTs: a VRT is not a raster of the allowed formats at all.
  SourceOptions no_vrt;
  no_vrt.raster = RasterPolicy::confined(root_, false);
  expect_refused(open_source(root_ / "fine.vrt", no_vrt), "formats allowed for ingest");
}

TEST_F(RasterPolicyTest, VrtFeaturesThatReadArbitraryFilesOrRunCodeAreRefusedEverywhere) {
  write_tif(root_ / "dem.tif", 4, 3, GDT_Float32, NAN);
  const std::string raw =
      "<VRTDataset rasterXSize=\"16\" rasterYSize=\"1\">\n"
      "  <VRTRasterBand dataType=\"Byte\" band=\"1\" subClass=\"VRTRawRasterBand\">\n"
      "    <SourceFilename relativeToVRT=\"0\">/etc/passwd</SourceFilename>\n"
      "    <ImageOffset>0</ImageOffset><PixelOffset>1</PixelOffset><LineOffset>16</LineOffset>\n"
      "  </VRTRasterBand>\n"
      "</VRTDataset>\n";
  write_text(root_ / "raw.vrt", raw);
  const std::string derived =
      "<VRTDataset rasterXSize=\"4\" rasterYSize=\"3\">\n"
      "  <GeoTransform>8.5, 0.001, 0, 47.4, 0, -0.001</GeoTransform>\n"
      "  <VRTRasterBand dataType=\"Float32\" band=\"1\" subClass=\"VRTDerivedRasterBand\">\n"
      "    <PixelFunctionType>inv</PixelFunctionType>\n"
      "    <SimpleSource><SourceFilename relativeToVRT=\"1\">dem.tif</SourceFilename>"
      "<SourceBand>1</SourceBand></SimpleSource>\n"
      "  </VRTRasterBand>\n"
      "</VRTDataset>\n";
  write_text(root_ / "derived.vrt", derived);
  write_text(root_ / "vsi.vrt", vrt_over("/vsicurl/http://127.0.0.1:9/dem.tif", false));
  write_text(root_ / "zip.vrt", vrt_over("/vsizip/bomb.zip/dem.tif", false));
  write_text(root_ / "url.vrt", vrt_over("http://127.0.0.1:9/dem.tif", false));
  write_text(root_ / "nested.vrt", vrt_over("raw.vrt", true));
  write_text(root_ / "cwd.vrt", vrt_over("dem.tif", false));  // relative to the process's cwd
  write_text(root_ / "srs.vrt",
             "<VRTDataset rasterXSize=\"4\" rasterYSize=\"3\">\n"
             "  <SRS>/etc/passwd</SRS>\n"
             "</VRTDataset>\n");
  write_text(root_ / "options.vrt",
             vrt_over("dem.tif", true, 4, 3, "",
                      "      <OpenOptions><OOI key=\"NUM_THREADS\">64</OOI></OpenOptions>\n"));
  const std::pair<const char*, const char*> cases[] = {
      {"raw.vrt", "subClass=\"VRTRawRasterBand\""},
      {"derived.vrt", "subClass=\"VRTDerivedRasterBand\""},
      {"vsi.vrt", "local files"},
      {"zip.vrt", "local files"},
      {"url.vrt", "local files"},
      {"nested.vrt", "formats allowed for ingest"},
      {"cwd.vrt", "absolute path"},
      {"srs.vrt", "<SRS>"},
      {"options.vrt", "<OpenOptions>"},
  };
  for (const auto& [file, why] : cases) {
    SCOPED_TRACE(file);
    expect_refused(open_source(root_ / file), why);  // the CLI's policy
    expect_refused(open_source(root_ / file, confined()), why);
  }
}

TEST_F(RasterPolicyTest, RastersTooBigToAllocateFailCleanlyBeforeAnyRead) {
  write_tif(root_ / "dem.tif", 4, 3, GDT_Float32, NAN);
  // Before the limits, reading this allocated a strip of 2^31 doubles (16 GiB).
  write_text(root_ / "wide.vrt", vrt_over("dem.tif", true, 2147483647, 1));
  expect_refused(open_source(root_ / "wide.vrt"), "exceed the raster limits");
  write_text(root_ / "tall.vrt", vrt_over("dem.tif", true, 4, 2147483647));
  expect_refused(open_source(root_ / "tall.vrt"), "exceed the raster limits");
  SourceOptions small;
  small.raster.max_cells = 11;
  expect_refused(open_source(root_ / "dem.tif", small), "exceed the raster limits");
  // A block (here one tile of 64 × 64) above the block limit.
  const char* strip[] = {"TILED=YES", "BLOCKXSIZE=64", "BLOCKYSIZE=64", nullptr};
  write_tif(root_ / "strip.tif", 64, 64, GDT_Float32, NAN, {}, strip);
  SourceOptions blocks;
  blocks.raster.max_block_bytes = std::uint64_t{64} * 64 * 4 - 1;
  expect_refused(open_source(root_ / "strip.tif", blocks), "has blocks of 64 × 64");
  blocks.raster.max_block_bytes = std::uint64_t{64} * 64 * 4;
  EXPECT_TRUE(open_source(root_ / "strip.tif", blocks).ok());
  // A VRT's source is held to the same limits.
  SourceOptions source_limit;
  source_limit.raster.max_block_bytes = 64 * 64 * 4 - 1;
  write_text(root_ / "over_strip.vrt", vrt_over("strip.tif", true));
  expect_refused(open_source(root_ / "over_strip.vrt", source_limit), "has blocks of 64 × 64");
  // A VRT larger than its limit is not even parsed.
  SourceOptions tiny_vrt;
  tiny_vrt.raster.max_vrt_bytes = 100;
  write_text(root_ / "fine.vrt", vrt_over("dem.tif", true));
  expect_refused(open_source(root_ / "fine.vrt", tiny_vrt), "a VRT of");
}

TEST_F(RasterPolicyTest, OnlyTheAllowedDriversOpenAnInput) {
  // PNM is a raster GDAL reads (and writes here), but not an elevation format of the list.
  GDALAllRegister();
  const fs::path pgm = root_ / "image.pgm";
  GDALDatasetH ds = GDALCreate(GDALGetDriverByName("PNM"), pgm.c_str(), 4, 3, 1, GDT_Byte, nullptr);
  ASSERT_NE(ds, nullptr);
  GDALClose(ds);
  expect_refused(open_source(pgm), "formats allowed for ingest");
  // And only one of them even as a VRT's source.
  write_text(root_ / "over_pgm.vrt", vrt_over("image.pgm", true));
  expect_refused(open_source(root_ / "over_pgm.vrt"), "formats allowed for ingest");
  // Paths GDAL would take as virtual file systems never reach it.
  SourceOptions as_raster;
  as_raster.format = SourceFormat::raster;
  expect_refused(open_source("/vsicurl/http://127.0.0.1:9/x.tif", as_raster),
                 "virtual file systems");
  // A policy naming the driver lets it in (to the next check: a PGM has no georeferencing).
  SourceOptions with_pnm;
  with_pnm.raster.drivers.emplace_back("PNM");
  expect_refused(open_source(pgm, with_pnm), "no geotransform");
}

TEST_F(RasterPolicyTest, GdalbuildvrtAndGdalTranslateVrtsAreAccepted) {
  write_tif(root_ / "a.tif", 4, 3, GDT_Float32, NAN);
  write_tif(root_ / "b.tif", 4, 3, GDT_Float32, NAN);
  // What gdalbuildvrt writes (ComplexSource, NODATA, OverviewList, metadata).
  const std::string vrt =
      "<VRTDataset rasterXSize=\"8\" rasterYSize=\"3\">\n"
      "  <SRS dataAxisToSRSAxisMapping=\"2,1\">GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID["
      "\"WGS 84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\","
      "0.0174532925199433]]</SRS>\n"
      "  <GeoTransform>8.5, 0.001, 0, 47.4, 0, -0.001</GeoTransform>\n"
      "  <Metadata><MDI key=\"AREA_OR_POINT\">Area</MDI></Metadata>\n"
      "  <OverviewList resampling=\"nearest\">2</OverviewList>\n"
      "  <VRTRasterBand dataType=\"Float32\" band=\"1\">\n"
      "    <NoDataValue>-9999</NoDataValue>\n"
      "    <ColorInterp>Gray</ColorInterp>\n"
      "    <!-- two tiles side by side -->\n"
      "    <ComplexSource>\n"
      "      <SourceFilename relativeToVRT=\"1\">a.tif</SourceFilename>\n"
      "      <SourceBand>1</SourceBand>\n"
      "      <SourceProperties RasterXSize=\"4\" RasterYSize=\"3\" DataType=\"Float32\" "
      "BlockXSize=\"4\" BlockYSize=\"3\" />\n"
      "      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"4\" ySize=\"3\" />\n"
      "      <DstRect xOff=\"0\" yOff=\"0\" xSize=\"4\" ySize=\"3\" />\n"
      "      <NODATA>-9999</NODATA>\n"
      "    </ComplexSource>\n"
      "    <ComplexSource>\n"
      "      <SourceFilename relativeToVRT=\"0\">" +
      (root_ / "b.tif").string() +
      "</SourceFilename>\n"
      "      <SourceBand>1</SourceBand>\n"
      "      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"4\" ySize=\"3\" />\n"
      "      <DstRect xOff=\"4\" yOff=\"0\" xSize=\"4\" ySize=\"3\" />\n"
      "    </ComplexSource>\n"
      "  </VRTRasterBand>\n"
      "</VRTDataset>\n";
  write_text(root_ / "mosaic.vrt", vrt);
  auto src = open_source(root_ / "mosaic.vrt", confined());
  ASSERT_TRUE(src.ok()) << src.error().message;
  auto pts = read_all(**src, 4096);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  EXPECT_EQ(pts->size(), 24u);
}

// #22, bad input that passed: gdal_translate -of VRT of a Float32 GeoTIFF whose NODATA is -3.4e38
// writes it as the text -3.399999952144364e+38, which as a double no Float32 cell equals.
TEST_F(RasterPolicyTest, Float32NodataWrittenAsTextInAVrtStillRejectsItsCells) {
  const float nodata = -3.4e38f;
  write_tif(root_ / "dem.tif", 4, 3, GDT_Float32, static_cast<double>(nodata), {1, 5, 11});
  write_text(
      root_ / "translated.vrt",
      vrt_over("dem.tif", true, 4, 3, "    <NoDataValue>-3.399999952144364e+38</NoDataValue>\n"));
  for (const char* file : {"dem.tif", "translated.vrt"}) {
    SCOPED_TRACE(file);
    auto src = open_source(root_ / file);
    ASSERT_TRUE(src.ok()) << src.error().message;
    auto pts = read_all(**src, 4096);
    ASSERT_TRUE(pts.ok()) << pts.error().message;
    EXPECT_EQ(pts->size(), 9u);
    EXPECT_EQ((*src)->counters().rejected_nodata, 3u);
    for (const auto& p : *pts) EXPECT_GE(p.z, 400.0);
  }
}

TEST_F(RasterPolicyTest, IntegerNodataOutsideTheTypeMatchesNoCell) {
  // An Int16 band whose NODATA (70000) no cell can hold, and one whose NODATA is 401.5: GDAL's
  // mask flags nothing; a double comparison would agree here, but a rounded one must not.
  write_tif(root_ / "int.tif", 4, 3, GDT_Int16, NAN);
  write_text(
      root_ / "big_nodata.vrt",
      vrt_over("int.tif", true, 4, 3, "    <NoDataValue>70000</NoDataValue>\n", "", "Int16"));
  write_text(
      root_ / "frac_nodata.vrt",
      vrt_over("int.tif", true, 4, 3, "    <NoDataValue>401.5</NoDataValue>\n", "", "Int16"));
  write_text(root_ / "int_nodata.vrt",
             vrt_over("int.tif", true, 4, 3, "    <NoDataValue>401</NoDataValue>\n", "", "Int16"));
  for (const auto& [file, expected] :
       {std::pair{"big_nodata.vrt", 12u}, std::pair{"frac_nodata.vrt", 12u},
        std::pair{"int_nodata.vrt", 11u}}) {
    SCOPED_TRACE(file);
    auto src = open_source(root_ / file);
    ASSERT_TRUE(src.ok()) << src.error().message;
    auto pts = read_all(**src, 4096);
    ASSERT_TRUE(pts.ok()) << pts.error().message;
    EXPECT_EQ(pts->size(), expected);
  }
}

}  // namespace
}  // namespace tinstream::sources
