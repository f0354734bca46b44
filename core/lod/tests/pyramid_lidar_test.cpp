// The stored pyramid of a real LiDAR file against greedy insertion from its finest data (#20): on
// every level whose one tile holds the data, the stored tile's largest vertical error over the
// finest level's data points (the input points and the finest tiles' edge points, the points the
// recorded error is measured at) is not far above that of a greedy-insertion TIN of those same
// points with as many vertices (point_greedy.hpp: CGAL's Delaunay TIN, its own
// bookkeeping). Both errors are evaluated here by brute force, independently of core/lod.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "point_greedy.hpp"
#include "temp_store.hpp"
#include "tinstream/ingest/ingest.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::lod {
namespace {

using ::tinstream::testing::GreedyPoint;

// The height of `t` at (x, y) by brute force over its triangles (bounding boxes first): the
// triangle with the largest smallest barycentric weight.
double tile_height(const tile::TinTile& t, const std::vector<std::array<double, 4>>& boxes,
                   double x, double y) {
  const auto v = t.vertices();
  double best_w = -std::numeric_limits<double>::infinity(), best_h = 0;
  for (std::size_t k = 0; k < t.triangles.size(); ++k) {
    const auto& b = boxes[k];
    if (x < b[0] || x > b[2] || y < b[1] || y > b[3]) continue;
    const auto& tr = t.triangles[k];
    const auto &a = v[tr[0]], &p = v[tr[1]], &c = v[tr[2]];
    const double det = (p.x - a.x) * (c.y - a.y) - (p.y - a.y) * (c.x - a.x);
    const double wb = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
    const double wc = ((p.x - a.x) * (y - a.y) - (p.y - a.y) * (x - a.x)) / det;
    const double w = std::min({1 - wb - wc, wb, wc});
    if (w > best_w) best_w = w, best_h = (1 - wb - wc) * a.z + wb * p.z + wc * c.z;
  }
  return best_h;
}

double max_error(const tile::TinTile& t, const std::vector<GreedyPoint>& pts) {
  const auto v = t.vertices();
  std::vector<std::array<double, 4>> boxes;
  for (const auto& tr : t.triangles) {
    std::array<double, 4> b{v[tr[0]].x, v[tr[0]].y, v[tr[0]].x, v[tr[0]].y};
    for (const auto i : tr) {
      b[0] = std::min(b[0], v[i].x), b[1] = std::min(b[1], v[i].y);
      b[2] = std::max(b[2], v[i].x), b[3] = std::max(b[3], v[i].y);
    }
    boxes.push_back(b);
  }
  double e = 0;
  for (const auto& p : pts) e = std::max(e, std::abs(tile_height(t, boxes, p.x, p.y) - p.z));
  return e;
}

// `file` (in the shared data, at least `least_points` finest data points) ingested at
// `max_points`: every level whose one tile holds the data, its stored tile's max error over the
// finest data points at most `bound` × greedy insertion's with as many vertices. Levels with more
// than `most_vertices` vertices are left out.
void one_tile_levels_against_greedy(const char* file, std::size_t least_points,
                                    std::uint32_t max_points, double bound,
                                    std::size_t most_vertices) {
  const std::filesystem::path las = std::filesystem::path(TINSTREAM_SHARED_DATA) / file;
  if (!std::filesystem::exists(las)) GTEST_SKIP() << las << " not found";
  testing::TempStore ts("lidar-greedy");
  ingest::IngestOptions o;
  o.store_path = ts.dir / "autzen.sqlite";
  o.layer = "a";
  transform::InputSpec in;
  in.path = las;
  o.inputs.push_back(in);
  o.max_points = max_points;
  o.threads = 2;
  o.tmp_dir = ts.dir;
  auto summary = ingest::run_ingest(o);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  auto store = store::TileStore::open(o.store_path, store::TileStore::Mode::read_only);
  ASSERT_TRUE(store.ok());
  const auto info = *store->layer("a");

  // The finest level's data points, one of each position.
  std::map<std::pair<double, double>, double> data;
  const auto finest_ids = store->tile_ids("a", info.max_level);
  ASSERT_TRUE(finest_ids.ok());
  for (const auto& id : *finest_ids) {
    const tile::TinTile t = **store->read_tile("a", id);
    const auto mask = t.footprint_mask();
    for (std::size_t k = 0; k < t.triangles.size(); ++k) {
      if (!mask[k]) continue;
      for (const auto i : t.triangles[k]) data[{t.vertex(i).x, t.vertex(i).y}] = t.vertex(i).z;
    }
  }
  std::vector<GreedyPoint> pts;
  pts.reserve(data.size());
  for (const auto& [xy, z] : data) pts.push_back({xy.first, xy.second, z});
  ASSERT_GT(pts.size(), least_points);

  // The one-tile levels, fewest vertices first (one greedy run serves them all).
  struct Level {
    std::uint32_t z;
    std::size_t vertices;
    double ours;
  };
  std::vector<Level> levels;
  for (std::uint32_t z = info.min_level; z < info.max_level; ++z) {
    const auto ids = store->tile_ids("a", z);
    ASSERT_TRUE(ids.ok());
    if (ids->size() != 1) continue;
    const tile::TinTile t = **store->read_tile("a", ids->front());
    if (t.vertex_count() > most_vertices) continue;
    levels.push_back({z, t.vertex_count(), max_error(t, pts)});
  }
  ASSERT_GE(levels.size(), 5u);
  std::sort(levels.begin(), levels.end(),
            [](const Level& a, const Level& b) { return a.vertices < b.vertices; });
  ::tinstream::testing::PointGreedy greedy(pts);
  for (const Level& l : levels) {
    while (greedy.vertices() < l.vertices && greedy.step()) {
    }
    const double peer = greedy.max_error();
    EXPECT_LE(l.ours, bound * peer)
        << "level " << l.z << " (" << l.vertices << " vertices): stored " << l.ours << " m, greedy "
        << peer << " m";
  }
}

// autzen_trim.las at --max-points 2048 (levels 0–20; one tile holds the data from level 16 up).
// Until 2026-11-28 the finest tiles' edge points weighed 0 beside inputs of weight 1, and coverage
// first took the points of largest error against the fans' continued heights: level 16 measured
// 3.1×, level 15 2.5×, levels 14–0 1.7–1.8× greedy insertion's error (bench/lod/RESULTS.md); now
// 0.45–0.88×. The bound, 1.25×, leaves room for the thinning's own choices.
TEST(PyramidQuality, LidarOneTileLevelsAreNotFarBehindGreedyInsertion) {
  one_tile_levels_against_greedy("autzen_trim.las", 20000, 2048, 1.25,
                                 std::numeric_limits<std::size_t>::max());
}

// autzen_trim.las at the default --max-points (16,384): levels 12–0 keep the outline floor, 128
// vertices, thinned with exchange steps (parent.hpp, "Budget"). Until 2026-11-28 (no exchange
// steps) they measured 0.851 m against greedy insertion's 0.896 m, 0.95×; now 0.724 m, 0.81×
// (bench/lod/RESULTS.md, "exchange steps at the outline floor"). #20's target is 0.9×.
TEST(PyramidQuality, LidarOutlineFloorLevelsMeetTheTargetAgainstGreedyInsertion) {
  one_tile_levels_against_greedy("autzen_trim.las", 20000, 16384, 0.9, 128);
}

// nm_4_6_crop.las at the default --max-points: one tile holds the data from level 18 up, and
// levels 13–0 take their one child's 128 vertices. Until 2026-11-28 levels 10–0 measured
// 0.573–0.576 m against level 11's 0.198 m, 1.78× greedy insertion's error: their corners, farther
// out, let the Delaunay triangulation join three nearly collinear outline vertices into a flat
// data triangle whose long side the data's edge points measured (parent.cpp; bench/lod/RESULTS.md
// 2026-11-28 15:00); now such a parent is thinned from its sources: 0.191–0.202 m.
TEST(PyramidQuality, LidarOneChildLevelsKeepTheChildsQuality) {
  one_tile_levels_against_greedy("nm_4_6_crop.las", 5000, 16384, 0.9, 128);
}

}  // namespace
}  // namespace tinstream::lod
