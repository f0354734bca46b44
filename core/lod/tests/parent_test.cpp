#include "tinstream/lod/parent.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "lod_test_support.hpp"
#include "tinstream/lod/error.hpp"

namespace tinstream::lod {
namespace {

using testing::grid_tile;
using tile::TinTile;

double hills(double x, double y) {
  return 500.0 + 80.0 * std::sin(x * 900.0) * std::cos(y * 700.0) +
         15.0 * std::sin(x * 5000.0 + y * 3000.0);
}

// Children of the 2×2 parents whose NW parent is (z, x0, y0), each a reduced grid tile.
std::map<geo::TileId, TinTile> children_block(std::uint32_t z, std::uint32_t x0, std::uint32_t y0,
                                              double epsilon) {
  std::map<geo::TileId, TinTile> out;
  for (std::uint32_t y = 2 * y0; y < 2 * y0 + 4; ++y) {
    for (std::uint32_t x = 2 * x0; x < 2 * x0 + 4; ++x) {
      const geo::TileId id{z + 1, x, y};
      TinTile t = grid_tile(id, 32, hills);
      LodOptions o;
      o.epsilon = epsilon;
      EXPECT_TRUE(reduce_finest_tile(t, o).ok());
      out.emplace(id, std::move(t));
    }
  }
  return out;
}

std::array<std::optional<TinTile>, 4> kids_of(const geo::TileId& p,
                                              const std::map<geo::TileId, TinTile>& all) {
  std::array<std::optional<TinTile>, 4> k;
  const auto ids = p.children();
  for (std::size_t i = 0; i < 4; ++i) {
    if (auto it = all.find(ids[i]); it != all.end()) k[i] = it->second;
  }
  return k;
}

TEST(Parent, NeighbouringParentsBuiltIndependentlyAreWatertight) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  const auto kids = children_block(z, x0, y0, 0.05);
  std::vector<TinTile> child_level;
  for (const auto& [id, t] : kids) child_level.push_back(t);
  ASSERT_TRUE(check_level_watertight(child_level).ok());
  LodOptions o;
  o.max_points = 300;
  std::vector<TinTile> parents;
  for (std::uint32_t y = y0; y < y0 + 2; ++y) {
    for (std::uint32_t x = x0; x < x0 + 2; ++x) {
      auto p = build_parent({z, x, y}, kids_of({z, x, y}, kids), o);
      ASSERT_TRUE(p.ok()) << p.error().message;
      EXPECT_TRUE(tile::check_structure(*p).ok());
      EXPECT_TRUE(check_budget(*p, o.max_points).ok());
      parents.push_back(std::move(*p));
    }
  }
  const Status s = check_level_watertight(parents);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  // The shared borders were thinned (not kept whole), so the check had something to compare.
  EXPECT_LT(parents[0].east.size(), 2u * 31u);
  EXPECT_GT(parents[0].east.size(), 0u);
}

TEST(Parent, StoredErrorBoundsTheFinestSurfaceAndIsMonotone) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  const auto kids = children_block(z, x0, y0, 0.2);
  LodOptions o;
  o.max_points = 200;
  const geo::TileId pid{z, x0, y0};
  auto p = build_parent(pid, kids_of(pid, kids), o);
  ASSERT_TRUE(p.ok()) << p.error().message;
  std::vector<TinTile> under;
  double child_max = 0;
  for (const auto& c : pid.children()) {
    under.push_back(kids.at(c));
    child_max = std::max(child_max, kids.at(c).geometric_error);
    EXPECT_GT(kids.at(c).geometric_error, 0.0);
  }
  EXPECT_GE(p->geometric_error, child_max);
  EXPECT_GT(p->rms_error, 0.0);
  EXPECT_LE(p->rms_error, p->geometric_error);
  // Against the children's surface, densely and independently: |parent − children| ≤ bound −
  // children's.
  const double vs_children = testing::sampled_max_difference(*p, under, 150);
  EXPECT_GE(p->geometric_error - child_max, vs_children);
  auto measured = measured_max_error(*p, under);
  ASSERT_TRUE(measured.ok());
  EXPECT_LE(*measured, p->geometric_error);
  // Against the unreduced finest grid, which the children approximate within their error.
  std::vector<TinTile> finest;
  for (const auto& c : pid.children()) finest.push_back(grid_tile(c, 32, hills));
  EXPECT_GE(p->geometric_error, testing::sampled_max_difference(*p, finest, 150));
  // A bound that is not absurd: within a few times the measured error.
  EXPECT_LT(p->geometric_error, 3.0 * (vs_children + child_max) + 1.0);
}

TEST(Parent, MissingChildrenGiveNodataCorners) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  auto kids = children_block(z, x0, y0, 0.1);
  const geo::TileId pid{z, x0, y0};
  auto k = kids_of(pid, kids);
  k[1].reset();
  k[2].reset();
  auto p = build_parent(pid, k, LodOptions{});
  ASSERT_TRUE(p.ok()) << p.error().message;
  EXPECT_FALSE(p->corner_nodata[0]);
  EXPECT_TRUE(p->corner_nodata[1]);
  EXPECT_TRUE(p->corner_nodata[2]);
  EXPECT_FALSE(p->corner_nodata[3]);
  EXPECT_EQ(p->corners[1].z, 0.0);
  EXPECT_TRUE(tile::check_structure(*p).ok());
  // The parent's north side is child 0's north side, then the midpoint, then nothing.
  EXPECT_EQ(p->corners[0].z, kids.at(pid.children()[0]).corners[0].z);
}

TEST(Parent, RejectsWrongOrNoChildren) {
  const geo::TileId pid{9, 100, 140};
  std::array<std::optional<TinTile>, 4> none;
  EXPECT_FALSE(build_parent(pid, none, LodOptions{}).ok());
  std::array<std::optional<TinTile>, 4> wrong;
  wrong[0] = grid_tile(pid.children()[1], 4, hills);
  EXPECT_FALSE(build_parent(pid, wrong, LodOptions{}).ok());
}

TEST(Watertight, DetectsADifferentSharedPoint) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  auto kids = children_block(z, x0, y0, 0.1);
  std::vector<TinTile> level;
  for (const auto& [id, t] : kids) level.push_back(t);
  ASSERT_TRUE(check_level_watertight(level).ok());
  ASSERT_FALSE(level[0].east.empty());
  level[0].east[0].z += 0.001;
  EXPECT_FALSE(check_level_watertight(level).ok());
}

TEST(SurfaceDifference, FindsTheMaximumOnAnEdgeCrossing) {
  // Fine: a ridge along the diagonal NW–SE (values only at vertices, so the maximum of the
  // difference to a flat coarse tile on the *other* diagonal's crossing is at the centre).
  const geo::TileId id{5, 3, 4};
  const geo::MercatorRect r = id.bounds();
  TinTile coarse;
  coarse.id = id;
  coarse.corners = {tile::Vertex{r.min_x, r.max_y, 10, 0}, tile::Vertex{r.max_x, r.max_y, 0, 0},
                    tile::Vertex{r.min_x, r.min_y, 0, 0}, tile::Vertex{r.max_x, r.min_y, 10, 0}};
  coarse.triangles = {{2, 3, 1}, {2, 1, 0}};  // diagonal SW–NE
  TinTile fine = coarse;
  fine.triangles = {{0, 2, 3}, {0, 3, 1}};  // diagonal NW–SE
  const TinTile* f = &fine;
  const auto d = surface_difference(coarse, std::span<const TinTile* const>(&f, 1));
  // At the centre: coarse 0 (on its SW–NE diagonal), fine 10 (on its NW–SE ridge).
  EXPECT_NEAR(d.max_abs, 10.0, 1e-9);
  EXPECT_GT(d.rms(), 0.0);
  EXPECT_NEAR(d.area, r.width() * r.height(), 1e-12 * r.width() * r.height() + 1e-30);
  // Vertex sampling alone misses it.
  auto m = measured_max_error(coarse, {fine});
  ASSERT_TRUE(m.ok());
  EXPECT_LT(*m, 1e-9);
}

TEST(SurfaceDifference, MaximumAndAreaMatchABruteForceOverlay) {
  // A 16×16 lattice of a rough surface against a thinned version of itself: fine triangles
  // inside one coarse triangle (the fast path) and fine triangles cut by coarse edges (the
  // clipping path) both occur. Brute force, independent of the library: the difference of two
  // piecewise-linear surfaces peaks at a vertex of either mesh or where a coarse edge crosses a
  // fine edge; evaluate both surfaces there by brute-force barycentrics.
  const geo::TileId id{9, 270, 180};
  const TinTile fine = grid_tile(id, 16, hills);
  TinTile coarse = fine;
  LodOptions o;
  o.max_points = 40;
  o.border_points_per_side = 4;
  o.epsilon = 1e9;
  ASSERT_TRUE(reduce_finest_tile(coarse, o).ok());
  ASSERT_LT(coarse.vertex_count(), fine.vertex_count());

  double brute = 0;
  auto probe = [&](double x, double y) {
    const auto zc = testing::brute_height(coarse, x, y, true);
    const auto zf = testing::brute_height(fine, x, y, true);
    if (zc && zf) brute = std::max(brute, std::abs(*zc - *zf));
  };
  for (const auto& p : fine.vertices()) probe(p.x, p.y);
  for (const auto& p : coarse.vertices()) probe(p.x, p.y);
  auto edges = [](const TinTile& t) {
    std::vector<std::pair<tile::Vertex, tile::Vertex>> e;
    const auto v = t.vertices();
    for (const auto& tr : t.triangles) {
      for (int k = 0; k < 3; ++k) e.emplace_back(v[tr[k]], v[tr[(k + 1) % 3]]);
    }
    return e;
  };
  std::size_t crossings = 0;
  for (const auto& [a, b] : edges(coarse)) {
    for (const auto& [c, e] : edges(fine)) {
      const double den = (b.x - a.x) * (e.y - c.y) - (b.y - a.y) * (e.x - c.x);
      if (den == 0) continue;
      const double s = ((c.x - a.x) * (e.y - c.y) - (c.y - a.y) * (e.x - c.x)) / den;
      const double u = ((c.x - a.x) * (b.y - a.y) - (c.y - a.y) * (b.x - a.x)) / den;
      if (s <= 0 || s >= 1 || u <= 0 || u >= 1) continue;
      ++crossings;
      probe(a.x + s * (b.x - a.x), a.y + s * (b.y - a.y));
    }
  }
  ASSERT_GT(crossings, 0u);

  const TinTile* f = &fine;
  const auto d = surface_difference(coarse, std::span<const TinTile* const>(&f, 1));
  EXPECT_GT(brute, 1.0);  // the thinning really changed the surface
  EXPECT_NEAR(d.max_abs, brute, 1e-9 * (1 + brute));
  const geo::MercatorRect r = id.bounds();
  EXPECT_NEAR(d.area, r.width() * r.height(), 1e-9 * r.width() * r.height());
  // The RMS lies between 0 and the maximum, and near a dense sample's RMS.
  double sum_sq = 0;
  int n = 0;
  for (int j = 0; j < 200; ++j) {
    for (int i = 0; i < 200; ++i) {
      const double x = r.min_x + r.width() * (i + 0.5) / 200,
                   y = r.min_y + r.height() * (j + 0.5) / 200;
      const double diff =
          *testing::brute_height(coarse, x, y, true) - *testing::brute_height(fine, x, y, true);
      sum_sq += diff * diff;
      ++n;
    }
  }
  EXPECT_NEAR(d.rms(), std::sqrt(sum_sq / n), 0.02 * std::sqrt(sum_sq / n));
}

}  // namespace
}  // namespace tinstream::lod
