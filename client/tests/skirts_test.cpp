// Which sides hang a skirt (skirts.hpp): only towards a drawn tile of the same layer and another
// level, over the part of it that is drawn; never at the data's edge; depth and floor from the
// tiles on both sides. Expected sides are worked out by hand from the tile ids below.
#include "tinstream/client/skirts.hpp"

#include <gtest/gtest.h>

#include <deque>

namespace tinstream::client {
namespace {

constexpr std::uint8_t N = 1, E = 2, S = 4, W = 8;

class Frame {
 public:
  // A drawn tile: level z, column x, row y (north → south), stored error and lowest height.
  Frame& tile(std::uint32_t z, std::uint32_t x, std::uint32_t y, double error = 0, double min_z = 0,
              std::uint8_t mask = 0xF, std::uint16_t layer = 0) {
    ResidentTile& r = tiles_.emplace_back();
    r.geometric_error = error;
    r.min_z = min_z;
    r.skirt_margin = 0.5;
    r.skirt_lowest = -1000;
    draws_.push_back({TileKey{TileKind::terrain, layer, {z, x, y}}, &r, mask});
    return *this;
  }
  std::vector<DrawItem>& plan() {
    plan_skirts(draws_);
    return draws_;
  }

 private:
  std::deque<ResidentTile> tiles_;  // stable addresses
  std::vector<DrawItem> draws_;
};

TEST(Skirts, ALoneTileHasNone) {
  Frame f;
  f.tile(10, 100, 200, 30, 500);
  EXPECT_EQ(f.plan()[0].skirt_sides, 0);
}

TEST(Skirts, TilesOfOneLevelHaveNone) {
  // A 3×3 block of level-12 tiles: same-level borders are watertight.
  Frame f;
  for (std::uint32_t x = 40; x < 43; ++x)
    for (std::uint32_t y = 70; y < 73; ++y) f.tile(12, x, y, 5, 100);
  for (const DrawItem& d : f.plan()) EXPECT_EQ(d.skirt_sides, 0) << d.key.tile.to_string();
}

TEST(Skirts, ACoarseAndAFineNeighbourHangSkirtsOnTheSharedSideOnly) {
  // 10/100/200 and, east of it, 11/202/401 (a child of 10/101/200: its west column, row 1).
  Frame f;
  f.tile(10, 100, 200, 30, 500).tile(11, 202, 401, 8, 650);
  const auto& d = f.plan();
  EXPECT_EQ(d[0].skirt_sides, E);
  EXPECT_EQ(d[1].skirt_sides, W);
  // The crack is at most 30 + 8 m; the floor is the other tile's lowest height.
  EXPECT_DOUBLE_EQ(d[0].skirt_depth, 30 + 8 + 0.5);
  EXPECT_DOUBLE_EQ(d[0].skirt_floor, 650 - 0.5);
  EXPECT_DOUBLE_EQ(d[1].skirt_depth, 8 + 30 + 0.5);
  EXPECT_DOUBLE_EQ(d[1].skirt_floor, 500 - 0.5);
}

TEST(Skirts, AFineTileNotOnTheSharedEdgeIsNoNeighbour) {
  // 11/203/401 lies in 10/101/200 but on its east column: it does not touch 10/100/200.
  Frame f;
  f.tile(10, 100, 200).tile(11, 203, 401);
  for (const DrawItem& d : f.plan()) EXPECT_EQ(d.skirt_sides, 0);
}

TEST(Skirts, EverySideAndTheFloorNeverBelowTheBox) {
  // Level-8 tile 8/50/60 with level-9 tiles touching it on all four sides (and one corner only).
  Frame f;
  f.tile(8, 50, 60, 10, 100)
      .tile(9, 100, 119, 4, 300)    // north (row 119 = 2·60 − 1)
      .tile(9, 102, 121, 4, 300)    // east (column 102 = 2·51)
      .tile(9, 101, 122, 4, -5000)  // south (row 122 = 2·61)
      .tile(9, 99, 120, 4, 300)     // west (column 99 = 2·50 − 1)
      .tile(9, 102, 122, 4, 300);   // diagonal (SE corner only)
  const auto& d = f.plan();
  EXPECT_EQ(d[0].skirt_sides, N | E | S | W);
  EXPECT_EQ(d[1].skirt_sides, S);
  EXPECT_EQ(d[2].skirt_sides, W);
  EXPECT_EQ(d[3].skirt_sides, N);
  EXPECT_EQ(d[4].skirt_sides, E);
  EXPECT_EQ(d[5].skirt_sides, 0);
  // The south neighbour's −5000 m would put the floor below what the box holds (−1000 m).
  EXPECT_DOUBLE_EQ(d[0].skirt_floor, -1000);
}

TEST(Skirts, AParentDrawnInSomeQuadrantsMeetsItsChildrenInside) {
  // 9/10/20 draws only its north quadrants (NW, NE: its SW, SE children have no data, or are
  // not there); children 10/20/41 (SW) and 10/21/41 (SE) are drawn.
  Frame f;
  f.tile(9, 10, 20, 20, 0, 0b0011).tile(10, 20, 41, 6, 0).tile(10, 21, 41, 6, 0);
  const auto& d = f.plan();
  EXPECT_EQ(d[0].skirt_sides, 0);  // the parent's own sides meet nothing drawn
  EXPECT_EQ(d[1].skirt_sides, N);  // under the parent's NW quadrant
  EXPECT_EQ(d[2].skirt_sides, N);  // under its NE quadrant; W–E between the two: same level
  // With the NE quadrant not drawn either, nothing is drawn north of 10/21/41.
  Frame g;
  g.tile(9, 10, 20, 20, 0, 0b0001).tile(10, 21, 41, 6, 0);
  EXPECT_EQ(g.plan()[1].skirt_sides, 0);
}

TEST(Skirts, ACoarseNeighbourCountsOnlyWhereItsQuadrantIsDrawn) {
  // 10/99/200 and, east of it, 9/50/100, whose NW quadrant (10/100/200: column 100 = 2·50,
  // row 200 = 2·100, digit 0) is the part next to it.
  Frame f;
  f.tile(10, 99, 200).tile(9, 50, 100, 0, 0, 0b1110);  // NW not drawn (its children are)
  EXPECT_EQ(f.plan()[0].skirt_sides, 0);
  Frame g;
  g.tile(10, 99, 200).tile(9, 50, 100, 0, 0, 0b0001);  // only NW drawn
  EXPECT_EQ(g.plan()[0].skirt_sides, E);
  EXPECT_EQ(g.plan()[1].skirt_sides, W);
}

TEST(Skirts, OtherLayersAndTheAntimeridian) {
  // Another layer's tile beside it is no neighbour.
  Frame f;
  f.tile(10, 100, 200).tile(11, 202, 401, 0, 0, 0xF, /*layer=*/1);
  for (const DrawItem& d : f.plan()) EXPECT_EQ(d.skirt_sides, 0);
  // Column 0 and the last column meet across ±180°.
  Frame g;
  g.tile(3, 0, 4).tile(4, 15, 8);
  EXPECT_EQ(g.plan()[0].skirt_sides, W);
  EXPECT_EQ(g.plan()[1].skirt_sides, E);
}

}  // namespace
}  // namespace tinstream::client
