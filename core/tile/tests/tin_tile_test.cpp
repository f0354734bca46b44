#include "tinstream/tile/tin_tile.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "exact_orientation.hpp"
#include "test_tiles.hpp"

namespace tinstream::tile {
namespace {

using testing::make_grid_tile;
__extension__ typedef __int128 Int128;

TinTile two_triangle_tile(const geo::TileId& id) {
  TinTile t;
  t.id = id;
  const auto r = id.bounds();
  t.corners = {Vertex{r.min_x, r.max_y, 1, 0}, Vertex{r.max_x, r.max_y, 2, 0},
               Vertex{r.min_x, r.min_y, 3, 0}, Vertex{r.max_x, r.min_y, 4, 0}};
  t.triangles = {{2, 3, 1}, {2, 1, 0}};
  t.update_z_range();
  return t;
}

TEST(TinTile, VertexNumberingFollowsTheContract) {
  std::mt19937_64 rng(1);
  const TinTile t = make_grid_tile({5, 10, 11}, 4, 3, rng);
  // 4 corners, 3 north, 2 east, 3 south, 2 west, 3·2 interior.
  ASSERT_EQ(t.vertex_count(), 4u + 3 + 2 + 3 + 2 + 6);
  EXPECT_EQ(t.role(0), VertexRole::corner);
  EXPECT_EQ(t.role(3), VertexRole::corner);
  EXPECT_EQ(t.role(4), VertexRole::north);
  EXPECT_EQ(t.role(7), VertexRole::east);
  EXPECT_EQ(t.role(9), VertexRole::south);
  EXPECT_EQ(t.role(12), VertexRole::west);
  EXPECT_EQ(t.role(14), VertexRole::interior);
  EXPECT_EQ(t.vertex(5).x, t.north[1].x);
  EXPECT_EQ(t.vertex(8).y, t.east[1].y);
  EXPECT_EQ(t.vertex(19).x, t.interior[5].x);
  const auto all = t.vertices();
  ASSERT_EQ(all.size(), t.vertex_count());
  for (std::size_t i = 0; i < all.size(); ++i) EXPECT_EQ(all[i].z, t.vertex(i).z);
}

TEST(TinTile, BorderListsIncludeBothCornersInEdgeOrder) {
  std::mt19937_64 rng(2);
  const TinTile t = make_grid_tile({3, 1, 2}, 3, 4, rng);
  const auto north = t.border(geo::Direction::north);
  ASSERT_EQ(north.size(), t.north.size() + 2);
  EXPECT_EQ(north.front().x, t.corners[0].x);
  EXPECT_EQ(north.back().x, t.corners[1].x);
  const auto east = t.border(geo::Direction::east);
  EXPECT_EQ(east.front().y, t.corners[1].y);
  EXPECT_EQ(east.back().y, t.corners[3].y);
  const auto south = t.border(geo::Direction::south);
  EXPECT_EQ(south.front().x, t.corners[2].x);
  EXPECT_EQ(south.back().x, t.corners[3].x);
  const auto west = t.border(geo::Direction::west);
  ASSERT_EQ(west.size(), t.west.size() + 2);
  EXPECT_EQ(west.front().y, t.corners[0].y);
  EXPECT_EQ(west.back().y, t.corners[2].y);
  for (std::size_t i = 1; i < west.size(); ++i) EXPECT_LT(west[i].y, west[i - 1].y);
}

TEST(TinTile, ZRangeSkipsNodataCorners) {
  TinTile t = two_triangle_tile({2, 1, 1});
  t.corners[0].z = -50;
  t.corners[3].z = 0;
  t.corner_nodata[3] = true;
  t.corners[1].z = 120;
  t.update_z_range();
  EXPECT_EQ(t.min_z, -50);
  EXPECT_EQ(t.max_z, 120);
  t.corner_nodata = {true, true, true, true};
  t.update_z_range();
  EXPECT_EQ(t.min_z, 0);
  EXPECT_EQ(t.max_z, 0);
}

// Triangles (2, 3, 1) and (2, 1, 0) of two_triangle_tile: NW (0) is only in the second, SE (3)
// only in the first, SW (2) and NE (1) in both.
TEST(Footprint, ATriangleWithANodataCornerIsOutsideTheFootprint) {
  TinTile t = two_triangle_tile({6, 20, 33});
  EXPECT_FALSE(t.has_nodata_triangles());
  EXPECT_EQ(t.footprint_mask(), (std::vector<std::uint8_t>{1, 1}));
  t.corner_nodata[0] = true;
  EXPECT_TRUE(t.is_nodata_vertex(0));
  EXPECT_FALSE(t.is_nodata_vertex(1));
  EXPECT_FALSE(t.is_nodata_triangle(0));
  EXPECT_TRUE(t.is_nodata_triangle(1));
  EXPECT_EQ(t.footprint_mask(), (std::vector<std::uint8_t>{1, 0}));
  EXPECT_TRUE(t.has_nodata_triangles());
  t.corner_nodata = {false, false, true, false};  // SW: in both triangles
  EXPECT_EQ(t.footprint_mask(), (std::vector<std::uint8_t>{0, 0}));
}

TEST(Footprint, OnlyCornersCanBeNodata) {
  std::mt19937_64 rng(11);
  TinTile t = make_grid_tile({9, 300, 200}, 3, 3, rng, false);
  t.corner_nodata = {true, true, true, true};
  for (std::size_t i = 4; i < t.vertex_count(); ++i) EXPECT_FALSE(t.is_nodata_vertex(i)) << i;
  const auto mask = t.footprint_mask();
  std::size_t data = 0;
  for (std::size_t k = 0; k < t.triangles.size(); ++k) {
    const auto& tr = t.triangles[k];
    const bool corner = tr[0] < 4 || tr[1] < 4 || tr[2] < 4;
    EXPECT_EQ(mask[k], corner ? 0 : 1) << k;
    data += mask[k];
  }
  EXPECT_GT(data, 0u);  // the interior of the grid is footprint
  t.corner_nodata = {false, false, false, false};
  EXPECT_FALSE(t.has_nodata_triangles());
}

TEST(CheckStructure, AcceptsGeneratedTilesAtEveryLevel) {
  std::mt19937_64 rng(3);
  for (std::uint32_t z = 0; z <= 30; ++z) {
    const std::uint64_t n = std::uint64_t{1} << z;
    const geo::TileId id{z, static_cast<std::uint32_t>(rng() % n),
                         static_cast<std::uint32_t>(rng() % n)};
    const TinTile t = make_grid_tile(id, 1 + static_cast<std::uint32_t>(rng() % 9),
                                     1 + static_cast<std::uint32_t>(rng() % 9), rng);
    const Status s = check_structure(t);
    EXPECT_TRUE(s.ok()) << id.to_string() << ": " << (s.ok() ? "" : s.error().message);
  }
  EXPECT_TRUE(check_structure(two_triangle_tile({0, 0, 0})).ok());
}

TEST(CheckStructure, RejectsClockwiseTriangle) {
  TinTile t = two_triangle_tile({4, 3, 9});
  std::swap(t.triangles[0][0], t.triangles[0][1]);
  const Status s = check_structure(t);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("counter-clockwise"), std::string::npos);
  EXPECT_NE(s.error().message.find("4/3/9"), std::string::npos);
}

TEST(CheckStructure, RejectsMissingTriangleAsAHole) {
  TinTile t = two_triangle_tile({4, 3, 9});
  t.triangles.pop_back();
  EXPECT_FALSE(check_structure(t).ok());
  t.triangles.clear();
  EXPECT_FALSE(check_structure(t).ok());
}

TEST(CheckStructure, RejectsOverlap) {
  TinTile t = two_triangle_tile({4, 3, 9});
  t.triangles.push_back(t.triangles[0]);
  EXPECT_FALSE(check_structure(t).ok());
}

TEST(CheckStructure, RejectsIndexOutOfRange) {
  TinTile t = two_triangle_tile({1, 0, 0});
  t.triangles[1][2] = 4;
  EXPECT_FALSE(check_structure(t).ok());
}

TEST(CheckStructure, RejectsCornerOffByOneUlp) {
  TinTile t = two_triangle_tile({7, 40, 41});
  t.corners[1].x = std::nextafter(t.corners[1].x, 2.0);
  EXPECT_FALSE(check_structure(t).ok());
}

TEST(CheckStructure, RejectsEdgePointsOffTheBorderOrOutOfOrder) {
  std::mt19937_64 rng(4);
  const TinTile good = make_grid_tile({6, 20, 30}, 4, 4, rng, false);
  ASSERT_TRUE(check_structure(good).ok());
  {
    TinTile t = good;
    t.north[1].y = std::nextafter(t.north[1].y, 0.0);
    EXPECT_FALSE(check_structure(t).ok());
  }
  {
    TinTile t = good;
    std::swap(t.east[0], t.east[1]);
    EXPECT_FALSE(check_structure(t).ok());
  }
  {
    TinTile t = good;
    t.west[0] = t.west[1];  // duplicate
    EXPECT_FALSE(check_structure(t).ok());
  }
  {
    TinTile t = good;
    t.south.back().x = t.corners[3].x;  // on the corner, not strictly inside the side
    EXPECT_FALSE(check_structure(t).ok());
  }
  {
    TinTile t = good;
    t.interior[0].x = t.corners[0].x;  // on the west border
    EXPECT_FALSE(check_structure(t).ok());
  }
}

TEST(CheckStructure, AcceptsNodataCornerWithContinuedHeightRejectsBadValues) {
  TinTile t = two_triangle_tile({2, 2, 2});
  t.corner_nodata[2] = true;  // z = 3: a height continued from the data (tin_tile.hpp)
  t.update_z_range();
  EXPECT_TRUE(check_structure(t).ok());
  t.corners[2].z = std::nan("");
  EXPECT_FALSE(check_structure(t).ok());
  t.corners[2].z = 3;
  t.corners[0].weight = -1;
  EXPECT_FALSE(check_structure(t).ok());
  t.corners[0].weight = 0;
  t.corners[0].z = std::nan("");
  EXPECT_FALSE(check_structure(t).ok());
}

TEST(CheckStructure, RejectsInvalidTileId) {
  TinTile t = two_triangle_tile({2, 2, 2});
  t.id = {2, 4, 0};
  EXPECT_FALSE(check_structure(t).ok());
}

// The exact orientation test against 128-bit integer arithmetic on dyadic coordinates k·2^-40.
TEST(ExactOrientation, MatchesIntegerArithmetic) {
  std::mt19937_64 rng(5);
  const auto coord = [&](std::int64_t base) {
    return base + static_cast<std::int64_t>(rng() % 9) - 4;  // clusters: nearly degenerate
  };
  for (int i = 0; i < 200000; ++i) {
    const std::int64_t range = std::int64_t{1} << 40;
    const std::int64_t b0 =
        static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(range)) - range / 2;
    const std::int64_t b1 =
        static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(range)) - range / 2;
    const bool degenerate = i % 2 == 0;
    std::int64_t k[6];
    if (degenerate) {
      // Nearly collinear: a, b = a + d, c = a + 2d ± small.
      const std::int64_t dx = static_cast<std::int64_t>(rng() % 1000000) - 500000;
      const std::int64_t dy = static_cast<std::int64_t>(rng() % 1000000) - 500000;
      k[0] = b0, k[1] = b1, k[2] = b0 + dx, k[3] = b1 + dy;
      k[4] = coord(b0 + 2 * dx), k[5] = coord(b1 + 2 * dy);
    } else {
      for (auto& v : k)
        v = static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(range)) - range / 2;
    }
    const Int128 det = static_cast<Int128>(k[2] - k[0]) * (k[5] - k[1]) -
                       static_cast<Int128>(k[3] - k[1]) * (k[4] - k[0]);
    const int expected = det > 0 ? 1 : (det < 0 ? -1 : 0);
    double d[6];
    for (int j = 0; j < 6; ++j) d[j] = std::ldexp(static_cast<double>(k[j]), -40);
    ASSERT_EQ(detail::orient2d_sign(d[0], d[1], d[2], d[3], d[4], d[5]), expected) << i;
  }
}

TEST(ExactOrientation, DetectsOneUlpOffALine) {
  const double a = 0.5, b = 0.75;
  // (a, a), (b, b) and points on / one ulp beside the diagonal far away.
  const double c = 0.9999999999999999;
  EXPECT_EQ(detail::orient2d_sign(a, a, b, b, c, c), 0);
  EXPECT_EQ(detail::orient2d_sign(a, a, b, b, c, std::nextafter(c, 2.0)), 1);
  EXPECT_EQ(detail::orient2d_sign(a, a, b, b, c, std::nextafter(c, 0.0)), -1);
  const double x = 0.1, y = 0.3;  // inexact decimals: the line through them is not y = 3x
  EXPECT_EQ(detail::orient2d_sign(0, 0, x, y, 2 * x, 2 * y), 0);
}

}  // namespace
}  // namespace tinstream::tile
