// tinstream-viewer --imagery (issue #19): a generated store with a terrain layer and an imagery
// layer of a known colour pattern, rendered headless (EGL on Mesa) from the store and from the
// real tinstream-server on 127.0.0.1; the pixels over known ground points must have the pattern's
// colours. The pattern: the ground is cut into level-13 tiles (the quadrants of level-12 tiles);
// each cell's colour says which cell it is (its quadrant in its level-12 tile and that tile's
// parity) and which imagery level it came from. So a pixel tells whether the right imagery tile
// was drawn, at the right place, and from which level (the same quadkey or an ancestor).
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <thread>

#include "offscreen_renderer.hpp"
#include "process.hpp"
#include "synthetic_store.hpp"
#include "tinstream/client/png.hpp"
#include "tinstream/client/viewer.hpp"
#include "tinstream/imagery/image.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {
namespace {

using nlohmann::json;
using testing::TempDir;

constexpr std::uint32_t kCellLevel = 13;
constexpr std::uint32_t kSize = 256;  // imagery tile side
// The terrain tile under the camera: inside default_layer()'s 4×4 block of level-12 tiles.
const geo::TileId kTile{12, 2121, 1401};

// The colour of level-13 cell (cx, cy) in an imagery tile of level `level`.
std::array<std::uint8_t, 3> cell_colour(std::uint32_t level, std::uint32_t cx, std::uint32_t cy) {
  const std::uint32_t i = (cx & 1) + 2 * (cy & 1) + 4 * (((cx >> 1) + (cy >> 1)) & 1);
  return {static_cast<std::uint8_t>(40 + 90 * (level - 10)), static_cast<std::uint8_t>(20 + 30 * i),
          static_cast<std::uint8_t>(240 - 30 * i)};
}

imagery::RgbaImage pattern_tile(const geo::TileId& id) {
  imagery::RgbaImage img(kSize, kSize);
  const std::uint32_t per_tile = 1u << (kCellLevel - id.z);  // cells per tile side
  for (std::uint32_t py = 0; py < kSize; ++py)
    for (std::uint32_t px = 0; px < kSize; ++px) {
      const auto c = cell_colour(id.z, id.x * per_tile + px * per_tile / kSize,
                                 id.y * per_tile + py * per_tile / kSize);
      std::uint8_t* p = img.at(px, py);
      p[0] = c[0];
      p[1] = c[1];
      p[2] = c[2];
      p[3] = 255;
    }
  return img;
}

// The imagery layer "synth" over the terrain's tiles, levels 10–12, as `format`; `missing` is
// left out, `corrupt` stored as bytes no decoder takes.
void write_imagery(const std::filesystem::path& path, const std::vector<geo::TileId>& tiles,
                   imagery::ImageFormat format, std::optional<geo::TileId> missing = {},
                   std::optional<geo::TileId> corrupt = {}) {
  store::ImageryInfo info;
  info.name = "synth";
  info.format = std::string(imagery::to_string(format));
  info.min_level = 10;
  info.max_level = 12;
  testing::write_imagery(path, "synth", info, tiles,
                         [&](const geo::TileId& id) -> std::optional<std::vector<std::uint8_t>> {
                           if (id == missing) return std::nullopt;
                           if (id == corrupt) {
                             const std::string junk = "these bytes are no image";
                             return std::vector<std::uint8_t>(junk.begin(), junk.end());
                           }
                           auto bytes = imagery::encode(pattern_tile(id), format,
                                                        {.quality = 95, .lossless = true});
                           if (!bytes) throw std::runtime_error(bytes.error().message);
                           return std::move(*bytes);
                         });
}

struct ViewRun {
  int status = -1;
  json stats;
  std::string err;
  Image image;
};

// Straight down (north up) over kTile's centre, 4 km above its highest point: the tile fills the
// 160 × 160 view, each image quadrant shows one of its quadrants.
ViewRun view(const std::filesystem::path& out, const std::vector<std::string>& source,
             const std::vector<std::string>& extra = {}, bool imagery = true) {
  const geo::LonLatRect r =
      kTile.lonlat_bounds(geo::NormalisedMercator(geo::Projection::spherical));
  std::ostringstream camera;
  camera.precision(12);
  camera << (r.west + r.east) / 2 << ',' << (r.south + r.north) / 2 << ",4500,0,-90";
  std::vector<std::string> args{"--headless", "--size",      "160x160",   "--msaa",
                                "0",          "--no-legend", "--max-sse", "0.1",
                                "--timeout",  "120",         "--camera",  camera.str(),
                                "--out",      out.string(),  "--layer",   "synth"};
  if (imagery) args.insert(args.end(), {"--imagery", "synth"});
  args.insert(args.end(), source.begin(), source.end());
  args.insert(args.end(), extra.begin(), extra.end());
  testing::Child child(testing::binary("tinstream-viewer"), args, /*capture_stderr=*/true);
  ViewRun run;
  run.status = child.wait(std::chrono::minutes(2));
  run.err = child.err();
  std::istringstream lines(child.out());
  for (std::string line; std::getline(lines, line);)
    if (!line.empty() && line.front() == '{') run.stats = json::parse(line, nullptr, false);
  if (run.status == 0) {
    auto img = read_png(out);
    if (img) run.image = std::move(*img);
  }
  return run;
}

const std::uint8_t* pixel(const Image& img, double fx, double fy) {
  const auto x = static_cast<std::size_t>(fx * img.width);
  const auto y = static_cast<std::size_t>(fy * img.height);
  return img.rgba.data() + (y * static_cast<std::size_t>(img.width) + x) * 4;
}

// The pixels inside kTile's four quadrants show the pattern's cells of imagery level `level`.
void expect_quadrants(const ViewRun& run, std::uint32_t level) {
  ASSERT_EQ(run.image.width, 160) << run.err;
  const std::array<std::array<double, 2>, 4> at{{{0.3, 0.3}, {0.7, 0.3}, {0.3, 0.7}, {0.7, 0.7}}};
  for (std::uint32_t q = 0; q < 4; ++q) {
    const auto want = cell_colour(level, 2 * kTile.x + (q & 1), 2 * kTile.y + (q >> 1));
    const std::uint8_t* got = pixel(run.image, at[q][0], at[q][1]);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(got[c], want[static_cast<std::size_t>(c)], 3)
          << "quadrant " << q << " channel " << c << " (imagery level " << level << ")";
  }
}

class Drape : public ::testing::Test {
 protected:
  void SetUp() override { tiles_ = testing::write_layer(store_(), testing::default_layer()); }
  std::filesystem::path store_() const { return dir_.path / "drape.sqlite"; }
  TempDir dir_{"drape"};
  std::vector<geo::TileId> tiles_;
};

TEST_F(Drape, TheImageryTileOfTheSameQuadkeyIsDrapedAndCountedInTheGpuTier) {
  write_imagery(store_(), tiles_, imagery::ImageFormat::png);
  const ViewRun a = view(dir_.path / "store.png", {"--store", store_().string()});
  ASSERT_EQ(a.status, 0) << a.err;
  EXPECT_EQ(a.stats["centre_level"], 12);
  EXPECT_TRUE(a.stats["complete"].get<bool>());
  EXPECT_GT(a.stats["imagery"]["loaded"].get<int>(), 0);
  EXPECT_EQ(a.stats["imagery"]["failed"].get<int>(), 0);
  EXPECT_EQ(a.stats["imagery"]["draped"], a.stats["tiles"]["drawn"]);
  // Imagery is asked for the tiles meant to stay only, not for the coarser ones drawn while
  // their children load (#19: 13–15 loaded for 2 draped): as many requested as draped.
  EXPECT_EQ(a.stats["imagery"]["requested"], a.stats["imagery"]["draped"]);
  expect_quadrants(a, 12);

  // Textures count in the GPU tier: at least one 256² RGBA texture more than the terrain alone.
  const ViewRun bare = view(dir_.path / "bare.png", {"--store", store_().string()}, {}, false);
  ASSERT_EQ(bare.status, 0) << bare.err;
  EXPECT_TRUE(bare.stats["imagery"].is_null());
  EXPECT_GE(a.stats["cache"]["gpu"]["bytes"].get<double>() -
                bare.stats["cache"]["gpu"]["bytes"].get<double>(),
            kSize * kSize * 4.0);
}

TEST_F(Drape, ImagerySwitchedOffAtRunTimeIsNeitherAskedForNorDraped) {
  // The window panel's switch (TileStreamer::set_imagery_enabled) and its counters
  // (imagery_stats), in this process: the session the viewer opens, the real renderer (EGL on
  // Mesa). Off from the start: the terrain completes with no imagery asked for; on: every drawn
  // tile gets its imagery; off again: the next frame drapes none and asks for nothing more.
  write_imagery(store_(), tiles_, imagery::ImageFormat::png);
  ViewerOptions o;
  o.store = store_();
  o.layers = {"synth"};
  o.imagery = "synth";
  o.threads = 2;
  o.max_sse = 0.1;
  o.heap_trim_ms = -1;
  auto session = open_session(o);
  ASSERT_TRUE(session.ok()) << session.error().message;
  Session& s = *session;
  auto offscreen = testing::open_offscreen_renderer(160);
  ASSERT_TRUE(offscreen.ok()) << offscreen.error().message;
  GlobeRenderer& gl = *offscreen->renderer;
  Camera camera(160, 160, 60);
  camera.log_depth = gl.log_depth();
  const geo::LonLatRect r =
      kTile.lonlat_bounds(geo::NormalisedMercator(geo::Projection::spherical));
  camera.set_pose({(r.west + r.east) / 2, (r.south + r.north) / 2, 4500, 0, -90});
  // Frames until `done` holds (a generous deadline: the loader works on other threads).
  const auto frames_until = [&](const auto& done) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(90);
    while (std::chrono::steady_clock::now() < deadline) {
      if (done(s.streamer->update(camera, gl))) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  };

  s.streamer->set_imagery_enabled(false);
  ASSERT_TRUE(frames_until([](const FrameResult& f) { return f.complete; }));
  ImageryStats i = imagery_stats(*s.streamer);
  EXPECT_EQ(i.requested, 0u);
  EXPECT_EQ(i.loaded, 0u);
  EXPECT_EQ(i.draped, 0u);

  s.streamer->set_imagery_enabled(true);
  ASSERT_TRUE(frames_until([&](const FrameResult& f) {
    return f.complete && !f.draws.empty() && imagery_stats(*s.streamer).draped == f.draws.size();
  }));
  i = imagery_stats(*s.streamer);
  EXPECT_GT(i.requested, 0u);
  EXPECT_GT(i.loaded, 0u);
  EXPECT_EQ(i.failed, 0u);

  s.streamer->set_imagery_enabled(false);
  const FrameResult& f = s.streamer->update(camera, gl);
  EXPECT_FALSE(f.draws.empty());
  const ImageryStats off = imagery_stats(*s.streamer);
  EXPECT_EQ(off.draped, 0u);
  EXPECT_EQ(off.requested, i.requested);
  s.streamer->release_all(gl);
}

TEST_F(Drape, TheServerAndTheDiskTierDeliverTheSameImagery) {
  write_imagery(store_(), tiles_, imagery::ImageFormat::png);
  // From the real server, through the disk tier; a second run revalidates every tile (304s).
  testing::Server server(store_());
  const std::vector<std::string> url{"--url", server.url(), "--disk-cache",
                                     (dir_.path / "disk").string()};
  const ViewRun b = view(dir_.path / "url.png", url);
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_GT(b.stats["requests"]["wire_bytes"].get<double>(), 0);
  EXPECT_GT(b.stats["imagery"]["loaded"].get<int>(), 0);
  expect_quadrants(b, 12);
  const ViewRun c = view(dir_.path / "warm.png", url);
  ASSERT_EQ(c.status, 0) << c.err;
  EXPECT_EQ(c.stats["requests"]["downloaded_bytes"].get<double>(), 0);
  EXPECT_EQ(c.stats["requests"]["not_modified"], b.stats["requests"]["ok"]);
  EXPECT_EQ(b.image.rgba, c.image.rgba);
}

TEST_F(Drape, JpegAndWebpTilesDrapeToo) {
  write_imagery(store_(), tiles_, imagery::ImageFormat::webp);  // lossless: exact colours
  const ViewRun a = view(dir_.path / "webp.png", {"--store", store_().string()});
  ASSERT_EQ(a.status, 0) << a.err;
  expect_quadrants(a, 12);
  write_imagery(store_(), tiles_, imagery::ImageFormat::jpeg);  // replaces the layer
  const ViewRun b = view(dir_.path / "jpeg.png", {"--store", store_().string()});
  ASSERT_EQ(b.status, 0) << b.err;
  expect_quadrants(b, 12);  // quality 95, cells of whole 8×8 blocks: within 3 of the colour
}

TEST_F(Drape, AMissingImageryTileFallsBackToItsParentsSubRectangle) {
  write_imagery(store_(), tiles_, imagery::ImageFormat::png, kTile);
  const ViewRun a = view(dir_.path / "missing.png", {"--store", store_().string()});
  ASSERT_EQ(a.status, 0) << a.err;
  EXPECT_EQ(a.stats["centre_level"], 12);
  EXPECT_GE(a.stats["imagery"]["absent"].get<int>(), 1);
  // kTile is the south-east quadrant of its parent: the parent's cells there, level-11 colours.
  expect_quadrants(a, 11);
}

TEST_F(Drape, ACorruptImageryTileIsALoggedErrorAndTheTerrainStillDraws) {
  write_imagery(store_(), tiles_, imagery::ImageFormat::png, {}, kTile);
  const ViewRun a = view(dir_.path / "corrupt.png", {"--store", store_().string()});
  ASSERT_EQ(a.status, 0) << a.err;
  EXPECT_EQ(a.stats["imagery"]["failed"].get<int>(), 1);
  EXPECT_NE(a.err.find("imagery tile 12/2121/1401"), std::string::npos) << a.err;
  EXPECT_NE(a.stats["last_error"].get<std::string>().find("of layer \"synth\""), std::string::npos);
  EXPECT_EQ(a.stats["tiles"]["failed"].get<int>(), 0);  // the terrain tiles are all there
  EXPECT_EQ(a.stats["centre_level"], 12);
  expect_quadrants(a, 11);  // the parent's imagery stands in
}

TEST_F(Drape, TheWireframeIsBlendedOverTheImagery) {
  write_imagery(store_(), tiles_, imagery::ImageFormat::png);
  const ViewRun a = view(dir_.path / "wire.png", {"--store", store_().string()}, {"--wireframe"});
  ASSERT_EQ(a.status, 0) << a.err;
  // Edges are light lines; between them the imagery's colours stay.
  int light = 0, imagery = 0;
  const auto want = cell_colour(12, 2 * kTile.x, 2 * kTile.y);
  for (int y = 5; y < 75; ++y)
    for (int x = 5; x < 75; ++x) {
      const std::uint8_t* p = pixel(a.image, x / 160.0, y / 160.0);
      light += p[0] + p[1] + p[2] > want[0] + want[1] + want[2] + 60;
      imagery += std::abs(p[0] - want[0]) <= 3 && std::abs(p[1] - want[1]) <= 3 &&
                 std::abs(p[2] - want[2]) <= 3;
    }
  EXPECT_GT(light, 70 * 70 / 50);
  EXPECT_GT(imagery, 70 * 70 / 2);
}

TEST_F(Drape, AnUnknownImageryLayerIsAClearError) {
  const ViewRun a = view(dir_.path / "none.png", {"--store", store_().string()});
  EXPECT_EQ(a.status, 2);
  EXPECT_NE(a.err.find("synth"), std::string::npos) << a.err;
}

}  // namespace
}  // namespace tinstream::client
