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

// `file` (in the shared data) ingested at `max_points` into `ts`; `store` stays empty when the file
// is not there (the test is skipped) or the ingest failed.
struct Ingested {
  std::optional<store::TileStore> store;
  store::LayerInfo info;
};
void ingest_lidar(const char* file, std::uint32_t max_points, const testing::TempStore& ts,
                  Ingested& out) {
  const std::filesystem::path las = std::filesystem::path(TINSTREAM_SHARED_DATA) / file;
  if (!std::filesystem::exists(las)) GTEST_SKIP() << las << " not found";
  ingest::IngestOptions o;
  o.store_path = ts.dir / "lidar.sqlite";
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
  out.info = *store->layer("a");
  out.store.emplace(std::move(*store));
}

// The finest level's data points (the vertices of its data triangles), by finest tile.
std::map<geo::TileId, std::vector<GreedyPoint>> finest_data(Ingested& lidar) {
  std::map<geo::TileId, std::vector<GreedyPoint>> out;
  const auto finest_ids = lidar.store->tile_ids("a", lidar.info.max_level);
  EXPECT_TRUE(finest_ids.ok());
  if (!finest_ids.ok()) return out;
  for (const auto& id : *finest_ids) {
    const tile::TinTile t = **lidar.store->read_tile("a", id);
    const auto mask = t.footprint_mask();
    std::map<std::pair<double, double>, double> data;  // one of each position
    for (std::size_t k = 0; k < t.triangles.size(); ++k) {
      if (!mask[k]) continue;
      for (const auto i : t.triangles[k]) data[{t.vertex(i).x, t.vertex(i).y}] = t.vertex(i).z;
    }
    for (const auto& [xy, z] : data) out[id].push_back({xy.first, xy.second, z});
  }
  return out;
}

// `file` (in the shared data, at least `least_points` finest data points) ingested at
// `max_points`: every level whose one tile holds the data, its stored tile's max error over the
// finest data points at most `bound` × greedy insertion's with as many vertices. Levels with more
// than `most_vertices` vertices are left out.
void one_tile_levels_against_greedy(const char* file, std::size_t least_points,
                                    std::uint32_t max_points, double bound,
                                    std::size_t most_vertices) {
  testing::TempStore ts("lidar-greedy");
  Ingested lidar;
  ingest_lidar(file, max_points, ts, lidar);
  if (!lidar.store) return;
  const auto& info = lidar.info;
  auto& store = lidar.store;
  // The finest level's data points, one of each position.
  std::map<std::pair<double, double>, double> data;
  for (const auto& [id, points] : finest_data(lidar)) {
    for (const auto& p : points) data[{p.x, p.y}] = p.z;
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

// The data footprint of a tile (its triangles without a NODATA vertex), with bounding boxes.
class Footprint {
 public:
  explicit Footprint(const tile::TinTile& t) : t_(t) {
    for (std::size_t k = 0; k < t.triangles.size(); ++k) {
      if (t.is_nodata_triangle(k)) continue;
      std::array<double, 4> b{
          std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
      for (const auto i : t.triangles[k]) {
        const auto& v = t.vertex(i);
        b = {std::min(b[0], v.x), std::min(b[1], v.y), std::max(b[2], v.x), std::max(b[3], v.y)};
      }
      data_.push_back(k);
      boxes_.push_back(b);
    }
  }
  // The distance from (x, y) to the footprint: 0 inside a data triangle (its sides included, up
  // to rounding), else to the nearest side of one.
  double distance(double x, double y) const {
    for (std::size_t d = 0; d < data_.size(); ++d) {
      const auto& b = boxes_[d];
      if (x < b[0] || x > b[2] || y < b[1] || y > b[3]) continue;
      const auto& [a, p, c] = corners(d);
      const double det = (p.x - a.x) * (c.y - a.y) - (p.y - a.y) * (c.x - a.x);
      const double wb = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
      const double wc = ((p.x - a.x) * (y - a.y) - (p.y - a.y) * (x - a.x)) / det;
      if (std::min({1 - wb - wc, wb, wc}) >= -1e-9) return 0;
    }
    auto segment = [&](const tile::Vertex& a, const tile::Vertex& b) {
      const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
      const double s =
          len2 > 0 ? std::clamp(((x - a.x) * dx + (y - a.y) * dy) / len2, 0.0, 1.0) : 0.0;
      return std::hypot(x - (a.x + s * dx), y - (a.y + s * dy));
    };
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t d = 0; d < data_.size(); ++d) {
      const auto& [a, p, c] = corners(d);
      best = std::min({best, segment(a, p), segment(p, c), segment(c, a)});
    }
    return best;
  }

 private:
  std::array<tile::Vertex, 3> corners(std::size_t d) const {
    const auto& tri = t_.triangles[data_[d]];
    return {t_.vertex(tri[0]), t_.vertex(tri[1]), t_.vertex(tri[2])};
  }
  const tile::TinTile& t_;
  std::vector<std::size_t> data_;             // the data triangles
  std::vector<std::array<double, 4>> boxes_;  // theirs: min x, min y, max x, max y
};

// `file` ingested at `max_points`: on every level above the finest, each finest data point lies
// within one quantized-mesh step (the tile's width / 32767) of its tile's data footprint. That
// step is the thinning's outline tolerance (greedy.hpp, coverage first: a point farther beyond a
// fan's data edge goes in before any other; the drop stage keeps the vertices next to a NODATA
// corner, and an exchange step moves one only within the step), so a client that draws the
// footprint only shows all the data to within what it can show.
void data_within_a_step_of_every_footprint(const char* file, std::uint32_t max_points) {
  testing::TempStore ts("lidar-coverage");
  Ingested lidar;
  ingest_lidar(file, max_points, ts, lidar);
  if (!lidar.store) return;
  const auto data = finest_data(lidar);
  ASSERT_FALSE(data.empty());
  for (std::uint32_t z = lidar.info.min_level; z < lidar.info.max_level; ++z) {
    const auto ids = lidar.store->tile_ids("a", z);
    ASSERT_TRUE(ids.ok());
    const std::uint32_t shift = lidar.info.max_level - z;
    for (const auto& id : *ids) {
      const tile::TinTile t = **lidar.store->read_tile("a", id);
      const double step = id.bounds().width() / 32767.0;
      const Footprint footprint(t);
      double farthest = 0;
      for (const auto& [fid, points] : data) {
        if ((fid.x >> shift) != id.x || (fid.y >> shift) != id.y) continue;
        for (const auto& p : points) farthest = std::max(farthest, footprint.distance(p.x, p.y));
      }
      EXPECT_LE(farthest, step) << "tile " << id.to_string() << ": a data point " << farthest / step
                                << " quantized-mesh steps outside its footprint";
    }
  }
}

// nm_4_6_crop.las (default --max-points, one tile a level from 18 up; levels 10-0 thinned again
// from their sources, parent.cpp) and autzen_trim.las at --max-points 2048: the re-thinned tiles
// leave more of the data's edge under their fans than the child they replace (nm levels 10-0:
// 82-293 of 9,407 points, not 12), all of it within the step (0.63 of one at most;
// bench/lod/RESULTS.md 2026-11-28 17:00).
TEST(PyramidQuality, LidarDataLieWithinAStepOfEveryFootprint) {
  data_within_a_step_of_every_footprint("nm_4_6_crop.las", 16384);
  data_within_a_step_of_every_footprint("autzen_trim.las", 2048);
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
