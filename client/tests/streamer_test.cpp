// Tile selection and streaming end to end on a real store (SQLite), without OpenGL: the GPU tier
// is fed through a counting GpuUploader.
#include "tinstream/client/streamer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <thread>

#include "synthetic_store.hpp"
#include "tinstream/geo/ecef.hpp"
#include "tinstream/imagery/image.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {
namespace {

using testing::SyntheticLayer;
using testing::TempDir;

// Hands out fake buffer names; counts what is alive.
class CountingUploader final : public GpuUploader {
 public:
  GpuMesh upload(const TileMesh& mesh) override {
    GpuMesh g;
    g.vao = ++next_;
    g.index_count = static_cast<std::uint32_t>(mesh.index_count());
    g.bytes = mesh.byte_size();
    ++alive;
    alive_bytes += g.bytes;
    return g;
  }
  GpuMesh upload_image(const imagery::RgbaImage& image) override {
    GpuMesh g;
    g.texture = ++next_;
    g.bytes = image.pixels.size();
    ++images;
    return g;
  }
  void release(GpuMesh& mesh) override {
    if (mesh.texture != 0) {
      --images;
      mesh.texture = 0;
      return;
    }
    ASSERT_NE(mesh.vao, 0u);
    --alive;
    alive_bytes -= mesh.bytes;
    mesh.vao = 0;
  }
  int alive = 0;  // meshes
  std::uint64_t alive_bytes = 0;
  int images = 0;  // textures

 private:
  std::uint32_t next_ = 0;
};

struct Fixture {
  explicit Fixture(const std::string& name, const SyntheticLayer& layer = testing::default_layer())
      : dir(name), store(dir.path / "s.db") {
    testing::write_layer(store, layer);
    auto source = open_store_source(store);
    if (!source) throw std::runtime_error(source.error().message);
    auto layers = (*source)->layers({});
    if (!layers) throw std::runtime_error(layers.error().message);
    loader = std::make_unique<TileLoader>(*source, *layers, nullptr, LoaderOptions{2});
  }
  TempDir dir;
  std::filesystem::path store;
  std::unique_ptr<TileLoader> loader;
};

// Runs frames until the view is complete (or 60 s pass); checks the drawn set every frame.
using FrameCheck = std::function<void(const FrameResult&)>;
bool run_until_complete(TileStreamer& s, TileLoader& loader, const Camera& camera, GpuUploader& gpu,
                        const FrameCheck& check = {}) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < until) {
    const FrameResult& f = s.update(camera, gpu);
    if (check) check(f);
    if (f.complete) return true;
    if (f.upload_pending == 0) loader.wait_for_results(std::chrono::milliseconds(50));
  }
  return false;
}

Camera above(double lon, double lat, double height) {
  Camera c(1280, 720, 60);
  c.set_pose({lon, lat, height, 0, -90});
  return c;
}

// The layer's centre (the 4×4 block of level-12 tiles at 2120…2123, 1400…1403).
geo::LonLat block_centre() {
  const geo::TileId root{10, 530, 350};
  const geo::MercatorRect r = root.bounds();
  return geo::NormalisedMercator().inverse({(r.min_x + r.max_x) / 2, (r.min_y + r.max_y) / 2});
}

// The drawn tiles (with their quadrant masks) cover the root exactly once: no overlap, no hole.
void expect_partition_of_root(const FrameResult& f, const geo::TileId& root) {
  double area = 0;
  for (const DrawItem& d : f.draws) {
    ASSERT_GE(d.key.tile.z, root.z);
    area += std::popcount(d.quadrant_mask) / 4.0 *
            std::ldexp(1.0, -2 * static_cast<int>(d.key.tile.z - root.z));
    for (const DrawItem& e : f.draws) {
      if (&d == &e || e.key.tile.z <= d.key.tile.z) continue;
      geo::TileId up = e.key.tile;
      while (up.z > d.key.tile.z + 1) up = up.parent();
      if (up.parent() != d.key.tile) continue;
      EXPECT_FALSE(d.quadrant_mask & (1u << up.child_index()))
          << d.key.tile.to_string() << " overlaps " << e.key.tile.to_string();
    }
  }
  EXPECT_EQ(area, 1.0) << "drawn tiles do not cover the layer exactly";
}

TEST(TileStreamer, RefinesToTheFinestLevelWithoutHolesOrOverlaps) {
  Fixture fx("streamer_refine");
  StreamerOptions options;
  options.max_sse = 0.01;  // everything down to the finest level
  TileStreamer s(*fx.loader, options);
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  const Camera camera = above(c.lon, c.lat, 60000);
  bool root_seen = false;
  ASSERT_TRUE(run_until_complete(s, *fx.loader, camera, gpu, [&](const FrameResult& f) {
    if (f.draws.empty()) {
      EXPECT_FALSE(root_seen) << "a frame without tiles after the root was drawn";
      return;
    }
    root_seen = true;
    expect_partition_of_root(f, {10, 530, 350});
  }));
  const FrameResult& f = s.last_frame();
  EXPECT_EQ(f.draws.size(), 16u);
  EXPECT_EQ(f.drawn_per_level[12], 16u);
  EXPECT_EQ(f.max_sse_drawn, 0.0);  // finest tiles carry no error
  EXPECT_EQ(s.level_counters()[10].loaded, 1u);
  EXPECT_EQ(s.level_counters()[11].loaded, 4u);
  EXPECT_EQ(s.level_counters()[12].loaded, 16u);
  EXPECT_EQ(fx.loader->counters().failed, 0u);
  EXPECT_EQ(gpu.alive, 21);
  // Nothing was evicted; the first frame that received tiles trimmed the heap, and later ones
  // no sooner than a second after (heap_trim_interval), so a fast run trims once or a few times.
  EXPECT_EQ(s.gpu_counters().evictions + s.ram_counters().evictions, 0u);
  EXPECT_GE(s.heap_trims(), 1u);
  EXPECT_LE(s.heap_trims(), s.frames());
  s.release_all(gpu);
  EXPECT_EQ(gpu.alive, 0);
}

TEST(TileStreamer, ALowerCameraDrawsFinerLevels) {
  Fixture fx("streamer_levels");
  TileStreamer s(*fx.loader, StreamerOptions{});  // 2 px
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  ASSERT_TRUE(run_until_complete(s, *fx.loader, above(c.lon, c.lat, 3000), gpu));
  const auto low = s.last_frame().drawn_per_level;
  ASSERT_TRUE(run_until_complete(s, *fx.loader, above(c.lon, c.lat, 40000), gpu));
  const auto high = s.last_frame().drawn_per_level;
  const auto finest = [](const std::array<std::uint32_t, kLevels>& a) {
    int z = -1;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (a[i]) z = static_cast<int>(i);
    return z;
  };
  // 3 km up a level-11 tile's 20 m error is ≈ 4 px: the finest level shows; 40 km up the root's
  // 40 m are < 1 px.
  EXPECT_EQ(finest(low), 12);
  EXPECT_LT(finest(high), 12);
  EXPECT_LE(s.last_frame().max_sse_drawn, 2.0);
  s.release_all(gpu);
}

// Imagery is draped per terrain tile at that tile's level. From 20 km up the synthetic root's
// terrain (40 m error: 1.25 px) needs no refinement, but its 256-pixel imagery tile spreads
// ~99 m texels over ~3 px: with imagery draped the root is refined until each drawn tile's texels
// look no larger than max_sse (or the imagery has no finer level), as CesiumJS picks imagery by
// texel size (#19: make demo's view stretched one level-0 imagery tile over 1280×720).
TEST(TileStreamer, DrapedImageryRefinesTilesWhoseTexelsWouldLookTooLarge) {
  TempDir dir("streamer_imagery_refine");
  const std::filesystem::path store_path = dir.path / "s.db";
  const std::vector<geo::TileId> tiles = testing::write_layer(store_path, testing::default_layer());
  store::ImageryInfo info;
  info.name = "ortho";
  info.format = "png";
  info.min_level = 10;
  info.max_level = 12;
  auto png = imagery::encode(imagery::RgbaImage(256, 256), imagery::ImageFormat::png);
  ASSERT_TRUE(png.ok()) << png.error().message;
  testing::write_imagery(store_path, "synth", info, tiles,
                         [&](const geo::TileId&) { return std::optional{*png}; });
  auto source = open_store_source(store_path);
  ASSERT_TRUE(source.ok()) << source.error().message;
  auto layers = (*source)->layers({"synth"});
  ASSERT_TRUE(layers.ok()) << layers.error().message;
  auto ortho = (*source)->imagery_layer("ortho");
  ASSERT_TRUE(ortho.ok()) << ortho.error().message;
  std::vector<LayerDescription> table = *layers;
  table.push_back(*ortho);
  TileLoader loader(*source, table, nullptr, LoaderOptions{2});
  const geo::LonLat c = block_centre();
  const Camera camera = above(c.lon, c.lat, 20000);
  CountingUploader gpu;

  // The ground width of a texel of the 256-pixel imagery tile of `id`, from its longitudes and
  // latitude (degrees on the WGS84 equator's circle, scaled by the cosine of the latitude).
  const auto texel_metres = [](const geo::TileId& id) {
    const geo::LonLatRect r = id.lonlat_bounds(geo::NormalisedMercator());
    const double rad = std::numbers::pi / 180;
    return (r.east - r.west) * rad * geo::kWgs84A * std::cos((r.south + r.north) / 2 * rad) / 256;
  };
  const auto levels = [](const FrameResult& f) {
    std::set<std::uint32_t> z;
    for (const DrawItem& d : f.draws) z.insert(d.key.tile.z);
    return z;
  };

  StreamerOptions options;  // 2 px
  options.imagery_layer = 1;
  TileStreamer with(loader, options);
  with.set_imagery_enabled(false);
  ASSERT_TRUE(run_until_complete(with, loader, camera, gpu));
  EXPECT_EQ(levels(with.last_frame()), std::set<std::uint32_t>{10});  // the terrain alone

  with.set_imagery_enabled(true);
  ASSERT_TRUE(run_until_complete(with, loader, camera, gpu));
  const FrameResult& f = with.last_frame();
  ASSERT_FALSE(f.draws.empty());
  EXPECT_EQ(levels(f).count(10), 0u) << "the root's texels look ~3 px: it must be refined";
  for (const DrawItem& d : f.draws) {
    EXPECT_TRUE(d.key.tile.z >= 12 ||
                camera.screen_space_error(texel_metres(d.key.tile), d.distance) <= 2.0)
        << d.key.tile.to_string() << ": texels of "
        << camera.screen_space_error(texel_metres(d.key.tile), d.distance) << " px";
    // Coarse enough: its parent's texels would have looked too large.
    EXPECT_GT(camera.screen_space_error(texel_metres(d.key.tile.parent()), d.distance), 2.0)
        << d.key.tile.to_string() << " is finer than its imagery needs";
  }
  with.release_all(gpu);
  EXPECT_EQ(gpu.alive, 0);
  EXPECT_EQ(gpu.images, 0);
}

TEST(TileStreamer, NothingBeyondTheHorizonIsRequested) {
  Fixture fx("streamer_horizon");
  TileStreamer s(*fx.loader, StreamerOptions{});
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  const double antipode_lon = c.lon > 0 ? c.lon - 180 : c.lon + 180;
  const Camera camera = above(antipode_lon, -c.lat, 2e6);
  for (int i = 0; i < 5; ++i) {
    const FrameResult& f = s.update(camera, gpu);
    EXPECT_TRUE(f.draws.empty());
    EXPECT_EQ(f.wanted, 0u);
    EXPECT_TRUE(f.complete);
  }
  EXPECT_EQ(fx.loader->counters().requests, 0u);
}

TEST(TileStreamer, PrefetchAsksForTheLevelsBelowAMissingTileAtOnceWithoutWaitingForThem) {
  const geo::LonLat c = block_centre();
  const Camera close = above(c.lon, c.lat, 1500);  // needs level 12 under the root
  for (const int levels : {0, 1, 2}) {
    Fixture fx("streamer_prefetch");
    StreamerOptions options;
    options.prefetch_levels = levels;
    TileStreamer s(*fx.loader, options);
    CountingUploader gpu;
    fx.loader->set_paused(true);  // nothing arrives: the first frame's requests stay queued
    const FrameResult& f = s.update(close, gpu);
    EXPECT_TRUE(f.draws.empty());
    EXPECT_EQ(f.pending_per_level[10], 1u) << levels;  // the root: the one tile the frame needs
    EXPECT_EQ(f.pending_per_level[11] + f.pending_per_level[12], 0u) << levels;
    // Below it, the visible descendants of up to `levels` levels (the layer's level-11 and -12
    // errors exceed max_sse at this height), asked for in the same frame.
    EXPECT_EQ(s.level_counters()[11].requested, levels >= 1 ? 4u : 0u) << levels;
    if (levels >= 2) {
      EXPECT_GT(s.level_counters()[12].requested, 0u);
    } else {
      EXPECT_EQ(s.level_counters()[12].requested, 0u) << levels;
    }
    EXPECT_EQ(f.prefetched, f.wanted - 1) << levels;
    // Prefetched requests rank after every needed one (positive errors): negative priorities,
    // coarser (larger estimated error) before finer.
    double lowest_11 = 0, highest_12 = -std::numeric_limits<double>::infinity();
    for (const TileRequest& r : s.requests()) {
      if (r.key.tile.z == 10) continue;
      EXPECT_LT(r.priority, 0.0) << r.key.tile.to_string();
      if (r.key.tile.z == 11) lowest_11 = std::min(lowest_11, r.priority);
      if (r.key.tile.z == 12) highest_12 = std::max(highest_12, r.priority);
    }
    if (levels >= 2) {
      EXPECT_GT(lowest_11, highest_12);
    }
    fx.loader->set_paused(false);
    // Prefetched tiles arrive, are not uploaded until the view needs them, and the view
    // completes on the same tiles as without prefetching.
    ASSERT_TRUE(run_until_complete(s, *fx.loader, close, gpu)) << levels;
    EXPECT_EQ(s.last_frame().drawn_per_level[12], s.last_frame().draws.size()) << levels;
    EXPECT_EQ(s.level_counters()[12].failed + fx.loader->counters().failed, 0u);
    s.release_all(gpu);
  }
}

TEST(TileStreamer, PrefetchGoesDeeperWhileAFrameAsksForFewerTilesThanThereAreDownloadThreads) {
  // One level of prefetch below the missing root asks for 5 tiles (the root and its 4 children).
  // With 8 download threads 3 would sit idle through a round trip: prefetch goes on to level 12
  // in the same frame. With one thread (busy whatever else is asked for) it does not.
  const geo::LonLat c = block_centre();
  const Camera close = above(c.lon, c.lat, 1500);  // needs level 12 under the root
  for (const int threads : {1, 8}) {
    Fixture fx("streamer_prefetch_deeper");
    fx.loader->set_threads(threads);
    StreamerOptions options;
    options.prefetch_levels = 1;
    TileStreamer s(*fx.loader, options);
    CountingUploader gpu;
    fx.loader->set_paused(true);  // nothing arrives: the first frame's requests stay queued
    const FrameResult& f = s.update(close, gpu);
    EXPECT_EQ(f.pending_per_level[10], 1u) << threads;
    EXPECT_EQ(s.level_counters()[11].requested, 4u) << threads;
    if (threads == 1) {
      EXPECT_EQ(s.level_counters()[12].requested, 0u);
      EXPECT_EQ(f.wanted, 5u);
    } else {
      EXPECT_GT(s.level_counters()[12].requested, 0u);
      EXPECT_GE(f.wanted, 8u);
    }
    EXPECT_EQ(f.prefetched, f.wanted - 1) << threads;
    for (const TileRequest& r : s.requests())
      if (r.key.tile.z == 12) {
        EXPECT_LT(r.priority, 0.0) << r.key.tile.to_string();  // ranked after every needed one
      }
    fx.loader->set_paused(false);
    // The view completes on the same tiles: level 12 only.
    ASSERT_TRUE(run_until_complete(s, *fx.loader, close, gpu)) << threads;
    EXPECT_EQ(s.last_frame().drawn_per_level[12], s.last_frame().draws.size()) << threads;
    EXPECT_EQ(s.level_counters()[12].failed + fx.loader->counters().failed, 0u);
    s.release_all(gpu);
  }
}

// Waits (60 s at most) until a worker has a result ready.
bool wait_for_a_result(TileLoader& loader) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < until)
    if (loader.wait_for_results(std::chrono::milliseconds(50))) return true;
  return false;
}

geo::LonLat tile_centre(const geo::TileId& id) {
  const geo::MercatorRect r = id.bounds();
  return geo::NormalisedMercator().inverse({(r.min_x + r.max_x) / 2, (r.min_y + r.max_y) / 2});
}

TEST(TileStreamer, ADecodedTilesChildrenAreAskedForInTheFrameItArrivesNotAfterItsUpload) {
  const geo::LonLat c = block_centre();
  const Camera close = above(c.lon, c.lat, 1500);  // needs level 12 under the root
  Fixture fx("streamer_look_ahead");
  StreamerOptions options;
  options.prefetch_levels = 0;  // nothing is asked for below a missing tile
  TileStreamer s(*fx.loader, options);
  CountingUploader gpu;
  ASSERT_EQ(s.update(close, gpu).wanted, 1u);  // the root
  ASSERT_TRUE(wait_for_a_result(*fx.loader));
  fx.loader->set_paused(true);  // what this frame asks for stays queued
  const FrameResult& f = s.update(close, gpu);
  // The frame took the root and uploads it at its end; it draws nothing yet.
  EXPECT_EQ(f.uploaded, 1u);
  EXPECT_TRUE(f.draws.empty());
  // From the root's own stored error and box, its four children are asked for now, as tiles
  // the view needs (positive priorities, counted as pending), not one frame later.
  EXPECT_EQ(s.level_counters()[11].requested, 4u);
  EXPECT_EQ(f.pending_per_level[11], 4u);
  EXPECT_EQ(f.prefetched, 0u);
  ASSERT_EQ(s.requests().size(), 4u);
  for (const TileRequest& r : s.requests()) {
    EXPECT_EQ(r.key.tile.z, 11u);
    EXPECT_GT(r.priority, 0.0);
  }
  // A frame that uploaded is not settled: without any new result, the next one draws the root.
  EXPECT_FALSE(f.settled());
  const FrameResult& next = s.update(close, gpu);
  ASSERT_EQ(next.draws.size(), 1u);
  EXPECT_EQ(next.draws[0].key.tile, (geo::TileId{10, 530, 350}));
  EXPECT_TRUE(next.settled());
  EXPECT_EQ(s.update(close, gpu).draws.size(), 1u);  // settled: the same again
  fx.loader->set_paused(false);
  ASSERT_TRUE(run_until_complete(s, *fx.loader, close, gpu));
  EXPECT_EQ(s.last_frame().drawn_per_level[12], s.last_frame().draws.size());
  EXPECT_EQ(fx.loader->counters().failed, 0u);
  s.release_all(gpu);
}

TEST(TileStreamer, AResidentTilesChildrenAreAskedForWhileItsSiblingsAreMissing) {
  // Camera A, low over the north-west level-12 tile of the root's north-west child, loads the
  // root, that child and that grandchild only. Camera B, over the root's centre, sees all four
  // children: three are missing, so the root stays drawn; the resident child's own children
  // that B needs are asked for at once, not after its slowest sibling arrived.
  const geo::TileId root{10, 530, 350};
  const geo::TileId nw = root.children()[0];
  const geo::LonLat a = tile_centre(nw.children()[0]);
  const geo::LonLat b = block_centre();
  Fixture fx("streamer_look_ahead_siblings");
  StreamerOptions options;
  options.prefetch_levels = 0;
  TileStreamer s(*fx.loader, options);
  CountingUploader gpu;
  ASSERT_TRUE(run_until_complete(s, *fx.loader, above(a.lon, a.lat, 1500), gpu));
  ASSERT_EQ(s.level_counters()[11].loaded, 1u);
  ASSERT_EQ(s.level_counters()[12].loaded, 1u);
  fx.loader->set_paused(true);
  const FrameResult& f = s.update(above(b.lon, b.lat, 1500), gpu);
  ASSERT_EQ(f.draws.size(), 1u);
  EXPECT_EQ(f.draws[0].key.tile, root);
  EXPECT_TRUE(f.draws[0].stand_in);
  std::size_t below_nw = 0;
  for (const TileRequest& r : s.requests()) {
    EXPECT_GT(r.priority, 0.0) << r.key.tile.to_string();
    if (r.key.tile.z == 12) {
      EXPECT_EQ(r.key.tile.parent(), nw) << r.key.tile.to_string();
      ++below_nw;
    }
  }
  EXPECT_EQ(f.pending_per_level[11], 3u);
  EXPECT_GE(below_nw, 1u);  // at least the grandchild at the root's centre
  EXPECT_EQ(f.pending_per_level[12], below_nw);
  fx.loader->set_paused(false);
  ASSERT_TRUE(run_until_complete(s, *fx.loader, above(b.lon, b.lat, 1500), gpu));
  EXPECT_EQ(s.last_frame().drawn_per_level[12], s.last_frame().draws.size());
  s.release_all(gpu);
}

TEST(TileStreamer, MovingTheCameraDropsTheOldViewsQueuedRequests) {
  Fixture fx("streamer_drop");
  TileStreamer s(*fx.loader, StreamerOptions{});
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  // Load the coarse levels, then stop the workers and look closely: the finer tiles are queued.
  ASSERT_TRUE(run_until_complete(s, *fx.loader, above(c.lon, c.lat, 400000), gpu));
  fx.loader->set_paused(true);
  const auto before = fx.loader->counters();
  const FrameResult& close = s.update(above(c.lon, c.lat, 1500), gpu);
  const std::size_t queued = close.wanted;
  ASSERT_GT(queued, 0u);
  // Turn to look at the sky: nothing is needed any more, the queue is dropped.
  Camera sky = above(c.lon, c.lat, 1500);
  sky.set_pose({c.lon, c.lat, 1500, 0, 60});
  EXPECT_EQ(s.update(sky, gpu).wanted, 0u);
  fx.loader->set_paused(false);
  for (int i = 0; i < 20; ++i) {
    s.update(sky, gpu);
    fx.loader->wait_for_results(std::chrono::milliseconds(10));
  }
  const auto after = fx.loader->counters();
  EXPECT_EQ(after.dropped - before.dropped, queued);
  EXPECT_EQ(after.requests, before.requests) << "a dropped request was sent";
  s.release_all(gpu);
}

TEST(TileLoader, AResultNotYetTakenIsNotRequestedAgain) {
  // A frame may look for a tile just before its worker finishes and submit it just after: the
  // tile must stay "in flight" until the render thread has taken its result.
  Fixture fx("loader_untaken");
  const TileKey root{TileKind::terrain, 0, {10, 530, 350}};
  fx.loader->submit({{root, 1, 1}});
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  bool ready = false;
  while (!ready && std::chrono::steady_clock::now() < until)
    ready = fx.loader->wait_for_results(std::chrono::milliseconds(50));
  ASSERT_TRUE(ready);
  fx.loader->submit({{root, 1, 1}});  // the result is ready but not taken
  EXPECT_EQ(fx.loader->counters().queued, 0u);
  EXPECT_EQ(fx.loader->counters().in_flight, 1u);
  const std::vector<LoadResult> results = fx.loader->take_results();
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].status, LoadStatus::loaded);
  EXPECT_EQ(fx.loader->counters().in_flight, 0u);
  EXPECT_EQ(fx.loader->counters().requests, 1u);
}

// A store source whose connections count the fetches they were asked for; a fetch of the tile
// `gated` (if any) sets `entered` and waits until `open` is set (30 s at most).
class CountingSource final : public TileSource {
 public:
  explicit CountingSource(std::shared_ptr<TileSource> inner,
                          std::optional<TileKey> gated = std::nullopt)
      : inner_(std::move(inner)), gated_(gated) {}
  std::string describe() const override { return inner_->describe(); }
  Result<std::vector<LayerDescription>> layers(const std::vector<std::string>& names) override {
    return inner_->layers(names);
  }
  Result<LayerDescription> imagery_layer(const std::string& name) override {
    return inner_->imagery_layer(name);
  }
  Result<std::unique_ptr<TileConnection>> connect() override {
    auto c = inner_->connect();
    if (!c) return c.error();
    return std::unique_ptr<TileConnection>(std::make_unique<Counted>(std::move(*c), *this));
  }
  bool remote() const override { return false; }
  std::atomic<int> fetches{0};
  std::atomic<bool> entered{false}, open{false};

 private:
  class Counted final : public TileConnection {
   public:
    Counted(std::unique_ptr<TileConnection> inner, CountingSource& source)
        : inner_(std::move(inner)), source_(source) {}
    FetchResponse fetch(const FetchRequest& request, const std::atomic<bool>& cancel) override {
      ++source_.fetches;
      if (request.key == source_.gated_) {
        source_.entered = true;
        const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        while (!source_.open.load() && std::chrono::steady_clock::now() < until)
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      return inner_->fetch(request, cancel);
    }

   private:
    std::unique_ptr<TileConnection> inner_;
    CountingSource& source_;
  };
  std::shared_ptr<TileSource> inner_;
  std::optional<TileKey> gated_;
};

TEST(TileLoader, ADownloadWorkerFetchesTheNextTileWhileThePreviousOneDecodes) {
  // One download thread, one decoder. The result callback runs on the thread that made the
  // result ready; for the first result it waits (5 s at most) until the download worker has
  // fetched the second tile. A worker that decoded its own tiles ran that callback itself and
  // could fetch nothing meanwhile: its connection sat idle through every decode.
  TempDir dir("loader_decoders");
  testing::write_layer(dir.path / "s.db", testing::default_layer());
  auto store = open_store_source(dir.path / "s.db");
  ASSERT_TRUE(store) << store.error().message;
  auto source = std::make_shared<CountingSource>(*store);
  auto layers = source->layers({});
  ASSERT_TRUE(layers) << layers.error().message;
  TileLoader loader(source, *layers, nullptr, LoaderOptions{1, 1});
  std::atomic<int> callbacks{0};
  std::atomic<bool> fetched_while_held{false};
  loader.set_result_callback([&] {
    if (callbacks++ > 0) return;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (source->fetches.load() < 2 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    fetched_while_held = source->fetches.load() >= 2;
  });
  const geo::TileId root{10, 530, 350};
  loader.submit(
      {{{TileKind::terrain, 0, root}, 2, 1}, {{TileKind::terrain, 0, root.children()[0]}, 1, 1}});
  std::vector<LoadResult> results;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (results.size() < 2 && std::chrono::steady_clock::now() < until) {
    loader.wait_for_results(std::chrono::milliseconds(50));
    for (LoadResult& r : loader.take_results()) results.push_back(std::move(r));
  }
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].key.tile, root);  // the more urgent request first
  for (const LoadResult& r : results) EXPECT_EQ(r.status, LoadStatus::loaded) << r.error;
  EXPECT_TRUE(fetched_while_held);
  EXPECT_EQ(loader.counters().most_decoding, 1);
  loader.set_result_callback(nullptr);
}

// A result callback that holds the decoder in the first result's callback until `release` (30 s
// at most); `callbacks` counts the calls.
std::function<void()> hold_first_result(std::atomic<int>& callbacks, std::atomic<bool>& release) {
  return [&callbacks, &release] {
    if (callbacks++ > 0) return;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (!release.load() && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
}

// Takes the loader's results until as many as `expected` arrived (or `until`): the tiles in that
// order, each loaded.
void expect_loaded_in_order(TileLoader& loader, const std::vector<TileKey>& expected,
                            std::chrono::steady_clock::time_point until) {
  std::vector<LoadResult> results;
  while (results.size() < expected.size() && std::chrono::steady_clock::now() < until) {
    loader.wait_for_results(std::chrono::milliseconds(50));
    for (LoadResult& r : loader.take_results()) results.push_back(std::move(r));
  }
  ASSERT_EQ(results.size(), expected.size());
  for (std::size_t i = 0; i < results.size(); ++i) {
    EXPECT_EQ(results[i].key, expected[i]) << "result " << i;
    EXPECT_EQ(results[i].status, LoadStatus::loaded) << results[i].error;
  }
}

TEST(TileLoader, APrefetchedPayloadTheViewNowNeedsIsDecodedBeforeLessUrgentOnes) {
  // One download thread, one decoder. The first result's callback holds the decoder while the
  // worker fetches two prefetched tiles (negative priorities, the nearer-to-needed -1 before -2)
  // and both payloads wait for it. Then the view needs the -2 one (a positive priority, as the
  // streamer submits a needed tile): it must be decoded before the -1 one. With decode jobs that
  // keep the priority they were fetched with it came last.
  TempDir dir("loader_decode_raise");
  testing::write_layer(dir.path / "s.db", testing::default_layer());
  auto source = open_store_source(dir.path / "s.db");
  ASSERT_TRUE(source) << source.error().message;
  auto layers = (*source)->layers({});
  ASSERT_TRUE(layers) << layers.error().message;
  TileLoader loader(*source, *layers, nullptr, LoaderOptions{1, 1});
  std::atomic<int> callbacks{0};
  std::atomic<bool> release{false};
  loader.set_result_callback(hold_first_result(callbacks, release));
  const geo::TileId root{10, 530, 350};
  const TileKey first{TileKind::terrain, 0, root};
  const TileKey later{TileKind::terrain, 0, root.children()[0]};
  const TileKey needed_now{TileKind::terrain, 0, root.children()[1]};
  loader.submit({{first, 3, 1}, {later, -1, 1}, {needed_now, -2, 1}});
  // Both prefetched payloads wait while the decoder is held in the first result's callback (not
  // merely two queued: before the decoder takes the first job, the first and the -1 one can be
  // the two waiting, and the -2 one still downloading, CI's ASan run, 2026-11-28).
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while ((callbacks.load() == 0 || loader.counters().decode_queued < 2) &&
         std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(callbacks.load(), 1);
  EXPECT_EQ(loader.counters().decode_queued, 2u);
  loader.submit({{needed_now, 5, 1}});  // both in flight: nothing is queued again
  EXPECT_EQ(loader.counters().queued, 0u);
  release = true;
  expect_loaded_in_order(loader, {first, needed_now, later}, until);
  EXPECT_EQ(loader.counters().requests, 3u);
  loader.set_result_callback(nullptr);
}

TEST(TileLoader, APrefetchedTileTheViewNeedsWhileItDownloadsIsDecodedBeforeLessUrgentOnes) {
  // One download thread, one decoder. The first result's callback holds the decoder; the worker
  // fetches the prefetched -1 tile (its payload waits) and then the -2 one, whose fetch waits at
  // the gate. While it downloads the view comes to need it (a positive priority): submit() cannot
  // raise a payload that is not there yet, so the raise must reach its decode job when the
  // payload arrives. With the priority it was fetched with it was decoded after the -1 one.
  TempDir dir("loader_decode_raise_in_flight");
  testing::write_layer(dir.path / "s.db", testing::default_layer());
  auto store = open_store_source(dir.path / "s.db");
  ASSERT_TRUE(store) << store.error().message;
  const geo::TileId root{10, 530, 350};
  const TileKey first{TileKind::terrain, 0, root};
  const TileKey later{TileKind::terrain, 0, root.children()[0]};
  const TileKey needed_now{TileKind::terrain, 0, root.children()[1]};
  auto source = std::make_shared<CountingSource>(*store, needed_now);
  auto layers = source->layers({});
  ASSERT_TRUE(layers) << layers.error().message;
  TileLoader loader(source, *layers, nullptr, LoaderOptions{1, 1});
  std::atomic<int> callbacks{0};
  std::atomic<bool> release{false};
  loader.set_result_callback(hold_first_result(callbacks, release));
  loader.submit({{first, 3, 1}, {later, -1, 1}, {needed_now, -2, 1}});
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  // The -2 tile is downloading (its fetch waits at the gate): the worker popped the other two
  // before it, one at a time. And the decoder is held in the first result's callback (without
  // this wait, a decoder slower than the worker found all three payloads waiting and took the
  // raised one first: 2 of 200 runs under load).
  while ((!source->entered.load() || callbacks.load() == 0) &&
         std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_TRUE(source->entered.load());
  ASSERT_EQ(callbacks.load(), 1);
  loader.submit({{needed_now, 5, 1}});  // in flight: nothing is queued again
  EXPECT_EQ(loader.counters().queued, 0u);
  source->open = true;
  // Both payloads wait for the held decoder.
  while (loader.counters().decode_queued < 2 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(loader.counters().decode_queued, 2u);
  release = true;
  expect_loaded_in_order(loader, {first, needed_now, later}, until);
  loader.set_result_callback(nullptr);
}

TEST(TileStreamer, AbsentChildrenAreCoveredByTheirParentsQuadrant) {
  SyntheticLayer layer = testing::default_layer();
  // Leave out the south-east 2×2 block: the level-11 tile 11/1061/701 does not exist.
  std::erase_if(layer.finest, [](const geo::TileId& t) { return t.x >= 2122 && t.y >= 1402; });
  Fixture fx("streamer_absent", layer);
  StreamerOptions options;
  options.max_sse = 0.01;
  TileStreamer s(*fx.loader, options);
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  ASSERT_TRUE(
      run_until_complete(s, *fx.loader, above(c.lon, c.lat, 60000), gpu, [&](const FrameResult& f) {
        if (!f.draws.empty()) expect_partition_of_root(f, {10, 530, 350});
      }));
  const FrameResult& f = s.last_frame();
  EXPECT_EQ(f.drawn_per_level[12], 12u);
  ASSERT_EQ(f.drawn_per_level[10], 1u);
  for (const DrawItem& d : f.draws)
    if (d.key.tile.z == 10) {
      EXPECT_EQ(d.quadrant_mask, 0b1000);
    }
  EXPECT_EQ(s.level_counters()[11].absent, 1u);
  s.release_all(gpu);
}

TEST(TileStreamer, GpuAndRamBudgetsHoldWithinOneTileAndEvictionsAndNewTilesTrimTheHeap) {
  Fixture fx("streamer_budget");
  StreamerOptions options;
  options.max_sse = 0.01;
  options.gpu_budget = 40000;  // a few tiles of 9×9 vertices (≈ 3 KB each)… too few for the view
  options.ram_budget = 30000;
  options.heap_trim_interval = std::chrono::milliseconds(0);  // every frame that may trim does
  options.idle_heap_trim_interval = std::chrono::milliseconds(-1);  // and only those
  // Evictions from both tiers plus meshes received: what makes a frame trim the heap.
  const auto churn = [](const TileStreamer& t) {
    std::uint64_t loaded = 0;
    for (const LevelCounters& l : t.level_counters()) loaded += l.loaded;
    return t.gpu_counters().evictions + t.ram_counters().evictions + loaded;
  };
  TileStreamer s(*fx.loader, options);
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  const Camera camera = above(c.lon, c.lat, 60000);
  // At least 200 frames, and on until the RAM tier has evicted, however slowly tiles arrive (the
  // deadline only stops a broken streamer from hanging the suite). The GPU tier refuses rather
  // than evicts here: everything it holds is drawn or on the path to what is drawn.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  std::uint64_t frames_that_churned = 0;
  for (int i = 0; i < 200 || s.ram_counters().evictions == 0; ++i) {
    ASSERT_LT(std::chrono::steady_clock::now(), until) << "the RAM tier never evicted";
    const std::uint64_t churn_before = churn(s);
    const std::uint64_t trims_before = s.heap_trims();
    s.update(camera, gpu);
    const TierCounters& g = s.gpu_counters();
    ASSERT_LE(g.bytes, g.budget + g.largest_entry);
    ASSERT_LE(s.ram_counters().bytes, s.ram_counters().budget + s.ram_counters().largest_entry);
    ASSERT_EQ(static_cast<std::uint64_t>(gpu.alive_bytes), g.bytes);
    // A frame trims the heap exactly when it evicted something or received tiles.
    const bool churned = churn(s) > churn_before;
    ASSERT_EQ(s.heap_trims() - trims_before, churned ? 1u : 0u) << "frame " << i;
    frames_that_churned += churned ? 1 : 0;
    fx.loader->wait_for_results(std::chrono::milliseconds(5));
  }
  EXPECT_GT(s.gpu_counters().inserts, 0u);
  EXPECT_GT(frames_that_churned, 0u);
  EXPECT_EQ(s.heap_trims(), frames_that_churned);
  s.release_all(gpu);
}

}  // namespace
// A view that stopped changing (nothing evicted, nothing new) still trims the heap, on the idle
// period: memory freed elsewhere (a software rasteriser's frame bins) goes back to the system too.
TEST(TileStreamer, AnUnchangingViewTrimsTheHeapOnTheIdlePeriodOnly) {
  Fixture fx("streamer_idle_trim");
  StreamerOptions options;
  options.max_sse = 0.01;
  options.heap_trim_interval = std::chrono::milliseconds(0);
  options.idle_heap_trim_interval = std::chrono::milliseconds(40);
  TileStreamer s(*fx.loader, options);
  CountingUploader gpu;
  const geo::LonLat c = block_centre();
  const Camera camera = above(c.lon, c.lat, 60000);
  ASSERT_TRUE(run_until_complete(s, *fx.loader, camera, gpu));
  s.update(camera, gpu);  // the last arrivals' trim, if any
  const std::uint64_t loaded = s.level_counters()[12].loaded;
  const std::uint64_t trims_before = s.heap_trims();
  const auto start = std::chrono::steady_clock::now();
  std::uint64_t frames = 0;
  while (std::chrono::steady_clock::now() - start < std::chrono::milliseconds(400)) {
    s.update(camera, gpu);
    ++frames;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const auto elapsed_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::steady_clock::now() - start)
                              .count();
  ASSERT_EQ(s.level_counters()[12].loaded, loaded);  // nothing new: only idle trims below
  ASSERT_EQ(s.gpu_counters().evictions + s.ram_counters().evictions, 0u);
  const std::uint64_t idle_trims = s.heap_trims() - trims_before;
  EXPECT_GE(idle_trims, 2u) << frames << " frames in " << elapsed_ms << " ms";
  // At most one per started 40 ms, far fewer than frames.
  EXPECT_LE(idle_trims, static_cast<std::uint64_t>(elapsed_ms / 40 + 1));
  EXPECT_LT(idle_trims, frames);

  // Off (-1): an unchanging view never trims.
  StreamerOptions off = options;
  off.idle_heap_trim_interval = std::chrono::milliseconds(-1);
  TileStreamer quiet(*fx.loader, off);
  ASSERT_TRUE(run_until_complete(quiet, *fx.loader, camera, gpu));
  quiet.update(camera, gpu);
  const std::uint64_t quiet_before = quiet.heap_trims();
  for (int i = 0; i < 50; ++i) {
    quiet.update(camera, gpu);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(quiet.heap_trims(), quiet_before);
  s.release_all(gpu);
  quiet.release_all(gpu);
}

}  // namespace tinstream::client
