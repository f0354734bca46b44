#include "tinstream/lod/thinning.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lod_test_support.hpp"
#include "tinstream/lod/error.hpp"

namespace tinstream::lod {
namespace {

using testing::grid_tile;
using tile::Vertex;

const geo::TileId kTile{10, 300, 200};

double plane(double x, double y) { return 120.0 + 3000.0 * x - 1700.0 * y; }

TEST(BorderSide, StraightSideThinsToItsCorners) {
  std::vector<Vertex> side;
  for (int i = 0; i <= 64; ++i) side.push_back({i / 64.0, 1.0, 5.0 + 2.0 * i / 64.0, 0});
  const auto kept = thin_border_side(side, true, 1000, 1e-6);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].x, 0.0);
  EXPECT_EQ(kept[1].x, 1.0);
}

TEST(BorderSide, BudgetKeepsTheLargestBreaks) {
  std::vector<Vertex> side;
  for (int i = 0; i <= 100; ++i) side.push_back({1.0, 1.0 - i / 100.0, i == 37 ? 50.0 : 0.0, 0});
  // Along y (east/west sides run north → south, y decreasing).
  const auto kept = thin_border_side(side, false, 1, 0.0);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[1].y, side[37].y);
  EXPECT_EQ(kept[1].z, 50.0);
}

TEST(BorderSide, EpsilonStopsAtTheFirstLargeError) {
  std::vector<Vertex> side;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  for (int i = 0; i <= 200; ++i)
    side.push_back({i / 200.0, 0.0, (i == 100 ? 10.0 : 0.0) + noise(rng), 0});
  std::vector<Vertex> removed;
  const auto kept = thin_border_side(side, true, 1000, 0.5, &removed);
  // Noise < 0.5 everywhere; the spike and the feet on either side of it stay (a chord from
  // farther away to the spike would pass far above the flat ground).
  ASSERT_EQ(kept.size(), 5u);
  EXPECT_EQ(kept[1].x, side[99].x);
  EXPECT_EQ(kept[2].x, side[100].x);
  EXPECT_EQ(kept[3].x, side[101].x);
  EXPECT_EQ(removed.size(), 196u);
}

TEST(BorderSide, WeightKeepsAPointOnAFlatSide) {
  std::vector<Vertex> side;
  for (int i = 0; i <= 20; ++i) side.push_back({i / 20.0, 0.0, 1.0, i == 5 ? 100.0 : 0.0});
  const auto kept = thin_border_side(side, true, 1, 1.0);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[1].x, side[5].x);
}

TEST(BorderSide, SameSideGivesBitIdenticalResultsWithTies) {
  // A lattice on a zig-zag: many equal errors, resolved by position.
  std::vector<Vertex> side;
  for (int i = 0; i <= 64; ++i) side.push_back({i / 64.0, 0.0, (i % 2) ? 1.0 : 0.0, 0});
  const auto a = thin_border_side(side, true, 7, 0.0);
  const auto b = thin_border_side(side, true, 7, 0.0);
  ASSERT_EQ(a.size(), 9u);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].x, b[i].x);
}

TEST(Thinning, PlaneThinsToItsFourCorners) {
  const auto full = grid_tile(kTile, 32, plane);
  ASSERT_EQ(full.vertex_count(), 33u * 33u);
  LodOptions o;
  o.epsilon = 1e-6;
  tile::TinTile t = full;
  ASSERT_TRUE(reduce_finest_tile(t, o).ok());
  EXPECT_EQ(t.vertex_count(), 4u);
  EXPECT_EQ(t.triangles.size(), 2u);
  EXPECT_TRUE(tile::check_structure(t).ok());
  EXPECT_LT(t.geometric_error, 1e-5);
}

TEST(Thinning, BudgetIsRespectedAndStructureValid) {
  auto f = [](double x, double y) { return 100.0 + 40.0 * std::sin(x * 4e4) * std::cos(y * 3e4); };
  const auto full = grid_tile(kTile, 64, f);
  for (std::size_t budget : {8u, 50u, 300u, 1000u}) {
    tile::TinTile t = full;
    LodOptions o;
    o.max_points = budget;
    ThinStats st;
    ASSERT_TRUE(reduce_finest_tile(t, o, &st).ok());
    EXPECT_LE(t.vertex_count(), budget);
    EXPECT_GE(t.vertex_count(), budget - 1);  // epsilon 0: stops at the budget
    EXPECT_TRUE(check_budget(t, budget).ok());
    const Status s = tile::check_structure(t);
    EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
    EXPECT_LE(t.north.size(), side_budget(o));
    EXPECT_EQ(st.input_points, full.vertex_count());
    // The stored error bounds an independent dense evaluation.
    const double measured = testing::sampled_max_difference(t, {full}, 80);
    EXPECT_GE(t.geometric_error, measured) << "budget " << budget;
    EXPECT_GT(measured, 0.0);
  }
}

TEST(Thinning, FlatAreaGoesEarlyWithEpsilon) {
  const geo::MercatorRect r = kTile.bounds();
  const double mid = 0.5 * (r.min_x + r.max_x);
  auto f = [&](double x, double y) {
    if (x <= mid) return 250.0;  // a lake
    return 250.0 + 30.0 * std::sin((x - mid) * 9e4) * std::cos(y * 7e4) + 31.0;
  };
  const auto full = grid_tile(kTile, 64, f);
  tile::TinTile t = full;
  LodOptions o;
  o.epsilon = 0.5;
  ASSERT_TRUE(reduce_finest_tile(t, o).ok());
  std::size_t lake_before = 0, lake_after = 0, land_before = 0, land_after = 0;
  const double guard = r.width() / 16;  // stay away from the shore
  auto count = [&](const std::vector<Vertex>& pts, std::size_t& lake, std::size_t& land) {
    for (const auto& p : pts) {
      if (p.x < mid - guard) ++lake;
      if (p.x > mid + guard) ++land;
    }
  };
  count(full.interior, lake_before, land_before);
  count(t.interior, lake_after, land_after);
  EXPECT_GT(lake_before, 1000u);
  EXPECT_EQ(lake_after, 0u);
  EXPECT_GT(land_after, land_before / 2);
  EXPECT_TRUE(tile::check_structure(t).ok());
}

TEST(Thinning, WeightedPointSurvivesTheBudget) {
  const geo::MercatorRect r = kTile.bounds();
  const double px = r.min_x + r.width() * 20 / 32, py = r.max_y - r.height() * 11 / 32;
  auto f = [&](double x, double y) {
    return 10.0 * std::sin(x * 5e4) + (x == px && y == py ? 0.3 : 0.0);
  };
  auto w = [&](double x, double y) { return x == px && y == py ? 1e6 : 0.0; };
  tile::TinTile t = grid_tile(kTile, 32, f, w);
  LodOptions o;
  o.max_points = 16;
  ASSERT_TRUE(reduce_finest_tile(t, o).ok());
  bool found = false;
  for (const auto& p : t.interior) found = found || (p.x == px && p.y == py);
  EXPECT_TRUE(found);
  EXPECT_LE(t.vertex_count(), 16u);
}

TEST(Thinning, OrphansFeedTheError) {
  // A centre point 0.5 m above the corners' plane goes with epsilon 1 — unless an orphan (a point
  // of the surface that is not a candidate, e.g. on a parent's internal cross) next to it stands
  // 1.2 m high: removing the centre would then leave a 1.2 m error there.
  ThinInput in;
  in.id = kTile;
  const geo::MercatorRect r = kTile.bounds();
  auto v = [](double x, double y, double z) { return Vertex{x, y, z, 0}; };
  in.corners = {v(r.min_x, r.max_y, 0), v(r.max_x, r.max_y, 0), v(r.min_x, r.min_y, 0),
                v(r.max_x, r.min_y, 0)};
  const double cx = 0.5 * (r.min_x + r.max_x), cy = 0.5 * (r.min_y + r.max_y);
  in.interior = {v(cx, cy, 0.5)};
  LodOptions o;
  o.epsilon = 1.0;
  auto without = thin_tile(in, o);
  ASSERT_TRUE(without.ok());
  EXPECT_EQ(without->interior.size(), 0u);
  in.orphans = {v(cx + r.width() * 0.01, cy, 1.2)};
  auto with = thin_tile(in, o);
  ASSERT_TRUE(with.ok());
  EXPECT_EQ(with->interior.size(), 1u);
}

TEST(Thinning, RejectsTooSmallBudget) {
  const auto full = grid_tile(kTile, 4, plane);
  tile::TinTile t = full;
  LodOptions o;
  o.max_points = 3;
  EXPECT_FALSE(reduce_finest_tile(t, o).ok());
  EXPECT_EQ(t.vertex_count(), full.vertex_count());
}

}  // namespace
}  // namespace tinstream::lod
