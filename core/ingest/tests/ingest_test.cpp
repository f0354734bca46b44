#include "tinstream/ingest/ingest.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <random>

#include "tinstream/ingest/verify.hpp"
#include "tinstream/lod/error.hpp"

namespace tinstream::ingest {
namespace {

namespace fs = std::filesystem;

class IngestTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tinstream-ingest-test-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Hilly synthetic terrain near Zürich as lon/lat/height text (EPSG:4326).
  fs::path write_xyz(const std::string& name, std::size_t n, std::uint64_t seed) {
    fs::path p = dir_ / name;
    std::ofstream out(p);
    out.precision(12);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (std::size_t i = 0; i < n; ++i) {
      const double lon = 8.5 + 0.02 * u(rng), lat = 47.3 + 0.02 * u(rng);
      out << lon << " " << lat << " " << 400 + 80 * std::sin(lon * 300) * std::cos(lat * 250)
          << "\n";
    }
    return p;
  }

  IngestOptions options(const std::vector<fs::path>& inputs, const std::string& layer) {
    IngestOptions o;
    o.store_path = dir_ / "store.sqlite";
    o.layer = layer;
    for (const auto& p : inputs) {
      transform::InputSpec in;
      in.path = p;
      in.reproject.crs = "EPSG:4326";
      o.inputs.push_back(in);
    }
    o.max_points = 500;
    o.threads = 2;
    o.tmp_dir = dir_ / "tmp";
    o.memory_bytes = 1 << 20;
    return o;
  }

  fs::path dir_;
};

TEST_F(IngestTest, XyzIngestPublishesAVerifiedLayer) {
  const auto xyz = write_xyz("hills.xyz", 20000, 1);
  auto summary = run_ingest(options({xyz}, "hills"));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->records_read, 20000u);
  EXPECT_EQ(summary->points, 20000u);
  EXPECT_GT(summary->tiles, 16u);
  EXPECT_GT(summary->finest_level, 10u);
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_only);
  ASSERT_TRUE(store.ok());
  auto layer = store->layer("hills");
  ASSERT_TRUE(layer.ok());
  EXPECT_EQ(layer->point_count, 20000u);
  EXPECT_NEAR(layer->bounds.west, 8.5, 1e-3);
  EXPECT_NEAR(layer->bounds.north, 47.32, 1e-3);
  auto report = verify_layer(*store, "hills");
  ASSERT_TRUE(report.ok()) << report.error().message;
  for (const auto& m : report->messages) ADD_FAILURE() << m;
  EXPECT_TRUE(report->ok());
  EXPECT_GT(report->shared_borders, 10u);
  // Temporary files are gone.
  EXPECT_TRUE(!fs::exists(dir_ / "tmp") || fs::is_empty(dir_ / "tmp"));
}

TEST_F(IngestTest, BadInputLeavesThePublishedLayerUntouched) {
  const auto good = write_xyz("good.xyz", 5000, 2);
  ASSERT_TRUE(run_ingest(options({good}, "terrain")).ok());
  auto before_store =
      store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_only);
  const auto before = before_store->layer("terrain");
  ASSERT_TRUE(before.ok());

  const fs::path bad = dir_ / "bad.xyz";
  {
    std::ofstream out(bad);
    out << "8.5 47.3 400\n8.51 47.31 nan\n";
  }
  auto failed = run_ingest(options({good, bad}, "terrain"));
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.error().message.find("bad.xyz"), std::string::npos) << failed.error().message;

  auto after_store =
      store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_only);
  const auto after = after_store->layer("terrain");
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(after->version, before->version);
  EXPECT_EQ(after->tile_count, before->tile_count);
  auto report = verify_layer(*after_store, "terrain");
  ASSERT_TRUE(report.ok());
  EXPECT_TRUE(report->ok());
}

TEST_F(IngestTest, PointsOutsideTheMercatorRangeAreRejectedByRecord) {
  const fs::path polar = dir_ / "polar.xyz";
  {
    std::ofstream out(polar);
    out << "10 60 5\n10 89.5 5\n";
  }
  auto r = run_ingest(options({polar}, "polar"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("polar.xyz"), std::string::npos) << r.error().message;
}

TEST_F(IngestTest, ReingestReplacesTheLayer) {
  ASSERT_TRUE(run_ingest(options({write_xyz("a.xyz", 3000, 3)}, "t")).ok());
  auto second = run_ingest(options({write_xyz("b.xyz", 6000, 4)}, "t"));
  ASSERT_TRUE(second.ok()) << second.error().message;
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_only);
  EXPECT_EQ(store->layer("t")->point_count, 6000u);
  auto report = verify_layer(*store, "t");
  ASSERT_TRUE(report.ok());
  EXPECT_TRUE(report->ok());
}

TEST_F(IngestTest, InvalidOptionsRejectedUpFront) {
  auto o = options({write_xyz("c.xyz", 10, 5)}, "bad/name");
  EXPECT_FALSE(run_ingest(o).ok());
  o.layer = "ok";
  o.max_points = 70000;
  EXPECT_FALSE(run_ingest(o).ok());
  o.max_points = 100;
  o.inputs.clear();
  EXPECT_FALSE(run_ingest(o).ok());
}

TEST_F(IngestTest, VerifyDetectsATamperedBorder) {
  ASSERT_TRUE(run_ingest(options({write_xyz("d.xyz", 8000, 6)}, "v")).ok());
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_write);
  ASSERT_TRUE(store.ok());
  const auto info = *store->layer("v");
  const auto ids = store->tile_ids("v");
  ASSERT_TRUE(ids.ok());
  // Re-publish the layer with one tile whose east border point is nudged.
  auto writer = store->begin_layer(info);
  ASSERT_TRUE(writer.ok());
  bool tampered = false;
  for (const auto& id : *ids) {
    auto t = **store->read_tile("v", id);
    if (!tampered && id.z == info.max_level && !t.east.empty()) {
      t.east[0].z += 0.5;
      tampered = true;
    }
    ASSERT_TRUE((*writer)->put(t).ok());
  }
  ASSERT_TRUE(tampered);
  ASSERT_TRUE((*writer)->publish(info).ok());
  auto report = verify_layer(*store, "v");
  ASSERT_TRUE(report.ok());
  EXPECT_FALSE(report->ok());
  bool mentions = false;
  for (const auto& m : report->messages) mentions |= m.find("not watertight") != std::string::npos;
  EXPECT_TRUE(mentions);
}

// Re-publishes layer `name` with `edit` applied to every tile (and `edit_info` to the layer).
void republish(store::TileStore& store, const std::string& name,
               const std::function<void(tile::TinTile&)>& edit,
               const std::function<void(store::LayerInfo&)>& edit_info = {}) {
  auto info = *store.layer(name);
  const auto ids = store.tile_ids(name);
  ASSERT_TRUE(ids.ok());
  if (edit_info) edit_info(info);
  auto writer = store.begin_layer(info);
  ASSERT_TRUE(writer.ok());
  for (const auto& id : *ids) {
    auto t = **store.read_tile(name, id);
    edit(t);
    ASSERT_TRUE((*writer)->put(t).ok());
  }
  ASSERT_TRUE((*writer)->publish(info).ok());
}

bool mentions(const VerifyReport& r, const std::string& what) {
  for (const auto& m : r.messages) {
    if (m.find(what) != std::string::npos) return true;
  }
  return false;
}

TEST_F(IngestTest, VerifyChecksStoredErrorsAgainstTheFinestSurface) {
  ASSERT_TRUE(run_ingest(options({write_xyz("e.xyz", 8000, 7)}, "e")).ok());
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_write);
  ASSERT_TRUE(store.ok());
  const auto info = *store->layer("e");
  ASSERT_GT(info.max_level, info.min_level + 1);
  auto good = verify_layer(*store, "e");
  ASSERT_TRUE(good.ok());
  EXPECT_TRUE(good->ok()) << (good->messages.empty() ? "" : good->messages.front());
  EXPECT_GT(good->error_checks, 0u);
  EXPECT_GT(good->worst_error_ratio, 0.0);
  EXPECT_LE(good->worst_error_ratio, 1.0);
  // Understate the error of the parents of the finest level (their children's errors are 0, so
  // the monotonicity check cannot see it; only measuring against the finest surface does).
  republish(*store, "e", [&](tile::TinTile& t) {
    if (t.id.z + 1 == info.max_level) t.geometric_error *= 0.25;
  });
  auto bad = verify_layer(*store, "e");
  ASSERT_TRUE(bad.ok());
  EXPECT_FALSE(bad->ok());
  EXPECT_TRUE(mentions(*bad, "below the error measured against the finest surface"));
  EXPECT_GT(bad->worst_error_ratio, 1.0);
  VerifyOptions off;
  off.error_samples = 0;
  auto skipped = verify_layer(*store, "e", off);
  ASSERT_TRUE(skipped.ok());
  EXPECT_TRUE(skipped->ok());
  EXPECT_EQ(skipped->error_checks, 0u);
}

// The vertex sample (lod::measured_max_error) is a lower bound of the surface difference: it misses
// the maxima where a coarse edge crosses a finest edge. A parent of the finest level whose stored
// error lies between the two passes the default check and fails with --surface-error, which names
// the tile, the stored and the overlay maximum. (The LOD's stored errors bound the finest data
// points, not the surface between them, so other tiles of this fresh layer may fail it too.)
TEST_F(IngestTest, VerifySurfaceErrorFindsAnErrorBetweenTheVertexSampleAndTheOverlay) {
  ASSERT_TRUE(run_ingest(options({write_xyz("s.xyz", 8000, 11)}, "s")).ok());
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_write);
  ASSERT_TRUE(store.ok());
  const auto info = *store->layer("s");
  ASSERT_GT(info.max_level, info.min_level);
  const auto ids = store->tile_ids("s");
  ASSERT_TRUE(ids.ok());
  // A parent of the finest level (verify samples all of its at most 4 children) whose overlay
  // maximum exceeds its vertex sample by more than the rounding allowances.
  std::optional<geo::TileId> chosen;
  double vertex = 0, overlay = 0;
  for (const auto& id : *ids) {
    if (id.z + 1 != info.max_level) continue;
    const auto t = **store->read_tile("s", id);
    std::vector<tile::TinTile> children;
    for (const auto& c : id.children()) {
      if (auto ct = store->read_tile("s", c); ct.ok() && ct->has_value()) {
        children.push_back(**ct);
      }
    }
    if (children.empty()) continue;
    std::vector<const tile::TinTile*> fines;
    fines.reserve(children.size());
    for (const auto& c : children) fines.push_back(&c);
    const double v = *lod::measured_max_error(t, children);
    const double o = lod::surface_difference(t, fines).max_abs;
    if (o - v > 4 * lod::error_rounding_allowance(t) + 1e-3) {
      chosen = id, vertex = v, overlay = o;
      break;
    }
  }
  ASSERT_TRUE(chosen.has_value()) << "no parent of the finest level where the overlay matters";
  const double stored = 0.5 * (vertex + overlay);
  republish(*store, "s", [&](tile::TinTile& t) {
    if (t.id == *chosen) t.geometric_error = stored;
  });
  auto plain = verify_layer(*store, "s");
  ASSERT_TRUE(plain.ok());
  EXPECT_TRUE(plain->ok()) << (plain->messages.empty() ? "" : plain->messages.front());
  VerifyOptions strict;
  strict.surface_error = true;
  strict.max_problems = SIZE_MAX;
  auto bad = verify_layer(*store, "s", strict);
  ASSERT_TRUE(bad.ok());
  EXPECT_FALSE(bad->ok());
  EXPECT_GT(bad->worst_surface_ratio, 1.0);
  const std::string expected = "tile " + chosen->quadkey() + " (" + chosen->to_string() +
                               "): stored geometric error " + std::to_string(stored) +
                               " m is below the maximum difference to the finest surface";
  const auto named = std::find_if(bad->messages.begin(), bad->messages.end(),
                                  [&](const auto& m) { return m.rfind(expected, 0) == 0; });
  ASSERT_NE(named, bad->messages.end()) << expected;
  // The measured metres: the overlay maximum over the same tiles (up to the printed digits).
  const std::string tail = named->substr(named->rfind(", ") + 2);
  EXPECT_NEAR(std::stod(tail), overlay, 1e-6) << *named;
}

// #20: an edge point 1e-14 beside a tile corner became a duplicate vertex and zero-area triangles
// in quantized-mesh. A sound layer has neither; one interior vertex moved to 1e-13 from its tile's
// north-west corner is a near-duplicate pair, which verify counts and reports as a problem naming
// the tile; its needles are left out of the quantized-mesh encoding (terrain drops flat
// triangles), so verify finds no zero-area triangle.
TEST_F(IngestTest, VerifyRejectsNearDuplicateVerticesAndFindsNoZeroAreaQuantisedTriangles) {
  ASSERT_TRUE(run_ingest(options({write_xyz("q.xyz", 8000, 9)}, "q")).ok());
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_write);
  ASSERT_TRUE(store.ok());
  const auto info = *store->layer("q");
  auto good = verify_layer(*store, "q");
  ASSERT_TRUE(good.ok());
  EXPECT_TRUE(good->ok()) << (good->messages.empty() ? "" : good->messages.front());
  EXPECT_EQ(good->near_duplicate_pairs, 0u);
  bool moved = false;
  republish(*store, "q", [&](tile::TinTile& t) {
    if (moved || t.id.z != info.max_level || t.interior.empty()) return;
    // The interior vertex nearest the NW corner, so that the move flips no far triangle.
    const auto& nw = t.corners[0];
    auto nearest = std::min_element(
        t.interior.begin(), t.interior.end(), [&](const tile::Vertex& a, const tile::Vertex& b) {
          return std::hypot(a.x - nw.x, a.y - nw.y) < std::hypot(b.x - nw.x, b.y - nw.y);
        });
    nearest->x = nw.x + 1e-13;
    nearest->y = nw.y - 1e-13;
    moved = true;
  });
  ASSERT_TRUE(moved);
  auto bad = verify_layer(*store, "q");
  ASSERT_TRUE(bad.ok());
  EXPECT_EQ(bad->near_duplicate_pairs, 1u);
  EXPECT_FALSE(bad->ok());  // (the move breaks other checks too: Delaunay, the errors above)
  EXPECT_TRUE(mentions(*bad, "1 pairs of vertices closer than 1e-12"));
  EXPECT_FALSE(mentions(*bad, "zero-area triangles in its quantized-mesh encoding"));
  VerifyOptions off;
  off.quantisation = false;
  off.delaunay = false;
  auto unchecked = verify_layer(*store, "q", off);
  ASSERT_TRUE(unchecked.ok());
  EXPECT_EQ(unchecked->near_duplicate_pairs, 0u);
  EXPECT_FALSE(mentions(*unchecked, "zero-area"));
}

// #20 on real data-edge tiles: a LiDAR file (autzen_trim.las, its own CRS) and a DEM with NoData
// outside the country (luxembourg_elev.tif). Some tiles have NODATA corners; no vertex of any tile,
// NODATA corners included, lies outside the data's height range (no walls to the ellipsoid), so
// every height interpolated in a tile, also outside the data's hull, lies within it; verify (the
// recorded errors against the finest surface, near-duplicates, quantized-mesh) passes.
TEST_F(IngestTest, DataEdgeTilesStayWithinTheDataHeights) {
  for (const char* file : {"autzen_trim.las", "luxembourg_elev.tif"}) {
    const fs::path path = fs::path(TINSTREAM_SHARED_DATA) / file;
    if (!fs::exists(path)) GTEST_SKIP() << path << " not found";
    IngestOptions o = options({path}, "d");
    o.inputs.front().reproject.crs.clear();  // the file's own CRS
    o.max_points = 2000;
    o.store_path = dir_ / (std::string(file) + ".sqlite");
    auto summary = run_ingest(o);
    ASSERT_TRUE(summary.ok()) << file << ": " << summary.error().message;
    auto store = store::TileStore::open(o.store_path, store::TileStore::Mode::read_only);
    ASSERT_TRUE(store.ok());
    const auto info = *store->layer("d");
    ASSERT_LT(info.min_level, info.max_level) << file;
    std::size_t nodata_corners = 0;
    const auto ids = store->tile_ids("d");
    ASSERT_TRUE(ids.ok());
    for (const auto& id : *ids) {
      const auto t = **store->read_tile("d", id);
      for (std::size_t i = 0; i < t.vertex_count(); ++i) {
        nodata_corners += t.is_nodata_vertex(i) ? 1 : 0;
        ASSERT_GE(t.vertex(i).z, info.min_z)
            << file << " tile " << id.to_string() << " vertex " << i;
        ASSERT_LE(t.vertex(i).z, info.max_z)
            << file << " tile " << id.to_string() << " vertex " << i;
      }
    }
    EXPECT_GT(nodata_corners, 0u) << file << ": no data-edge tile to check";
    auto report = verify_layer(*store, "d");
    ASSERT_TRUE(report.ok());
    for (const auto& m : report->messages) ADD_FAILURE() << file << ": " << m;
  }
}

TEST_F(IngestTest, VerifyChecksThePointBudget) {
  ASSERT_TRUE(run_ingest(options({write_xyz("b.xyz", 8000, 8)}, "b")).ok());
  auto store = store::TileStore::open(dir_ / "store.sqlite", store::TileStore::Mode::read_write);
  ASSERT_TRUE(store.ok());
  std::size_t largest_coarse = 0;
  const auto info = *store->layer("b");
  const auto ids = store->tile_ids("b");
  ASSERT_TRUE(ids.ok());
  for (const auto& id : *ids) {
    if (id.z < info.max_level) {
      largest_coarse = std::max(largest_coarse, (**store->read_tile("b", id)).vertex_count());
    }
  }
  ASSERT_GT(largest_coarse, 4u);
  ASSERT_LE(largest_coarse, info.max_points);
  // A layer that claims one point less than its fullest coarse tile holds is over budget.
  republish(
      *store, "b", [](tile::TinTile&) {},
      [&](store::LayerInfo& i) { i.max_points = static_cast<std::uint32_t>(largest_coarse - 1); });
  auto report = verify_layer(*store, "b");
  ASSERT_TRUE(report.ok());
  EXPECT_FALSE(report->ok());
  EXPECT_TRUE(mentions(*report, "over the budget of " + std::to_string(largest_coarse - 1)));
}

}  // namespace
}  // namespace tinstream::ingest
