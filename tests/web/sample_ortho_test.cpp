// `tinstream sample --ortho`: the demo's imagery. The real CLI writes a LAS and its orthophoto;
// the GeoTIFF must be georeferenced over the points (EPSG:32632, the LAS's square), be a real
// picture (many colours), show the mountains where the points put them (the highest points'
// pixels brighter than the lowest: snow over forest), become imagery tiles with ingest-imagery,
// and bad options must be refused with a message naming them.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "tinstream/store/tile_store.hpp"

namespace tinstream {
namespace {

namespace fs = std::filesystem;

const fs::path kCli = fs::path(TINSTREAM_BINARY_DIR) / "bin" / "tinstream";

// A fresh folder under the build tree, removed with its contents.
struct TempDir {
  explicit TempDir(const std::string& name)
      : path(fs::path(TINSTREAM_BINARY_DIR) / "test-tmp" /
             (name + "-" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  fs::path path;
};

struct CliResult {
  int status = -1;
  std::string output;  // stdout and stderr together
};

// Runs the CLI through the shell (arguments are test-made paths and numbers, single-quoted).
CliResult cli(const std::vector<std::string>& args) {
  std::string command = "'" + kCli.string() + "'";
  for (const auto& a : args) command += " '" + a + "'";
  command += " 2>&1";
  CliResult r;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

struct LasPoint {
  double x, y, z;
};

// The points of a LAS 1.2 point-format-0 file, read from its bytes (header fields by offset).
std::vector<LasPoint> read_las(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto field = [&](std::size_t offset, auto value) {
    std::memcpy(&value, bytes.data() + offset, sizeof value);
    return value;
  };
  const auto data = field(96, std::uint32_t{});
  const auto count = field(107, std::uint32_t{});
  const std::array<double, 3> scale = {field(131, 0.0), field(139, 0.0), field(147, 0.0)};
  const std::array<double, 3> offset = {field(155, 0.0), field(163, 0.0), field(171, 0.0)};
  std::vector<LasPoint> points;
  for (std::uint32_t k = 0; k < count; ++k) {
    const std::size_t at = data + std::size_t{k} * 20;
    points.push_back({field(at, std::int32_t{}) * scale[0] + offset[0],
                      field(at + 4, std::int32_t{}) * scale[1] + offset[1],
                      field(at + 8, std::int32_t{}) * scale[2] + offset[2]});
  }
  return points;
}

TEST(SampleOrtho, IsTheImageryOfTheSamplesMountains) {
  TempDir dir("sample-ortho");
  const fs::path las = dir.path / "sample.las", tif = dir.path / "ortho.tif";
  const CliResult made = cli({"sample", "--out", las.string(), "--points", "20000", "--density",
                              "0.002", "--ortho", tif.string(), "--ortho-pixel", "20"});
  ASSERT_EQ(made.status, 0) << made.output;
  EXPECT_NE(made.output.find("orthophoto"), std::string::npos) << made.output;
  const auto points = read_las(las);
  ASSERT_EQ(points.size(), 20000u);

  GDALAllRegister();
  auto* ds = static_cast<GDALDataset*>(GDALOpen(tif.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  ASSERT_EQ(ds->GetRasterCount(), 3);
  ASSERT_EQ(ds->GetRasterBand(1)->GetRasterDataType(), GDT_Byte);
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  ASSERT_NE(srs, nullptr);
  EXPECT_STREQ(srs->GetAuthorityCode(nullptr), "32632");
  std::array<double, 6> gt{};
  ASSERT_EQ(ds->GetGeoTransform(gt.data()), CE_None);
  EXPECT_EQ(gt[1], 20.0);
  EXPECT_EQ(gt[5], -20.0);
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  // Every point lies on the picture (the LAS square, sqrt(20000 / 0.002) ≈ 3162 m a side).
  EXPECT_EQ(w, 159);
  EXPECT_EQ(h, 159);
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
  ASSERT_EQ(ds->RasterIO(GF_Read, 0, 0, w, h, rgb.data(), w, h, GDT_Byte, 3, nullptr, 3,
                         static_cast<GSpacing>(w) * 3, 1, nullptr),
            CE_None);
  GDALClose(ds);
  std::set<std::uint32_t> colours;
  for (std::size_t k = 0; k < rgb.size(); k += 3) {
    colours.insert(static_cast<std::uint32_t>(rgb[k] << 16 | rgb[k + 1] << 8 | rgb[k + 2]));
  }
  EXPECT_GT(colours.size(), 2000u);

  // The brightness of the pixel under each point; the top 5 % of the points by height against
  // the bottom 5 %.
  std::vector<std::pair<double, int>> by_height;
  for (const auto& p : points) {
    const auto i = static_cast<int>((p.x - gt[0]) / gt[1]);
    const auto j = static_cast<int>((p.y - gt[3]) / gt[5]);
    ASSERT_TRUE(i >= 0 && i < w && j >= 0 && j < h) << p.x << "," << p.y;
    const std::uint8_t* c = &rgb[(static_cast<std::size_t>(j) * static_cast<std::size_t>(w) +
                                  static_cast<std::size_t>(i)) *
                                 3];
    by_height.emplace_back(p.z, c[0] + c[1] + c[2]);
  }
  std::sort(by_height.begin(), by_height.end());
  const std::size_t tail = by_height.size() / 20;
  long low = 0, high = 0;
  for (std::size_t k = 0; k < tail; ++k) {
    low += by_height[k].second;
    high += by_height[by_height.size() - 1 - k].second;
  }
  const auto mean = [&](long sum) { return static_cast<double>(sum) / static_cast<double>(tail); };
  EXPECT_GT(mean(high), mean(low) + 60) << "low " << mean(low) << ", high " << mean(high);

  // ingest-imagery takes it: an imagery layer of the sample's name, tiles at its native level.
  const fs::path store = dir.path / "demo.sqlite";
  const CliResult ingested = cli({"ingest-imagery", "--quiet", "--store", store.string(), "--layer",
                                  "sample", "--format", "jpeg", tif.string()});
  ASSERT_EQ(ingested.status, 0) << ingested.output;
  auto st = store::TileStore::open(store, store::TileStore::Mode::read_only);
  ASSERT_TRUE(st.ok()) << st.error().message;
  auto layer = st->imagery_layer("sample");
  ASSERT_TRUE(layer.ok()) << layer.error().message;
  EXPECT_GT(layer->tile_count, 1u);
  EXPECT_EQ(layer->format, "jpeg");
}

TEST(SampleOrtho, BadOptionsAreRefusedNamingThem) {
  TempDir dir("sample-ortho-bad");
  const fs::path las = dir.path / "s.las";
  const CliResult tiny = cli({"sample", "--out", las.string(), "--points", "100", "--ortho",
                              (dir.path / "o.tif").string(), "--ortho-pixel", "0"});
  EXPECT_EQ(tiny.status, 2) << tiny.output;
  EXPECT_NE(tiny.output.find("--ortho-pixel"), std::string::npos) << tiny.output;
  EXPECT_FALSE(fs::exists(dir.path / "o.tif"));
  const CliResult nowhere = cli({"sample", "--out", las.string(), "--points", "100", "--ortho",
                                 (dir.path / "missing" / "o.tif").string()});
  EXPECT_EQ(nowhere.status, 1) << nowhere.output;
  EXPECT_NE(nowhere.output.find("missing/o.tif"), std::string::npos) << nowhere.output;
}

}  // namespace
}  // namespace tinstream
