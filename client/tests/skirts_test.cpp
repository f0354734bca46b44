// Which sides hang a skirt (skirts.hpp): only towards a drawn tile of the same layer and another
// level, over the part of it that is drawn; never at the data's edge; depth and floor from the
// tiles on both sides. Expected sides are worked out by hand from the tile ids below.
#include "tinstream/client/skirts.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <deque>

#include "grid_tile.hpp"
#include "tinstream/client/render_mesh.hpp"

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
    // One skirt quad per side and per cut (half-line), each along all of it: the tile's data
    // fills it.
    const geo::MercatorRect b = geo::TileId{z, x, y}.bounds();
    const double mx = (b.min_x + b.max_x) / 2, my = (b.min_y + b.max_y) / 2;
    r.gpu.skirt_index_count = {6, 6, 6, 6};
    r.gpu.cut_index_count = {6, 6, 6, 6};
    r.skirt_spans = {{b.min_x, b.max_x}, {b.min_y, b.max_y}, {b.min_x, b.max_x}, {b.min_y, b.max_y},
                     {my, b.max_y},      {b.min_y, my},      {b.min_x, mx},      {mx, b.max_x}};
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
  // The parent's own sides meet nothing drawn; its cuts between its drawn north quadrants and
  // its children hang (y = mid, west and east halves: bits 4 + Cut::west, 4 + Cut::east).
  EXPECT_EQ(d[0].skirt_sides, 0b1100'0000);
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

// Real meshes (build_render_mesh) of constructed tiles, as the streamer makes them resident.
struct MeshFrame {
  std::deque<TileMesh> meshes;
  std::deque<ResidentTile> tiles;
  std::vector<DrawItem> draws;

  const TileMesh& add(const tile::TinTile& t, std::uint8_t mask = 0xF) {
    LayerDescription layer;
    layer.max_level = 20;
    layer.min_z = 100;
    const TileKey key{TileKind::terrain, 0, t.id};
    const TileMesh& m = meshes.emplace_back(build_render_mesh(t, layer, key));
    ResidentTile& r = tiles.emplace_back();
    r.gpu.surface_index_count = m.surface_index_count;
    r.gpu.skirt_index_count = m.skirt_index_count;
    r.gpu.cut_index_count = m.cut_index_count;
    r.skirt_spans = m.skirt_spans;
    r.geometric_error = m.geometric_error;
    r.min_z = m.min_z;
    r.skirt_margin = m.skirt_margin;
    r.skirt_lowest = m.skirt_lowest;
    draws.push_back({key, &r, mask});
    return m;
  }
};

// The skirt quads drawn for item d (index of its first index after the surface, in sixes).
std::vector<std::uint32_t> drawn_quads(const DrawItem& d) {
  std::vector<std::uint32_t> quads;
  for (const auto& [first, count] : d.skirt_runs)
    for (std::uint32_t q = first; q < first + count; ++q) quads.push_back(q);
  return quads;
}

// The border vertices (not the lowered ones) of skirt quad q: indices a, sa, sb, a, sb, b.
std::array<const MeshVertex*, 2> quad_top(const TileMesh& m, std::uint32_t q) {
  const auto at = [&](std::size_t i) {
    return m.indices16.empty() ? m.indices32[i] : std::uint32_t{m.indices16[i]};
  };
  const std::size_t base = m.surface_index_count + std::size_t{q} * 6;
  return {&m.vertices[at(base)], &m.vertices[at(base + 5)]};
}

TEST(Skirts, OnlyQuadsBesideTheNeighboursDataHang) {
  // T = 12/2120/1400, a 5×5 grid: its east side has four quads, a quarter of it each. Its finer
  // neighbour N = 13/4242/2800 (the NW child of 12/2121/1400) meets the north half of that side,
  // and N's SW corner has no data: N's west side has data along its north half only, i.e. along
  // the north quarter of T's east side (v in [0, 1/4]). Only T's quad there hangs; a skirt under
  // the rest of the side would stand beyond N's data (the fin of #17).
  MeshFrame f;
  const geo::TileId t_id{12, 2120, 1400}, n_id{13, 4242, 2800};
  const TileMesh& t =
      f.add(tinstream::testing::make_grid_tile(t_id, 5, tinstream::testing::synthetic_height));
  tile::TinTile n =
      tinstream::testing::make_grid_tile(n_id, 3, tinstream::testing::synthetic_height);
  n.corner_nodata[2] = true;
  const TileMesh& nm = f.add(n);
  plan_skirts(f.draws);
  const auto quarter = static_cast<std::uint16_t>(65535 / 4 + 1);  // unorm16(0.25)
  std::size_t east_quads = 0;
  const std::uint32_t east_first = t.skirt_index_count[0] / 6;
  for (const std::uint32_t q : drawn_quads(f.draws[0])) {
    const auto [a, b] = quad_top(t, q);
    ASSERT_TRUE(q >= east_first && q < east_first + t.skirt_index_count[1] / 6)
        << "quad " << q << " is not on T's east side";
    EXPECT_EQ(a->u, 65535);
    EXPECT_LE(std::max(a->v, b->v), quarter)
        << "a skirt quad of T beyond N's data: v " << a->v << ".." << b->v;
    ++east_quads;
  }
  EXPECT_EQ(east_quads, 1u);
  // N hangs its one west quad with data (T is drawn beside all of it), nothing else.
  const std::vector<std::uint32_t> nq = drawn_quads(f.draws[1]);
  ASSERT_EQ(nq.size(), 1u);
  const auto [a, b] = quad_top(nm, nq[0]);
  EXPECT_EQ(a->u, 0);
  EXPECT_EQ(b->u, 0);
}

TEST(Skirts, AParentsCutHangsTowardsItsChildWhereTheChildHasData) {
  // P = 12/2120/1400 (a 4×4 grid: no vertex on its mid lines) drawn without its NE quadrant,
  // where its child C = 13/4241/2800 is drawn. The cuts between NE and NW (x = mid, north half)
  // and NE and SE (y = mid, east half) hang, all along; the other two cuts do not exist
  // (SW, SE, NW are all drawn).
  MeshFrame f;
  const TileMesh& p = f.add(
      tinstream::testing::make_grid_tile({12, 2120, 1400}, 4, tinstream::testing::synthetic_height),
      0b1101);
  f.add(tinstream::testing::make_grid_tile({13, 4241, 2800}, 5,
                                           tinstream::testing::synthetic_height));
  plan_skirts(f.draws);
  const geo::MercatorRect r = geo::TileId{12, 2120, 1400}.bounds();
  const double mx = (r.min_x + r.max_x) / 2, my = (r.min_y + r.max_y) / 2;
  EXPECT_EQ(f.draws[0].skirt_sides, 1u << (4 + 0) | 1u << (4 + 3));
  std::uint32_t side_quads = 0;
  for (const std::uint32_t n : p.skirt_index_count) side_quads += n / 6;
  // The hung cut quads: where they lie (from their vertices' u, v) and that they cover the
  // half-lines from the centre to the border without a hole (4×4 grid: 3 grid cells across, so
  // the cells crossing the centre are split there).
  std::vector<std::pair<std::uint16_t, std::uint16_t>> north, east;  // v ranges, u ranges
  for (const std::uint32_t q : drawn_quads(f.draws[0])) {
    ASSERT_GE(q, side_quads) << "P hangs a side quad";
    const auto [a, b] = quad_top(p, q);
    if (a->u == b->u) {
      EXPECT_EQ(a->u, 32768);  // unorm16(0.5)
      north.emplace_back(std::min(a->v, b->v), std::max(a->v, b->v));
    } else {
      EXPECT_EQ(a->v, b->v);
      EXPECT_EQ(a->v, 32768);
      east.emplace_back(std::min(a->u, b->u), std::max(a->u, b->u));
    }
  }
  for (auto* line : {&north, &east}) {
    std::sort(line->begin(), line->end());
    ASSERT_FALSE(line->empty());
    std::uint16_t reached = line == &north ? 0 : 32768;
    for (const auto& [lo, hi] : *line) {
      EXPECT_EQ(lo, reached) << "a hole in the cut skirt";
      reached = hi;
    }
    EXPECT_EQ(reached, line == &north ? 32768 : 65535);
  }
  // The spans the plan compared are those of the quads (normalised Mercator).
  for (const std::uint32_t q : drawn_quads(f.draws[0])) {
    const SkirtSpan& s = p.skirt_spans[q];
    EXPECT_TRUE((s.lo >= my && s.hi <= r.max_y) || (s.lo >= mx && s.hi <= r.max_x)) << q;
  }
}

}  // namespace
}  // namespace tinstream::client
