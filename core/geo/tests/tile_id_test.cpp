#include "tinstream/geo/tile_id.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

namespace tinstream::geo {
namespace {

TileId tile(std::uint32_t z, std::uint32_t x, std::uint32_t y) { return TileId{z, x, y}; }

TEST(TileId, BingDocumentedExample) {
  // Bing Maps Tile System: tile (3, 5) at level 3 has quadkey "213".
  EXPECT_EQ(tile(3, 3, 5).quadkey(), "213");
  const auto parsed = TileId::from_quadkey("213");
  ASSERT_TRUE(parsed.ok());
  EXPECT_EQ(*parsed, tile(3, 3, 5));
}

TEST(TileId, LevelOneTilesAreTheFourQuadrants) {
  EXPECT_EQ(tile(1, 0, 0).quadkey(), "0");
  EXPECT_EQ(tile(1, 1, 0).quadkey(), "1");
  EXPECT_EQ(tile(1, 0, 1).quadkey(), "2");
  EXPECT_EQ(tile(1, 1, 1).quadkey(), "3");
  const MercatorRect nw = tile(1, 0, 0).bounds();
  EXPECT_EQ(nw.min_x, -1.0);
  EXPECT_EQ(nw.max_x, 0.0);
  EXPECT_EQ(nw.min_y, 0.0);
  EXPECT_EQ(nw.max_y, 1.0);
  const MercatorRect se = tile(1, 1, 1).bounds();
  EXPECT_EQ(se.min_x, 0.0);
  EXPECT_EQ(se.max_y, 0.0);
  EXPECT_EQ(se.min_y, -1.0);
}

TEST(TileId, WorldIsEmptyQuadkey) {
  EXPECT_EQ(tile(0, 0, 0).quadkey(), "");
  EXPECT_EQ(*TileId::from_quadkey(""), tile(0, 0, 0));
  const MercatorRect w = tile(0, 0, 0).bounds();
  EXPECT_EQ(w.min_x, -1.0);
  EXPECT_EQ(w.max_x, 1.0);
  EXPECT_EQ(w.min_y, -1.0);
  EXPECT_EQ(w.max_y, 1.0);
}

TEST(TileId, LonLatBoundsOfLevelOne) {
  const NormalisedMercator sph(Projection::spherical);
  const LonLatRect nw = tile(1, 0, 0).lonlat_bounds(sph);
  EXPECT_DOUBLE_EQ(nw.west, -180);
  EXPECT_DOUBLE_EQ(nw.east, 0);
  EXPECT_DOUBLE_EQ(nw.south, 0);
  EXPECT_NEAR(nw.north, 85.0511287798066, 1e-10);
  const LonLatRect se = tile(1, 1, 1).lonlat_bounds(NormalisedMercator(Projection::ellipsoidal));
  EXPECT_NEAR(se.south, -85.0840590501, 1e-9);
}

TEST(TileId, MalformedQuadkeysRejectedWithReason) {
  for (const char* bad : {"4", "01a", "0 1", "-1", "0123012301230123012301230123012"}) {
    const auto r = TileId::from_quadkey(bad);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.error().code, ErrorCode::invalid_argument);
    EXPECT_FALSE(r.error().message.empty());
  }
  EXPECT_NE(TileId::from_quadkey("12x").error().message.find("'x' at position 2"),
            std::string::npos);
  EXPECT_NE(TileId::from_quadkey(std::string(31, '1')).error().message.find("maximum level"),
            std::string::npos);
  EXPECT_NE(TileId::from_quadkey(std::string("0\0", 2)).error().message.find("byte 0"),
            std::string::npos);
  EXPECT_TRUE(TileId::from_quadkey(std::string(30, '3')).ok());
}

TEST(TileId, QuadkeyRoundTripAllLevels) {
  std::mt19937_64 rng(5);
  for (std::uint32_t z = 0; z <= kMaxLevel; ++z) {
    std::uniform_int_distribution<std::uint32_t> idx(0, (1u << z) - 1);
    for (int i = 0; i < 200; ++i) {
      const TileId t = tile(z, idx(rng), idx(rng));
      const std::string key = t.quadkey();
      ASSERT_EQ(key.size(), z);
      ASSERT_EQ(*TileId::from_quadkey(key), t) << key;
    }
  }
}

TEST(TileId, ParentAndChildren) {
  const TileId t = tile(5, 13, 22);
  const auto kids = t.children();
  const MercatorRect pb = t.bounds();
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(kids[i].parent(), t);
    EXPECT_EQ(kids[i].child_index(), i);
    EXPECT_EQ(kids[i].quadkey(), t.quadkey() + static_cast<char>('0' + i));
    const MercatorRect kb = kids[i].bounds();
    EXPECT_GE(kb.min_x, pb.min_x);
    EXPECT_LE(kb.max_x, pb.max_x);
    EXPECT_GE(kb.min_y, pb.min_y);
    EXPECT_LE(kb.max_y, pb.max_y);
    EXPECT_EQ(kb.width() * 2, pb.width());
  }
  // NW child shares the parent's north-west corner; SE child the south-east one.
  EXPECT_EQ(kids[0].bounds().min_x, pb.min_x);
  EXPECT_EQ(kids[0].bounds().max_y, pb.max_y);
  EXPECT_EQ(kids[3].bounds().max_x, pb.max_x);
  EXPECT_EQ(kids[3].bounds().min_y, pb.min_y);
}

TEST(TileId, NeighboursShareEdgesAndWrapEastWest) {
  const TileId t = tile(3, 0, 4);
  EXPECT_EQ(*t.neighbour(Direction::north), tile(3, 0, 3));
  EXPECT_EQ(*t.neighbour(Direction::south), tile(3, 0, 5));
  EXPECT_EQ(*t.neighbour(Direction::east), tile(3, 1, 4));
  EXPECT_EQ(*t.neighbour(Direction::west), tile(3, 7, 4));  // across the antimeridian
  EXPECT_EQ(t.neighbour(Direction::north)->bounds().min_y, t.bounds().max_y);
  EXPECT_EQ(t.neighbour(Direction::east)->bounds().min_x, t.bounds().max_x);
  EXPECT_FALSE(tile(3, 2, 0).neighbour(Direction::north).has_value());
  EXPECT_FALSE(tile(3, 2, 7).neighbour(Direction::south).has_value());
  EXPECT_FALSE(tile(0, 0, 0).neighbour(Direction::east).has_value());
}

TEST(TileId, TmsRowFlip) {
  EXPECT_EQ(tile(0, 0, 0).tms_row(), 0u);
  EXPECT_EQ(tile(1, 0, 0).tms_row(), 1u);
  EXPECT_EQ(tile(3, 2, 1).tms_row(), 6u);
  EXPECT_EQ(*TileId::from_tms(3, 2, 6), tile(3, 2, 1));
  EXPECT_FALSE(TileId::from_tms(3, 2, 8).ok());
  EXPECT_FALSE(TileId::from_zxy(31, 0, 0).ok());
  EXPECT_FALSE(TileId::from_zxy(2, -1, 0).ok());
}

TEST(TileId, MortonOrderIsQuadkeyPreOrder) {
  std::mt19937_64 rng(9);
  std::vector<TileId> tiles;
  for (int i = 0; i < 3000; ++i) {
    const std::uint32_t z = std::uniform_int_distribution<std::uint32_t>(0, 12)(rng);
    std::uniform_int_distribution<std::uint32_t> idx(0, (1u << z) - 1);
    tiles.push_back(tile(z, idx(rng), idx(rng)));
  }
  for (std::size_t i = 0; i + 1 < tiles.size(); ++i) {
    const TileId& a = tiles[i];
    const TileId& b = tiles[i + 1];
    EXPECT_EQ(morton_less(a, b), a.quadkey() < b.quadkey()) << a.quadkey() << " " << b.quadkey();
  }
  EXPECT_TRUE(morton_less(tile(1, 0, 0), tile(2, 0, 0)));  // "0" before "00"
  EXPECT_FALSE(morton_less(tile(2, 0, 0), tile(1, 0, 0)));
  EXPECT_FALSE(morton_less(tile(2, 1, 0), tile(2, 1, 0)));
  EXPECT_TRUE(morton_less(tile(1, 0, 0), tile(2, 1, 1)));  // parent "0" before child "03"
}

TEST(TileId, ContainingAgreesWithExactBounds) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::uint32_t z : {0u, 1u, 7u, 16u, 24u, 30u}) {
    for (int i = 0; i < 20000; ++i) {
      const MercatorXY p{unit(rng), unit(rng)};
      const TileId t = TileId::containing(p, z);
      ASSERT_TRUE(t.valid());
      const MercatorRect r = t.bounds();
      ASSERT_TRUE(r.contains(p)) << z << " " << p.x << " " << p.y;
      // Half-open: never on the west edge unless it is the map's edge... i.e. x ≥ min_x and
      // x < max_x except in the last column.
      ASSERT_TRUE(p.x < r.max_x || t.x + 1 == t.tiles_per_side());
      ASSERT_TRUE(p.y > r.min_y || t.y + 1 == t.tiles_per_side());
    }
  }
}

// The edges are exact dyadic numbers: -1 + column · 2^(1 − z), computed here with std::ldexp
// (the library builds the power of two from its bits), on every level and at both ends, beyond
// the map's own levels too (halo cells are finer than tiles).
TEST(TileId, EdgesAreTheExactDyadicValues) {
  for (std::uint32_t z = 0; z <= 40; ++z) {
    const std::uint64_t side = std::uint64_t{1} << std::min(z, 31u);
    for (std::uint64_t c :
         {std::uint64_t{0}, std::uint64_t{1}, side / 3, side / 2, side - 1, side}) {
      const auto column = static_cast<std::uint32_t>(std::min<std::uint64_t>(c, 0xFFFFFFFFu));
      const double step = std::ldexp(static_cast<double>(column), 1 - static_cast<int>(z));
      ASSERT_EQ(tile_x_edge(z, column), -1.0 + step) << z << " " << column;
      ASSERT_EQ(tile_y_edge(z, column), 1.0 - step) << z << " " << column;
    }
  }
  EXPECT_EQ(tile_x_edge(1, 1), 0.0);
  EXPECT_EQ(tile_y_edge(2, 3), -0.5);
  EXPECT_EQ(tile_x_edge(30, 1), -1.0 + 0x1p-29);
}

TEST(TileId, ContainingPointsOnEdgesGoEastAndSouth) {
  const TileId t = tile(4, 5, 9);
  const MercatorRect r = t.bounds();
  EXPECT_EQ(TileId::containing({r.min_x, r.max_y}, 4), t);  // NW corner belongs to the tile
  EXPECT_EQ(TileId::containing({r.max_x, r.max_y}, 4), tile(4, 6, 9));
  EXPECT_EQ(TileId::containing({r.min_x, r.min_y}, 4), tile(4, 5, 10));
  EXPECT_EQ(TileId::containing({1.0, -1.0}, 4), tile(4, 15, 15));
  EXPECT_EQ(TileId::containing({-1.0, 1.0}, 4), tile(4, 0, 0));
  // Points 1 ulp either side of an edge land on either side.
  EXPECT_EQ(TileId::containing({std::nextafter(r.min_x, -2.0), 0.9 * r.max_y + 0.1 * r.min_y}, 4).x,
            4u);
}

}  // namespace
}  // namespace tinstream::geo
