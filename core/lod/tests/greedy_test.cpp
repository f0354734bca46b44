// The greedy-insertion stage of thin_tile (LodOptions::greedy_factor): inputs much larger than
// the budget are first built up by greedy insertion, then thinned by the drop heuristic.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "lod_test_support.hpp"
#include "tinstream/lod/error.hpp"
#include "tinstream/lod/thinning.hpp"

namespace tinstream::lod {
namespace {

using testing::brute_height;
using testing::grid_tile;
using tile::Vertex;

using testing::kTile;

// A few hills and ridges across the tile (z = 10 tiles are ~1e-3 wide in normalised Mercator).
double rough(double x, double y) {
  return 300.0 + 40.0 * std::sin(x * 1.9e4) * std::cos(y * 1.3e4) +
         15.0 * std::sin(x * 5.0e4 + y * 3.1e4);
}

TEST(Greedy, PlaneInsertsNothing) {
  const auto full =
      grid_tile(kTile, 64, [](double x, double y) { return 50.0 + 800.0 * x - 300.0 * y; });
  LodOptions o;
  o.max_points = 100;  // 65² points ≫ 1.25 × 100: the greedy stage runs
  ThinStats st;
  auto t = thin_tile(thin_input(full), o, &st);
  ASSERT_TRUE(t.ok()) << t.error().message;
  EXPECT_EQ(st.greedy_inserted, 0u);  // every interior point lies on the border's plane
  EXPECT_TRUE(t->interior.empty());
  EXPECT_EQ(st.greedy_error, 0.0);
  EXPECT_TRUE(tile::check_structure(*t).ok());
}

TEST(Greedy, SingleSpikeIsTheOnePointKept) {
  const geo::MercatorRect r = kTile.bounds();
  const double h = r.width() / 64;
  const double sx = r.min_x + 41 * h, sy = r.max_y - 17 * h;
  // Gentle hills everywhere (so that every point has some error) and one 25 m spike.
  auto f = [&](double x, double y) {
    return 100.0 + 3.0 * std::sin(x * 3e4) * std::cos(y * 2e4) + (x == sx && y == sy ? 25.0 : 0.0);
  };
  const auto full = grid_tile(kTile, 64, f);
  LodOptions o;
  o.border_points_per_side = 2;
  o.max_points = 4 + 4 * 2 + 1;  // the fixed points and exactly one greedy insertion
  o.greedy_factor = 1.0;
  ThinStats st;
  auto t = thin_tile(thin_input(full), o, &st);
  ASSERT_TRUE(t.ok()) << t.error().message;
  // The spike goes in first; settling may add a point or two next to it (the tent it raises
  // over the big border triangles), which the drop stage then removes again.
  EXPECT_GE(st.greedy_inserted, 1u);
  EXPECT_LE(st.greedy_inserted, 3u);
  ASSERT_EQ(t->interior.size(), 1u);
  EXPECT_EQ(t->interior[0].x, sx);
  EXPECT_EQ(t->interior[0].y, sy);
}

// Scattered interior points (no cocircular ties): with greedy_factor 1 the drop stage removes
// nothing, so the reported error of the greedy stage is the final mesh's; checked against a
// brute-force evaluation at every input point left out.
TEST(Greedy, ReportedErrorIsTheBruteForceMaximum) {
  const auto lattice = grid_tile(kTile, 32, rough);
  ThinInput in = thin_input(lattice);
  const geo::MercatorRect r = kTile.bounds();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(r.min_x + r.width() * 1e-3, r.max_x - r.width() * 1e-3);
  std::uniform_real_distribution<double> uy(r.min_y + r.height() * 1e-3,
                                            r.max_y - r.height() * 1e-3);
  in.interior.clear();
  for (int i = 0; i < 3000; ++i) {
    const double x = ux(rng), y = uy(rng);
    in.interior.push_back({x, y, rough(x, y), 0});
  }
  for (std::size_t budget : {40u, 200u, 600u}) {
    LodOptions o;
    o.max_points = budget;
    o.greedy_factor = 1.0;
    ThinStats st;
    auto t = thin_tile(in, o, &st);
    ASSERT_TRUE(t.ok()) << t.error().message;
    ASSERT_GT(st.greedy_inserted, 0u);
    EXPECT_EQ(t->vertex_count(), budget);
    EXPECT_TRUE(tile::check_structure(*t).ok());
    double brute = 0;
    std::size_t left_out = 0;
    for (const auto& p : in.interior) {
      const bool kept = std::any_of(t->interior.begin(), t->interior.end(),
                                    [&](const Vertex& v) { return v.x == p.x && v.y == p.y; });
      if (kept) continue;
      ++left_out;
      const auto z = brute_height(*t, p.x, p.y, false);
      ASSERT_TRUE(z.has_value());
      brute = std::max(brute, std::abs(*z - p.z));
    }
    EXPECT_EQ(left_out, in.interior.size() - t->interior.size());
    EXPECT_GT(brute, 0.0);
    EXPECT_NEAR(st.greedy_error, brute, 1e-9 * (1 + brute)) << "budget " << budget;
  }
}

// Enough points that the greedy stage's pool of filed points is compacted (in place) many times
// on the way: every point left out is still filed under the triangle that holds it, so the
// reported error is the brute-force maximum over them.
TEST(Greedy, ErrorAfterManyCompactionsIsTheBruteForceMaximum) {
  const geo::MercatorRect r = kTile.bounds();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(r.min_x + r.width() * 1e-3, r.max_x - r.width() * 1e-3);
  std::uniform_real_distribution<double> uy(r.min_y + r.height() * 1e-3,
                                            r.max_y - r.height() * 1e-3);
  ThinInput in = thin_input(grid_tile(kTile, 8, rough));
  in.interior.clear();
  for (int i = 0; i < 20000; ++i) {
    const double x = ux(rng), y = uy(rng);
    in.interior.push_back({x, y, rough(x, y), 0});
  }
  LodOptions o;
  o.max_points = 400;
  o.greedy_factor = 1.0;
  ThinStats st;
  auto t = thin_tile(in, o, &st);
  ASSERT_TRUE(t.ok()) << t.error().message;
  ASSERT_GT(st.greedy_inserted, 300u);
  EXPECT_TRUE(tile::check_structure(*t).ok());
  std::vector<std::pair<double, double>> kept;
  for (const auto& v : t->interior) kept.emplace_back(v.x, v.y);
  std::sort(kept.begin(), kept.end());
  double brute = 0;
  for (const auto& p : in.interior) {
    if (std::binary_search(kept.begin(), kept.end(), std::pair{p.x, p.y})) continue;
    const auto z = brute_height(*t, p.x, p.y, false);
    ASSERT_TRUE(z.has_value());
    brute = std::max(brute, std::abs(*z - p.z));
  }
  EXPECT_GT(brute, 0.0);
  EXPECT_NEAR(st.greedy_error, brute, 1e-9 * (1 + brute));
}

TEST(Greedy, NeighboursThinnedSeparatelyStayWatertight) {
  const geo::TileId east{kTile.z, kTile.x + 1, kTile.y};
  std::vector<tile::TinTile> level = {grid_tile(kTile, 64, rough), grid_tile(east, 64, rough)};
  ASSERT_TRUE(check_level_watertight(level).ok());
  LodOptions o;
  o.max_points = 150;
  for (auto& t : level) {
    ThinStats st;
    ASSERT_TRUE(reduce_finest_tile(t, o, &st).ok());
    EXPECT_GT(st.greedy_inserted, 0u);
    EXPECT_LE(t.vertex_count(), o.max_points);
  }
  const Status s = check_level_watertight(level);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  EXPECT_EQ(level[0].east.size(), level[1].west.size());
}

TEST(Greedy, RejectsANegativeFactor) {
  const auto full = grid_tile(kTile, 8, rough);
  LodOptions o;
  o.greedy_factor = -1;
  EXPECT_FALSE(thin_tile(thin_input(full), o).ok());
}

}  // namespace
}  // namespace tinstream::lod
