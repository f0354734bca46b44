// tinstream-viewer --headless on real stores (the client_stores fixture: SRTM DEM and LiDAR
// ingested by the real `tinstream ingest`), served by the real tinstream-server on 127.0.0.1 or
// read directly. The tests look at the PNG (pixel classes in regions where the layer is and where
// it is not) and at the JSON statistics.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "process.hpp"
#include "synthetic_store.hpp"
#include "tinstream/client/png.hpp"
#include "tinstream/client/render_mesh.hpp"
#include "tinstream/client/streamer.hpp"
#include "tinstream/geo/ecef.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {
namespace {

using nlohmann::json;
using testing::TempDir;

const std::filesystem::path kStores =
    std::filesystem::path(TINSTREAM_BINARY_DIR) / "tests/client/stores";

struct ViewerRun {
  int status = -1;
  json stats;                // the last JSON line of stdout
  std::vector<json> frames;  // per-frame lines of a camera path
  std::string err;
};

ViewerRun viewer(const std::vector<std::string>& args) {
  testing::Child child(testing::binary("tinstream-viewer"), args, /*capture_stderr=*/true);
  ViewerRun r;
  r.status = child.wait(std::chrono::minutes(10));
  r.err = child.err();
  std::istringstream lines(child.out());
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line.front() != '{') continue;
    json j = json::parse(line, nullptr, false);
    if (j.is_discarded()) continue;
    if (j.contains("frame"))
      r.frames.push_back(j);
    else
      r.stats = j;
  }
  return r;
}

store::LayerInfo layer_info(const std::filesystem::path& store, const std::string& name) {
  auto st = store::TileStore::open(store, store::TileStore::Mode::read_only);
  if (!st) throw std::runtime_error(st.error().message);
  auto info = st->layer(name);
  if (!info) throw std::runtime_error(info.error().message);
  return *info;
}

// Straight down over the centre of the layer's data, `height` metres above the ellipsoid.
std::string camera_above(const store::LayerInfo& l, double height, double pitch = -90) {
  std::ostringstream s;
  s.precision(12);
  s << (l.bounds.west + l.bounds.east) / 2 << ',' << (l.bounds.south + l.bounds.north) / 2 << ','
    << height << ",0," << pitch;
  return s.str();
}

// Metres from the layer's centre to its east and north edges (a sphere is close enough here).
std::pair<double, double> half_extent_m(const store::LayerInfo& l) {
  const double lat = (l.bounds.south + l.bounds.north) / 2 * M_PI / 180;
  return {(l.bounds.east - l.bounds.west) / 2 * M_PI / 180 * 6378137 * std::cos(lat),
          (l.bounds.north - l.bounds.south) / 2 * M_PI / 180 * 6378137};
}

const std::uint8_t* pixel(const Image& img, int x, int y) {
  const auto w = static_cast<std::size_t>(img.width);
  return img.rgba.data() + (static_cast<std::size_t>(y) * w + static_cast<std::size_t>(x)) * 4;
}

enum class Pixel { sky, globe, terrain };
// The globe is blue-dominant; the hypsometric ramp (greens, sand, browns, whites) never is; the
// sky is near black.
Pixel classify(const Image& img, int x, int y) {
  const std::uint8_t* p = pixel(img, x, y);
  const int r = p[0], g = p[1], b = p[2];
  if (r + g + b < 40) return Pixel::sky;
  if (b > r + 25 && b > g + 10) return Pixel::globe;
  return Pixel::terrain;
}

// Fraction of the pixels of class `c` in the box [x0, x1) × [y0, y1) (fractions of the image).
double fraction(const Image& img, Pixel c, double x0, double y0, double x1, double y1) {
  int hits = 0, total = 0;
  for (int y = static_cast<int>(y0 * img.height); y < static_cast<int>(y1 * img.height); ++y)
    for (int x = static_cast<int>(x0 * img.width); x < static_cast<int>(x1 * img.width); ++x) {
      ++total;
      hits += classify(img, x, y) == c;
    }
  return total ? static_cast<double>(hits) / total : 0;
}

double mean_luminance(const Image& img, double x0, double y0, double x1, double y1) {
  double sum = 0;
  int n = 0;
  for (int y = static_cast<int>(y0 * img.height); y < static_cast<int>(y1 * img.height); ++y)
    for (int x = static_cast<int>(x0 * img.width); x < static_cast<int>(x1 * img.width); ++x) {
      const std::uint8_t* p = pixel(img, x, y);
      sum += 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
      ++n;
    }
  return sum / n;
}

Image png(const std::filesystem::path& path) {
  auto img = read_png(path);
  if (!img) throw std::runtime_error(img.error().message);
  return *img;
}

std::vector<std::string> base_args(const std::filesystem::path& out, const std::string& camera) {
  return {"--headless", "--size", "480x270",  "--msaa", "0",     "--no-legend",
          "--timeout",  "300",    "--camera", camera,   "--out", out.string()};
}

std::vector<std::string> operator+(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

class Viewer : public ::testing::Test {
 protected:
  void SetUp() override {
    dem_ = kStores / "dem.sqlite";
    lidar_ = kStores / "lidar.sqlite";
    ASSERT_TRUE(std::filesystem::exists(dem_) && std::filesystem::exists(lidar_))
        << "the client_stores fixture did not run (tests/client/make_stores.sh)";
  }
  std::filesystem::path dem_, lidar_;
};

void expect_clean(const ViewerRun& r) {
  EXPECT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(r.stats.is_object()) << r.err;
  EXPECT_TRUE(r.stats["complete"].get<bool>());
  EXPECT_EQ(r.stats["requests"]["failed"].get<int>(), 0);
  EXPECT_EQ(r.stats["tiles"]["failed"].get<int>(), 0);
  EXPECT_EQ(r.stats["tiles"]["pending"].get<int>(), 0);
}

TEST_F(Viewer, DemIsTerrainWhereTheLayerIsAndGlobeElsewhere) {
  TempDir dir("viewer_dem");
  const store::LayerInfo l = layer_info(dem_, "dem");
  const auto [half_e, half_n] = half_extent_m(l);
  // From this height a 60° view spans 2·h·tan 30° vertically: the layer fills a known centre.
  const double height = 5 * half_n / std::tan(M_PI / 6) + l.max_z;
  const ViewerRun r = viewer(base_args(dir.path / "dem.png", camera_above(l, height)) +
                             std::vector<std::string>{"--store", dem_.string()});
  expect_clean(r);
  const Image img = png(dir.path / "dem.png");
  EXPECT_EQ(img.width, 480);
  EXPECT_EQ(img.height, 270);
  // The layer covers about ±20 % of the height and ±(half_e/half_n)·20 % of the height around
  // the centre; the middle is terrain, a frame around the border is globe.
  EXPECT_GT(fraction(img, Pixel::terrain, 0.45, 0.42, 0.55, 0.58), 0.98);
  EXPECT_GT(fraction(img, Pixel::globe, 0.0, 0.0, 1.0, 0.15), 0.98);
  EXPECT_GT(fraction(img, Pixel::globe, 0.0, 0.85, 1.0, 1.0), 0.98);
  EXPECT_GT(fraction(img, Pixel::globe, 0.0, 0.0, 0.1, 1.0), 0.98);
  EXPECT_GT(r.stats["tiles"]["drawn"].get<int>(), 0);
  EXPECT_LE(r.stats["max_sse_drawn"].get<double>(), 2.0);
}

TEST_F(Viewer, LidarIsTerrainWhereTheLayerIsAndNothingIsDrawnFarAway) {
  TempDir dir("viewer_lidar");
  const store::LayerInfo l = layer_info(lidar_, "lidar");
  const auto [half_e, half_n] = half_extent_m(l);
  const double height = 5 * half_n / std::tan(M_PI / 6) + l.max_z;
  const ViewerRun r = viewer(base_args(dir.path / "l.png", camera_above(l, height)) +
                             std::vector<std::string>{"--store", lidar_.string()});
  expect_clean(r);
  const Image img = png(dir.path / "l.png");
  EXPECT_GT(fraction(img, Pixel::terrain, 0.45, 0.42, 0.55, 0.58), 0.98);
  EXPECT_GT(fraction(img, Pixel::globe, 0.0, 0.0, 1.0, 0.15), 0.98);
  // 2000 km away the layer is not drawn at all: no terrain pixel, nothing requested beyond the
  // root tiles the horizon leaves in view.
  const ViewerRun far = viewer(base_args(dir.path / "far.png", "60,30,2000000,0,-90") +
                               std::vector<std::string>{"--store", lidar_.string()});
  expect_clean(far);
  EXPECT_EQ(far.stats["tiles"]["drawn"].get<int>(), 0);
  const Image far_img = png(dir.path / "far.png");
  EXPECT_EQ(fraction(far_img, Pixel::terrain, 0, 0, 1, 1), 0.0);
  EXPECT_GT(fraction(far_img, Pixel::globe, 0.3, 0.3, 0.7, 0.7), 0.99);
}

TEST_F(Viewer, TheWireframeChangesTheImage) {
  TempDir dir("viewer_wire");
  const store::LayerInfo l = layer_info(lidar_, "lidar");
  const std::string camera = camera_above(l, l.max_z + 150);
  const auto args = std::vector<std::string>{"--store", lidar_.string(), "--layer", "lidar"};
  const ViewerRun plain = viewer(base_args(dir.path / "plain.png", camera) + args);
  const ViewerRun wire = viewer(base_args(dir.path / "wire.png", camera) + args +
                                std::vector<std::string>{"--wireframe"});
  expect_clean(plain);
  expect_clean(wire);
  EXPECT_EQ(plain.stats["drawn_tiles"], wire.stats["drawn_tiles"]);
  const Image a = png(dir.path / "plain.png"), b = png(dir.path / "wire.png");
  int differ = 0;
  for (std::size_t i = 0; i < a.rgba.size(); i += 4)
    differ +=
        a.rgba[i] != b.rgba[i] || a.rgba[i + 1] != b.rgba[i + 1] || a.rgba[i + 2] != b.rgba[i + 2];
  EXPECT_GT(differ, static_cast<int>(a.rgba.size() / 4 / 20))
      << "fewer than 5 % of the pixels changed";
  // The edges are dark: the terrain in the middle gets darker.
  EXPECT_LT(mean_luminance(b, 0.4, 0.4, 0.6, 0.6), mean_luminance(a, 0.4, 0.4, 0.6, 0.6) - 5);
}

TEST_F(Viewer, ALowerCameraDrawsFinerLevels) {
  // The level under the image centre: tiles elsewhere follow their own errors (a tile at the
  // data's edge may carry a large one), the one looked at follows the distance.
  TempDir dir("viewer_levels");
  const store::LayerInfo l = layer_info(dem_, "dem");
  std::vector<int> levels;
  json nearest;
  // Heights for the Big Tujunga DEM's recorded errors (levels 0–5 138 m, 7–10 52 m, 12 21 m)
  // at 480×270: level 0 from 400 km, about level 7 from 8 km, about level 12 from 1.5 km.
  for (const double height : {400000.0, 8000.0, 1500.0}) {
    const ViewerRun r = viewer(base_args(dir.path / "x.png", camera_above(l, l.max_z + height)) +
                               std::vector<std::string>{"--store", dem_.string()});
    expect_clean(r);
    levels.push_back(r.stats["centre_level"].get<int>());
    EXPECT_LE(r.stats["max_sse_drawn"].get<double>(), 2.0) << height;
    nearest = r.stats;
  }
  EXPECT_GE(levels[0], 0);
  EXPECT_LT(levels[0], levels[1]);
  EXPECT_LT(levels[1], levels[2]);
  // A coarser quality knob draws coarser tiles from the same camera.
  const ViewerRun coarse =
      viewer(base_args(dir.path / "c.png", camera_above(l, l.max_z + 1500.0)) +
             std::vector<std::string>{"--store", dem_.string(), "--max-sse", "64"});
  expect_clean(coarse);
  EXPECT_LT(coarse.stats["centre_level"].get<int>(), levels[2]);
  EXPECT_LT(coarse.stats["tiles"]["triangles"].get<double>(),
            nearest["tiles"]["triangles"].get<double>());
  EXPECT_LE(coarse.stats["max_sse_drawn"].get<double>(), 64.0);
}

TEST_F(Viewer, StatisticsSayWhereTheCpuWentWhileStreaming) {
  // The CPU of a cold snapshot: the workers' decoding (CPU time beside its wall time), the render
  // thread's and the process's until the view is complete (the benchmark reads them to tell a
  // CPU-bound run from a latency-bound one). No prefetch: every decoded tile was needed, so it
  // was decoded before the view was complete. Four download workers, one decoder thread.
  TempDir dir("viewer_cpu");
  const store::LayerInfo l = layer_info(dem_, "dem");
  const ViewerRun r =
      viewer(base_args(dir.path / "cpu.png", camera_above(l, l.max_z + 8000.0)) +
             std::vector<std::string>{"--store", dem_.string(), "--threads", "4",
                                      "--decode-threads", "1", "--prefetch-levels", "0"});
  expect_clean(r);
  const json& req = r.stats["requests"];
  const json& cpu = r.stats["cpu"];
  ASSERT_TRUE(req.contains("decode_cpu_seconds")) << r.stats.dump();
  ASSERT_TRUE(cpu.is_object()) << r.stats.dump();
  const double decode_cpu = req["decode_cpu_seconds"].get<double>();
  const double decode_wall = req["decode_seconds"].get<double>();
  const double render_cpu = cpu["render_thread_s"].get<double>();
  const double process_cpu = cpu["process_s"].get<double>();
  const double to_complete = r.stats["time_to_complete_s"].get<double>();
  const int loaded = r.stats["tiles"]["loaded"].get<int>();
  ASSERT_GT(loaded, 1);
  // Each decode's CPU time is at most its wall time (the counters keep microseconds: one of
  // slack per decode).
  EXPECT_GT(decode_cpu, 0);
  EXPECT_LE(decode_cpu, decode_wall + 2e-6 * loaded);
  // The render thread is part of the process; the workers' decoding too (before complete).
  EXPECT_GT(render_cpu, 0);
  EXPECT_LE(render_cpu, process_cpu + 1e-6);
  EXPECT_LE(decode_cpu + render_cpu, process_cpu + 1e-3);
  // Four download workers, one decoder and the render thread cannot use more than six cores'
  // time (the workers mostly wait on I/O);
  // the process's other threads (llvmpipe's, the heap trimmer) are idle until the final draw.
  EXPECT_LE(process_cpu, 6.5 * to_complete + 0.05);
  // --decode-threads 1: one decoder, the payloads took turns (waiting in its queue).
  EXPECT_EQ(req["most_decoding"].get<int>(), 1);
  EXPECT_GE(req["decode_wait_seconds"].get<double>(), 0);
}

TEST_F(Viewer, StoreAndUrlDrawTheSameTilesAndPixelsFlushedOrNot) {
  TempDir dir("viewer_same");
  testing::Server server(lidar_);
  const store::LayerInfo l = layer_info(lidar_, "lidar");
  const std::string camera = camera_above(l, l.max_z + 300, -50);
  // The store's run also hands the driver every draw call on its own (a glFlush after each):
  // flushing must not change a pixel (the URL's run never flushes).
  const ViewerRun a = viewer(base_args(dir.path / "store.png", camera) +
                             std::vector<std::string>{"--store", lidar_.string(), "--layer",
                                                      "lidar", "--flush-triangles", "1"});
  const ViewerRun b = viewer(base_args(dir.path / "url.png", camera) +
                             std::vector<std::string>{"--url", server.url(), "--layer", "lidar",
                                                      "--flush-triangles", "0"});
  expect_clean(a);
  expect_clean(b);
  EXPECT_EQ(a.stats["drawn_tiles"], b.stats["drawn_tiles"]);
  EXPECT_GT(a.stats["tiles"]["flushes"].get<std::uint64_t>(), 0u);
  EXPECT_EQ(b.stats["tiles"]["flushes"].get<std::uint64_t>(), 0u);
  EXPECT_GT(a.stats["drawn_tiles"].size(), 0u);
  EXPECT_GT(b.stats["requests"]["wire_bytes"].get<double>(), 0);
  const Image x = png(dir.path / "store.png"), y = png(dir.path / "url.png");
  EXPECT_EQ(x.rgba, y.rgba);
}

TEST_F(Viewer, AWarmDiskCacheDownloadsNothingNewAndBudgetsHold) {
  TempDir dir("viewer_disk");
  testing::Server server(dem_);
  const store::LayerInfo l = layer_info(dem_, "dem");
  const std::string camera = camera_above(l, l.max_z + 20000, -60);
  const auto args = std::vector<std::string>{
      "--url",     server.url(), "--disk-cache",      (dir.path / "cache").string(),
      "--gpu-mb",  "48",         "--cache-mb",        "24",
      "--threads", "4",          "--prefetch-levels", "0"};
  // (No prefetching: which prefetched tiles a run sends before its view completes depends on
  // timing, so a warm run could ask for one the cold run dropped unsent.)
  const ViewerRun cold = viewer(base_args(dir.path / "cold.png", camera) + args);
  expect_clean(cold);
  const json& c = cold.stats;
  // (With these budgets a tile may leave both RAM and GPU and come back from the disk tier, 304,
  // even in the cold run.)
  EXPECT_GT(c["requests"]["downloaded_bytes"].get<double>(), 0);
  EXPECT_GT(c["requests"]["ok"].get<int>(), 0);
  const ViewerRun warm = viewer(base_args(dir.path / "warm.png", camera) + args);
  expect_clean(warm);
  const json& w = warm.stats;
  EXPECT_EQ(w["requests"]["downloaded_bytes"].get<double>(), 0);
  EXPECT_EQ(w["requests"]["ok"].get<int>(), 0);
  EXPECT_EQ(w["requests"]["not_modified"].get<int>(), w["tiles"]["loaded"].get<int>());
  EXPECT_EQ(w["cache"]["disk"]["hits"].get<int>(), w["tiles"]["loaded"].get<int>());
  EXPECT_EQ(w["drawn_tiles"], c["drawn_tiles"]);
  EXPECT_EQ(png(dir.path / "cold.png").rgba, png(dir.path / "warm.png").rgba);
  // Every tier kept its budget, within one tile.
  for (const json* s : {&c, &w})
    for (const char* tier : {"gpu", "ram", "disk"}) {
      const json& t = (*s)["cache"][tier];
      EXPECT_LE(t["peak_bytes"].get<double>(),
                t["budget"].get<double>() + t["largest_entry"].get<double>())
          << tier;
    }
}

TEST_F(Viewer, SmallBudgetsEvictDuringAFlightAndHold) {
  TempDir dir("viewer_flight");
  const store::LayerInfo l = layer_info(dem_, "dem");
  const double lon0 = l.bounds.west + 0.25 * (l.bounds.east - l.bounds.west);
  const double lon1 = l.bounds.west + 0.75 * (l.bounds.east - l.bounds.west);
  const double lat = (l.bounds.south + l.bounds.north) / 2;
  // Two views 18 km apart, straight down from 4 km at 960×540: each needs 2.0 / 2.4 MB of GPU
  // buffers and 4.0 / 3.7 MB of decoded tiles (the coarse ancestors they share included), both
  // together 4.4 and 7.7 MB (measured on the Big Tujunga store as the lod of 2026-11-28 makes
  // it, coarse tiles no denser than their level can show; the largest tile 0.66 MB): 3 MiB of
  // GPU and 5 MiB of RAM hold one view, not both.
  std::ofstream(dir.path / "path.txt")
      << "0 " << lon0 << "," << lat << ",4000,0,-90\nwait complete\n"
      << "1 " << lon1 << "," << lat << ",4000,0,-90\nwait complete\n";
  const ViewerRun r =
      viewer({"--headless", "--size", "960x540", "--msaa", "0", "--no-legend", "--store",
              dem_.string(), "--camera-path", (dir.path / "path.txt").string(), "--fps", "10",
              "--timeout", "300", "--gpu-mb", "3", "--cache-mb", "5"});
  EXPECT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(r.stats.is_object());
  ASSERT_GT(r.frames.size(), 3u);
  EXPECT_TRUE(r.frames.back()["complete"].get<bool>());
  for (const char* tier : {"gpu", "ram"}) {
    const json& t = r.stats["cache"][tier];
    EXPECT_GT(t["evictions"].get<int>(), 0) << tier;
    EXPECT_LE(t["peak_bytes"].get<double>(),
              t["budget"].get<double>() + t["largest_entry"].get<double>())
        << tier;
  }
  EXPECT_EQ(r.stats["requests"]["failed"].get<int>(), 0);
}

TEST_F(Viewer, SphericalAndEllipsoidalLayersLandInTheSamePlace) {
  TempDir dir("viewer_ell");
  const store::LayerInfo l = layer_info(lidar_, "lidar");
  const std::string camera = camera_above(l, l.max_z + 400, -70);
  const ViewerRun s = viewer(base_args(dir.path / "s.png", camera) +
                             std::vector<std::string>{"--store", lidar_.string(), "--layer",
                                                      "lidar", "--ramp", "120,135"});
  const ViewerRun e = viewer(base_args(dir.path / "e.png", camera) +
                             std::vector<std::string>{"--store", lidar_.string(), "--layer",
                                                      "lidar_ell", "--ramp", "120,135"});
  expect_clean(s);
  expect_clean(e);
  const Image a = png(dir.path / "s.png"), b = png(dir.path / "e.png");
  int same = 0, terrain = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      terrain += classify(a, x, y) == Pixel::terrain;
      same += classify(a, x, y) == classify(b, x, y);
    }
  EXPECT_GT(terrain, a.width * a.height / 10);
  EXPECT_GT(same, static_cast<int>(0.995 * a.width * a.height));
}

TEST_F(Viewer, LogarithmicDepthDrawsTheSameScene) {
  TempDir dir("viewer_logz");
  const store::LayerInfo l = layer_info(lidar_, "lidar");
  const std::string camera = camera_above(l, l.max_z + 250, -45);
  const ViewerRun a =
      viewer(base_args(dir.path / "a.png", camera) +
             std::vector<std::string>{"--store", lidar_.string(), "--layer", "lidar"});
  const ViewerRun b = viewer(
      base_args(dir.path / "b.png", camera) +
      std::vector<std::string>{"--store", lidar_.string(), "--layer", "lidar", "--log-depth"});
  expect_clean(a);
  expect_clean(b);
  EXPECT_NE(b.stats["renderer"].get<std::string>().find("log depth"), std::string::npos);
  const Image x = png(dir.path / "a.png"), y = png(dir.path / "b.png");
  int close = 0;
  for (std::size_t i = 0; i < x.rgba.size(); i += 4)
    close += std::abs(x.rgba[i] - y.rgba[i]) + std::abs(x.rgba[i + 1] - y.rgba[i + 1]) +
                 std::abs(x.rgba[i + 2] - y.rgba[i + 2]) <=
             12;
  EXPECT_GT(close, static_cast<int>(0.99 * x.width * x.height));
}

// Calls visit(name, layer, tile, its render mesh) for every tile of the DEM and LiDAR layers.
template <typename Visit>
void for_each_real_tile(const std::filesystem::path& dem, const std::filesystem::path& lidar,
                        const Visit& visit) {
  for (const auto& [path, name] :
       {std::pair{dem, "dem"}, std::pair{lidar, "lidar"}, std::pair{lidar, "lidar_ell"}}) {
    auto st = store::TileStore::open(path, store::TileStore::Mode::read_only);
    ASSERT_TRUE(st.ok());
    const LayerDescription layer = from_store_info(*st->layer(name));
    auto ids = st->tile_ids(name);
    ASSERT_TRUE(ids.ok());
    for (const geo::TileId& id : *ids) {
      auto t = st->read_tile(name, id);
      ASSERT_TRUE(t.ok() && t->has_value());
      visit(std::string(name), layer, **t,
            build_render_mesh(**t, layer, {TileKind::terrain, 0, id}));
    }
  }
}

// Where the image row of a point lies, by a pinhole camera written out here (not the client's):
// heading 0 (north), pitch p, vertical field of view fov, rows top to bottom.
struct Pinhole {
  Vec3 eye, forward, up;
  double rows, fov_y;
  Pinhole(double lon, double lat, double h, double pitch_deg, double fov_deg, int image_rows)
      : rows(image_rows), fov_y(fov_deg * M_PI / 180) {
    const double l = lon * M_PI / 180, f = lat * M_PI / 180, p = pitch_deg * M_PI / 180;
    const geo::Ecef e = geo::to_ecef({lon, lat, h});
    eye = {e.x, e.y, e.z};
    const Vec3 east{-std::sin(l), std::cos(l), 0};
    const Vec3 north{-std::sin(f) * std::cos(l), -std::sin(f) * std::sin(l), std::cos(f)};
    const Vec3 vertical{std::cos(f) * std::cos(l), std::cos(f) * std::sin(l), std::sin(f)};
    forward = north * std::cos(p) + vertical * std::sin(p);
    up = cross(east, forward);
  }
  // nullopt behind the camera.
  std::optional<double> row(const Vec3& point) const {
    const Vec3 v = point - eye;
    const double z = dot(v, forward);
    if (z <= 0) return std::nullopt;
    return rows / 2 - dot(v, up) / z * (rows / 2) / std::tan(fov_y / 2);
  }
};

TEST_F(Viewer, NoCurtainHangsFromTheDataEdgeSeenFromALowAngle) {
  // From 2 km south of the DEM's data, 1500 m up, looking north 12° down (1 px quality): the data's
  // south edge crosses the view. In each image column, no terrain may appear below the lowest row
  // that a data triangle of a drawn tile reaches there (a triangle's image lies within its
  // vertices' rows and columns; projected here by a pinhole camera of our own): below it, only the
  // globe. Skirts hung along the data's edge (down by the errors, hundreds of metres) were
  // terrain-coloured curtains reaching below it (skirts on every side as before fail this: 73 of
  // 480 columns on the store of 2026-11-27 09:05; 16 with 7 km and 2500 m on the older store).
  TempDir dir("viewer_edge");
  const store::LayerInfo l = layer_info(dem_, "dem");
  const double lon = (l.bounds.west + l.bounds.east) / 2, lat = l.bounds.south - 0.02;
  const double height = 1500, pitch = -12;
  std::ostringstream camera;
  camera.precision(12);
  camera << lon << ',' << lat << ',' << height << ",0," << pitch;
  const ViewerRun r = viewer(base_args(dir.path / "edge.png", camera.str()) +
                             std::vector<std::string>{"--store", dem_.string(), "--max-sse", "1"});
  expect_clean(r);
  const Image img = png(dir.path / "edge.png");
  const Pinhole pinhole(lon, lat, height, pitch, 60, img.height);
  const double focal = img.height / 2.0 / std::tan(M_PI / 6);

  auto st = store::TileStore::open(dem_, store::TileStore::Mode::read_only);
  ASSERT_TRUE(st.ok());
  const geo::NormalisedMercator merc(l.projection);
  std::vector<double> lowest(static_cast<std::size_t>(img.width), -1e9);  // per column
  for (const json& drawn : r.stats["drawn_tiles"]) {
    const std::string name = drawn.get<std::string>();  // "dem/QUADKEY:MASK"
    auto id = geo::TileId::from_quadkey(name.substr(4, name.find(':') - 4));
    ASSERT_TRUE(id.ok()) << name;
    auto t = st->read_tile("dem", *id);
    ASSERT_TRUE(t.ok() && t->has_value()) << name;
    const tile::TinTile& tile = **t;
    const auto all = tile.vertices();
    std::vector<std::optional<std::pair<double, double>>> at(all.size());  // (column, row)
    for (std::size_t i = 0; i < all.size(); ++i) {
      const geo::LonLat ll = merc.inverse({all[i].x, all[i].y});
      const geo::Ecef e = geo::to_ecef({ll.lon, ll.lat, all[i].z});
      const Vec3 v = Vec3{e.x, e.y, e.z} - pinhole.eye;
      const double z = dot(v, pinhole.forward);
      if (z <= 0) continue;
      const Vec3 right = cross(pinhole.forward, pinhole.up);
      at[i] = {img.width / 2.0 + dot(v, right) / z * focal, *pinhole.row(Vec3{e.x, e.y, e.z})};
    }
    for (std::size_t k = 0; k < tile.triangles.size(); ++k) {
      if (tile.is_nodata_triangle(k)) continue;
      const tile::Triangle& tri = tile.triangles[k];
      if (!at[tri[0]] || !at[tri[1]] || !at[tri[2]]) continue;
      double c0 = 1e9, c1 = -1e9, row = -1e9;
      for (const std::uint32_t v : tri) {
        c0 = std::min(c0, at[v]->first);
        c1 = std::max(c1, at[v]->first);
        row = std::max(row, at[v]->second);
      }
      for (int c = std::max(0, static_cast<int>(std::floor(c0)) - 1);
           c <= std::min(img.width - 1, static_cast<int>(std::ceil(c1)) + 1); ++c)
        lowest[static_cast<std::size_t>(c)] = std::max(lowest[static_cast<std::size_t>(c)], row);
    }
  }
  // Two rows of slack for rasterisation; below, only globe. A skirt between two tiles of
  // different levels may still show as a thin fin where that border meets the data's edge
  // (seen from outside, under the surface: at most the two tiles' errors deep): a few columns;
  // a curtain along the edge fills most of them.
  int columns_with_terrain_below = 0, below = 0, edge_columns = 0;
  for (int x = 0; x < img.width; ++x) {
    const double edge = lowest[static_cast<std::size_t>(x)];
    if (edge < 0.3 * img.height || edge > 0.8 * img.height) continue;  // the edge is not here
    ++edge_columns;
    bool terrain = false;
    for (int y = static_cast<int>(std::ceil(edge)) + 2; y < img.height; ++y) {
      ++below;
      terrain |= classify(img, x, y) != Pixel::globe;
    }
    columns_with_terrain_below += terrain;
  }
  // The data's edge crosses most of the picture, with room below it.
  EXPECT_GT(edge_columns, img.width / 2);
  EXPECT_GT(below, img.width * 40);
  EXPECT_LE(columns_with_terrain_below, edge_columns / 100)
      << "of " << edge_columns << " columns, terrain below the data's edge";
}

TEST_F(Viewer, SkirtsOfRealTilesLieUnderFootprintBorderSegmentsOnly) {
  // Every tile of both stores: each side's skirt quads are exactly the border segments on that
  // side that are an edge of a data (footprint) triangle, counted here from the tile's
  // coordinates (a segment lies on the north side when both ends have y == the tile's max_y).
  std::size_t tiles = 0, segments = 0, nodata_tiles = 0;
  const auto check = [&](const std::string& name, const LayerDescription&,
                         const tile::TinTile& tile, const TileMesh& mesh) {
    const geo::TileId& id = tile.id;
    const geo::MercatorRect r = id.bounds();
    const auto all = tile.vertices();
    std::array<std::set<std::pair<std::uint32_t, std::uint32_t>>, 4> on_side;
    for (std::size_t k = 0; k < tile.triangles.size(); ++k) {
      const tile::Triangle& tri = tile.triangles[k];
      const bool data = !tile.is_nodata_vertex(tri[0]) && !tile.is_nodata_vertex(tri[1]) &&
                        !tile.is_nodata_vertex(tri[2]);
      if (!data) continue;
      for (int e = 0; e < 3; ++e) {
        const std::uint32_t a = tri[static_cast<std::size_t>(e)],
                            b = tri[static_cast<std::size_t>((e + 1) % 3)];
        const tile::Vertex &p = all[a], &q = all[b];
        const std::pair key{std::min(a, b), std::max(a, b)};
        if (p.y == r.max_y && q.y == r.max_y) on_side[0].insert(key);
        if (p.x == r.max_x && q.x == r.max_x) on_side[1].insert(key);
        if (p.y == r.min_y && q.y == r.min_y) on_side[2].insert(key);
        if (p.x == r.min_x && q.x == r.min_x) on_side[3].insert(key);
      }
    }
    for (std::size_t s = 0; s < 4; ++s) {
      EXPECT_EQ(mesh.skirt_index_count[s], 6 * on_side[s].size())
          << name << " " << id.to_string() << " side " << s;
      segments += on_side[s].size();
    }
    nodata_tiles += tile.has_nodata_triangles();
    ++tiles;
  };

  for_each_real_tile(dem_, lidar_, check);
  EXPECT_GT(tiles, 50u);
  EXPECT_GT(nodata_tiles, 5u);  // tiles at the data's edge are among them
  EXPECT_GT(segments, 1000u);
}

TEST_F(Viewer, BadInputGetsAClearErrorAndStatus2) {
  const auto expect_error = [](const std::vector<std::string>& args, const std::string& says) {
    const ViewerRun r = viewer(std::vector<std::string>{"--headless", "--timeout", "30"} + args);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
  };
  expect_error({"--store", "/nonexistent/x.sqlite"}, "does not exist");
  expect_error({"--store", lidar_.string(), "--layer", "nope"}, "nope");
  expect_error(
      {"--url", "http://127.0.0.1:" + std::to_string(testing::closed_port()), "--retries", "1"},
      "cannot connect");
  expect_error({"--store", lidar_.string(), "--camera", "1,2"}, "camera");
  expect_error({"--store", lidar_.string(), "--size", "12by4"}, "--size");
  expect_error({}, "tile source");
}

TEST_F(Viewer, BoundingVolumesHoldEveryVertexOfRealTiles) {
  // Every tile of both stores: the loaded tile's fitted box, the box used before it is loaded
  // (rectangle clipped to the data, layer heights), and the exact ECEF box of its rectangle with
  // its own heights all contain every vertex it draws, computed here through GeographicLib.
  std::size_t tiles = 0, vertices = 0;
  for (const auto& [path, name] :
       {std::pair{dem_, "dem"}, std::pair{lidar_, "lidar"}, std::pair{lidar_, "lidar_ell"}}) {
    auto st = store::TileStore::open(path, store::TileStore::Mode::read_only);
    ASSERT_TRUE(st.ok());
    const LayerDescription layer = from_store_info(*st->layer(name));
    const geo::NormalisedMercator merc(layer.projection);
    auto ids = st->tile_ids(name);
    ASSERT_TRUE(ids.ok());
    for (const geo::TileId& id : *ids) {
      auto t = st->read_tile(name, id);
      ASSERT_TRUE(t.ok() && t->has_value());
      const tile::TinTile& tile = **t;
      const TileMesh mesh = build_render_mesh(tile, layer, {TileKind::terrain, 0, id});
      const Obb before = unloaded_tile_bounds(layer, id);
      const Aabb exact = rectangle_aabb(id.lonlat_bounds(merc), tile.min_z, tile.max_z);
      const auto all = tile.vertices();
      std::vector<bool> drawn(all.size(), false);
      for (std::size_t k = 0; k < tile.triangles.size(); ++k)
        if (!tile.is_nodata_triangle(k))
          for (std::uint32_t v : tile.triangles[k]) drawn[v] = true;
      for (std::size_t i = 0; i < all.size(); ++i) {
        if (!drawn[i]) continue;
        const geo::LonLat ll = merc.inverse({all[i].x, all[i].y});
        const geo::Ecef e = geo::to_ecef({ll.lon, ll.lat, all[i].z});
        const Vec3 p{e.x, e.y, e.z};
        ASSERT_TRUE(mesh.bounds.contains(p)) << name << " " << id.to_string() << " vertex " << i;
        ASSERT_TRUE(before.contains(p)) << name << " " << id.to_string() << " vertex " << i;
        ASSERT_TRUE(exact.contains(p)) << name << " " << id.to_string() << " vertex " << i;
        ++vertices;
      }
      ++tiles;
    }
  }
  EXPECT_GT(tiles, 50u);
  EXPECT_GT(vertices, 100000u);
}

// Window mode runs under a virtual X server: xvfb-run, from Debian's xvfb.
constexpr const char* kXvfbRun = "/usr/bin/xvfb-run";
constexpr const char* kNoXvfbRun =
    "xvfb-run is not installed (scripts/install-deps.sh installs xvfb)";

bool xvfb_run_installed() { return std::filesystem::exists(kXvfbRun); }

struct WindowRun {
  int status = -1;  // Child::wait's
  std::string out, err;
};

// tinstream-viewer in window mode with `args` under xvfb-run on a screen of `screen` (WxH, 24
// bits), waited for (up to `limit`).
WindowRun window_under_xvfb(const std::string& screen, const std::vector<std::string>& args,
                            std::chrono::milliseconds limit) {
  testing::Child window(kXvfbRun,
                        std::vector<std::string>{"-a", "-s", "-screen 0 " + screen + "x24",
                                                 testing::binary("tinstream-viewer")} +
                            args,
                        /*capture_stderr=*/true);
  WindowRun r;
  r.status = window.wait(limit);
  r.out = window.out();
  r.err = window.err();
  return r;
}

// The value under `key` of the last line of `out` that is a JSON object holding it; null if none.
json last_json_line_with(const std::string& out, const std::string& key) {
  json value;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    const json j = json::parse(line, nullptr, false);
    if (!j.is_discarded() && j.is_object() && j.contains(key)) value = j[key];
  }
  return value;
}

TEST_F(Viewer, WindowModeOutWritesTheWindowPanelIncludedUnderXvfb) {
  // Window mode (GLFW, GLX on Mesa) under a virtual X server (xvfb-run, Debian's xvfb): --out
  // writes the window once the view is complete, panel included, and exits 0. Right of the panel
  // it shows what the headless renderer draws for the same camera; at the top left, the panel,
  // which the headless image does not have.
  if (!xvfb_run_installed()) GTEST_SKIP() << kNoXvfbRun;
  TempDir dir("viewer_window");
  const store::LayerInfo l = layer_info(dem_, "dem");
  const std::vector<std::string> view{"--size",  "960x540",     "--msaa",
                                      "0",       "--no-legend", "--timeout",
                                      "300",     "--camera",    camera_above(l, 30000),
                                      "--store", dem_.string()};
  const WindowRun window = window_under_xvfb(
      "1280x720", view + std::vector<std::string>{"--out", (dir.path / "w.png").string()},
      std::chrono::minutes(10));
  ASSERT_EQ(window.status, 0) << window.err;
  const ViewerRun headless =
      viewer(std::vector<std::string>{"--headless", "--out", (dir.path / "h.png").string()} + view);
  expect_clean(headless);
  const Image w = png(dir.path / "w.png"), h = png(dir.path / "h.png");
  ASSERT_EQ(w.width, 960);
  ASSERT_EQ(w.height, 540);
  ASSERT_EQ(h.width, w.width);
  ASSERT_EQ(h.height, w.height);
  const auto differs = [&](int x, int y) {
    const std::uint8_t *a = pixel(w, x, y), *b = pixel(h, x, y);
    return std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]) > 12;
  };
  int right = 0, right_same = 0, terrain = 0;
  for (int y = 0; y < w.height; ++y)
    for (int x = 3 * w.width / 5; x < w.width; ++x) {
      ++right;
      right_same += !differs(x, y);
      terrain += classify(w, x, y) == Pixel::terrain;
    }
  EXPECT_GT(right_same, right * 98 / 100);
  EXPECT_GT(terrain, right / 10);
  int panel = 0, panel_differs = 0;
  for (int y = 10; y < 90; ++y)
    for (int x = 10; x < 300; ++x) {
      ++panel;
      panel_differs += differs(x, y);
    }
  EXPECT_GT(panel_differs, panel / 2);
}

TEST_F(Viewer, WindowModeDrawsNothingWhileNothingChangesUnderXvfb) {
  // Window mode redraws on demand (client/include/tinstream/client/redraw.hpp): once the view is
  // complete and nothing moves, the window blocks in glfwWaitEvents and draws no frame. Under a
  // virtual X server, with no input at all, the view streams in (tiles landing wake the loop)
  // and then the window stays idle until --close-after; it reports the frames it drew and the
  // time since the last one. Drawing every frame (as before #17's fourth session) leaves no
  // time since the last frame.
  if (!xvfb_run_installed()) GTEST_SKIP() << kNoXvfbRun;
  const store::LayerInfo l = layer_info(dem_, "dem");
  const double open_s = 12;
  const WindowRun window =
      window_under_xvfb("1280x720",
                        {"--size", "640x360", "--msaa", "0", "--camera", camera_above(l, 30000),
                         "--store", dem_.string(), "--close-after", std::to_string(open_s)},
                        std::chrono::minutes(5));
  ASSERT_EQ(window.status, 0) << window.err;
  const json run = last_json_line_with(window.out, "window");
  ASSERT_TRUE(run.is_object()) << "no window line in: " << window.out << window.err;
  EXPECT_TRUE(run["complete"].get<bool>()) << run.dump();
  EXPECT_GE(run["seconds"].get<double>(), open_s) << run.dump();
  EXPECT_GE(run["frames"].get<std::uint64_t>(), 2u) << run.dump();
  // The view of this store completes in well under a second headless; the window then drew
  // nothing for at least the last third of its time.
  EXPECT_GE(run["since_last_frame_s"].get<double>(), open_s / 3) << run.dump();
}

// A rectangle of window mode's layout line: x, y, width, height in window units.
struct Rect {
  double x = 0, y = 0, w = 0, h = 0;
};

Rect rect_of(const json& j) {
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>(),
          j.at(3).get<double>()};
}

bool within(const Rect& inner, const Rect& outer) {
  return inner.x >= outer.x && inner.y >= outer.y && inner.x + inner.w <= outer.x + outer.w &&
         inner.y + inner.h <= outer.y + outer.h;
}

bool intersect(const Rect& a, const Rect& b) {
  return a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
}

bool covers(const Rect& r, int x, int y, double margin) {
  return x >= r.x - margin && x < r.x + r.w + margin && y >= r.y - margin && y < r.y + r.h + margin;
}

std::ostream& operator<<(std::ostream& os, const Rect& r) {
  return os << '[' << r.x << ", " << r.y << ", " << r.w << " x " << r.h << ']';
}

TEST_F(Viewer, WindowModeLayoutKeepsPanelAndLegendInsideTheWindowAndApart) {
  // Window mode with the legend under xvfb-run at 640×360 (where the panel, sized for larger
  // windows, once ran off the bottom and over the legend) and at 1280×720. --out prints the
  // written frame's layout: the panel, the source line in it and the legend, as ImGui placed
  // them. The panel and the legend lie inside the window and apart; the source line (a store
  // path longer than the panel is wide) wraps inside the panel. The rectangles are checked
  // against the image: outside them the window shows what the headless renderer draws without
  // a legend, inside them it does not.
  if (!xvfb_run_installed()) GTEST_SKIP() << kNoXvfbRun;
  TempDir dir("viewer_layout");
  const std::filesystem::path store =
      dir.path / std::string(90, 'd') / "a_store_path_far_longer_than_the_panel_is_wide.sqlite";
  std::filesystem::create_directories(store.parent_path());
  std::filesystem::create_symlink(dem_, store);
  const store::LayerInfo l = layer_info(dem_, "dem");
  for (const auto& [width, height] : {std::pair{640, 360}, std::pair{1280, 720}}) {
    const std::string size = std::to_string(width) + "x" + std::to_string(height);
    SCOPED_TRACE(size);
    const std::vector<std::string> view{
        "--size",  size,           "--msaa",    "0",  "--camera", camera_above(l, 30000),
        "--store", store.string(), "--timeout", "300"};
    const std::filesystem::path shot = dir.path / (size + "_window.png");
    const WindowRun window =
        window_under_xvfb("1920x1080", view + std::vector<std::string>{"--out", shot.string()},
                          std::chrono::minutes(10));
    ASSERT_EQ(window.status, 0) << window.err;
    const json layout = last_json_line_with(window.out, "layout");
    ASSERT_TRUE(layout.is_object()) << "no layout line in: " << window.out;
    ASSERT_EQ(layout["window"], json::array({width, height}));
    const Rect screen{0, 0, static_cast<double>(width), static_cast<double>(height)};
    const Rect panel = rect_of(layout["panel"]), legend = rect_of(layout["legend"]);
    const Rect source = rect_of(layout["source_line"]);
    EXPECT_TRUE(within(panel, screen)) << "panel " << panel;
    EXPECT_TRUE(within(legend, screen)) << "legend " << legend;
    EXPECT_FALSE(intersect(panel, legend)) << "panel " << panel << ", legend " << legend;
    EXPECT_TRUE(within(source, panel)) << "source line " << source << ", panel " << panel;
    // ImGui's default font is 13 px high: more than one line.
    EXPECT_GT(source.h, 1.5 * 13.0) << "the source line did not wrap: " << source;

    const ViewerRun headless =
        viewer(std::vector<std::string>{"--headless", "--no-legend", "--out",
                                        (dir.path / (size + "_headless.png")).string()} +
               view);
    expect_clean(headless);
    const Image w = png(shot), h = png(dir.path / (size + "_headless.png"));
    ASSERT_EQ(w.width, width);
    ASSERT_EQ(w.height, height);
    ASSERT_EQ(h.width, width);
    ASSERT_EQ(h.height, height);
    const auto differs = [&](int x, int y) {
      const std::uint8_t *a = pixel(w, x, y), *b = pixel(h, x, y);
      return std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]) > 12;
    };
    int outside = 0, outside_differs = 0, in_panel = 0, panel_differs = 0, in_legend = 0,
        legend_differs = 0;
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        if (covers(panel, x, y, -2)) {
          ++in_panel;
          panel_differs += differs(x, y);
        } else if (covers(legend, x, y, -2)) {
          ++in_legend;
          legend_differs += differs(x, y);
        } else if (!covers(panel, x, y, 2) && !covers(legend, x, y, 2)) {
          ++outside;
          outside_differs += differs(x, y);
        }
      }
    EXPECT_LT(outside_differs, outside / 50) << "drawn outside the reported rectangles";
    EXPECT_GT(panel_differs, in_panel / 2);
    EXPECT_GT(legend_differs, in_legend / 4);
  }
}

}  // namespace
}  // namespace tinstream::client
