#include "tinstream/lod/parent.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <tuple>

#include "lod_test_support.hpp"
#include "tinstream/lod/error.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::lod {
namespace {

using testing::grid_tile;
using tile::TinTile;

double hills(double x, double y) {
  return 500.0 + 80.0 * std::sin(x * 900.0) * std::cos(y * 700.0) +
         15.0 * std::sin(x * 5000.0 + y * 3000.0);
}

// Children of the 2×2 parents whose NW parent is (z, x0, y0), each a reduced grid tile (with
// its residual bounds and witnesses, lod_tile.hpp).
std::map<geo::TileId, LodTile> children_block(std::uint32_t z, std::uint32_t x0, std::uint32_t y0,
                                              double epsilon) {
  std::map<geo::TileId, LodTile> out;
  for (std::uint32_t y = 2 * y0; y < 2 * y0 + 4; ++y) {
    for (std::uint32_t x = 2 * x0; x < 2 * x0 + 4; ++x) {
      const geo::TileId id{z + 1, x, y};
      LodOptions o;
      o.epsilon = epsilon;
      auto t = reduce_finest(grid_tile(id, 32, hills), o);
      EXPECT_TRUE(t.ok());
      out.emplace(id, std::move(*t));
    }
  }
  return out;
}

Children kids_of(const geo::TileId& p, const std::map<geo::TileId, LodTile>& all) {
  Children k;
  const auto ids = p.children();
  for (std::size_t i = 0; i < 4; ++i) {
    if (auto it = all.find(ids[i]); it != all.end()) k.tiles[i] = it->second;
  }
  return k;
}

TEST(Parent, NeighbouringParentsBuiltIndependentlyAreWatertight) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  const auto kids = children_block(z, x0, y0, 0.05);
  std::vector<TinTile> child_level;
  child_level.reserve(kids.size());
  for (const auto& [id, t] : kids) child_level.push_back(t.tile);
  ASSERT_TRUE(check_level_watertight(child_level).ok());
  LodOptions o;
  o.max_points = 300;
  std::vector<TinTile> parents;
  for (std::uint32_t y = y0; y < y0 + 2; ++y) {
    for (std::uint32_t x = x0; x < x0 + 2; ++x) {
      auto p = build_parent({z, x, y}, kids_of({z, x, y}, kids), o);
      ASSERT_TRUE(p.ok()) << p.error().message;
      EXPECT_TRUE(tile::check_structure(p->tile).ok());
      EXPECT_TRUE(check_budget(p->tile, o.max_points).ok());
      parents.push_back(std::move(p->tile));
    }
  }
  const Status s = check_level_watertight(parents);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  // The shared borders were thinned (not kept whole), so the check had something to compare.
  EXPECT_LT(parents[0].east.size(), 2u * 31u);
  EXPECT_GT(parents[0].east.size(), 0u);
}

TEST(Parent, StoredErrorBoundsTheFinestDataAndIsMonotone) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  const auto kids = children_block(z, x0, y0, 0.2);
  LodOptions o;
  o.max_points = 200;
  const geo::TileId pid{z, x0, y0};
  auto built = build_parent(pid, kids_of(pid, kids), o);
  ASSERT_TRUE(built.ok()) << built.error().message;
  const TinTile* p = &built->tile;
  std::vector<TinTile> under;
  double child_max = 0;
  for (const auto& c : pid.children()) {
    under.push_back(kids.at(c).tile);
    child_max = std::max(child_max, kids.at(c).tile.geometric_error);
    EXPECT_GT(kids.at(c).tile.geometric_error, 0.0);
  }
  EXPECT_GE(p->geometric_error, child_max);
  EXPECT_GT(p->rms_error, 0.0);
  EXPECT_LE(p->rms_error, p->geometric_error);
  EXPECT_LE(built->witnesses.size(), witness_count(o));
  EXPECT_FALSE(built->witnesses.empty());
  // Against the unreduced finest grid, which the children approximate: the stored error bounds
  // it at every data point, independently evaluated, and is not far above it (error.hpp).
  std::vector<TinTile> finest;
  for (const auto& c : pid.children()) finest.push_back(grid_tile(c, 32, hills));
  const double vs_finest = testing::data_point_max_difference(*p, finest);
  EXPECT_GE(p->geometric_error, vs_finest);
  auto measured = measured_max_error(*p, finest);
  ASSERT_TRUE(measured.ok());
  EXPECT_LE(*measured, p->geometric_error);
  EXPECT_LT(p->geometric_error, 1.5 * vs_finest);
  // And the triangle inequality against the children's vertices.
  EXPECT_GE(p->geometric_error + child_max, testing::data_point_max_difference(*p, under));
}

// Two peaks on the parent's internal cross (the children's shared sides): 40 m at its centre (a
// corner of all four children) and 30 m on a side point, on gentle hills (±5 m). Only the
// children's points on the cross carry them (the points one cell away stand on the hills), and the
// children keep them (a corner; a side's break). They are candidates of the parent, so it keeps
// both; as orphans (before) they only fed the error estimate and no candidate could bring the
// surface up there: the parent missed the 40 m peak.
TEST(Parent, PeaksOnTheInternalCrossAreKept) {
  const geo::TileId pid{9, 100, 140};
  const geo::MercatorRect nw = pid.children()[0].bounds();
  const double h = nw.width() / 32;  // the children's cell
  const double cx = nw.max_x, cy = nw.min_y;
  auto peak = [&](double x, double y, double py) {
    return std::abs(x - cx) < 0.25 * h && std::abs(y - py) < 0.25 * h;
  };
  auto f = [&](double x, double y) {
    return 500.0 + 5.0 * std::sin(x * 900.0) * std::cos(y * 700.0) + (peak(x, y, cy) ? 40.0 : 0.0) +
           (peak(x, y, cy + 11 * h) ? 30.0 : 0.0);
  };
  std::map<geo::TileId, LodTile> kids;
  std::vector<TinTile> finest;
  LodOptions ko;
  ko.epsilon = 0.1;
  for (const auto& c : pid.children()) {
    finest.push_back(grid_tile(c, 32, f));
    auto t = reduce_finest(finest.back(), ko);
    ASSERT_TRUE(t.ok()) << t.error().message;
    kids.emplace(c, std::move(*t));
  }
  LodOptions o;
  o.max_points = 200;
  auto p = build_parent(pid, kids_of(pid, kids), o);
  ASSERT_TRUE(p.ok()) << p.error().message;
  EXPECT_TRUE(check_budget(p->tile, o.max_points).ok());
  const double measured = testing::data_point_max_difference(p->tile, finest);
  EXPECT_LT(measured, 10.0);  // before: 40 m (the centre's peak, missed)
  EXPECT_GE(p->tile.geometric_error, measured);
}

TEST(Parent, MissingChildrenGiveNodataCorners) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  std::map<geo::TileId, TinTile> kids;
  for (const auto& [id, t] : children_block(z, x0, y0, 0.1)) kids.emplace(id, t.tile);
  const geo::TileId pid{z, x0, y0};
  std::array<std::optional<TinTile>, 4> k;
  k[0] = kids.at(pid.children()[0]);
  k[3] = kids.at(pid.children()[3]);
  auto p = build_parent(pid, k, LodOptions{});
  ASSERT_TRUE(p.ok()) << p.error().message;
  EXPECT_FALSE(p->corner_nodata[0]);
  EXPECT_TRUE(p->corner_nodata[1]);
  EXPECT_TRUE(p->corner_nodata[2]);
  EXPECT_FALSE(p->corner_nodata[3]);
  // An absent child's corner: never 0, the height of the present children's data vertex nearest
  // to it (the stand-alone rule of parent.hpp), found here by brute force.
  const geo::MercatorRect r = pid.bounds();
  for (const auto& [corner, x, y] :
       {std::tuple{1, r.max_x, r.max_y}, std::tuple{2, r.min_x, r.min_y}}) {
    double best_d2 = 1e300, best_z = 0;
    for (const std::size_t c : {std::size_t{0}, std::size_t{3}}) {
      const TinTile& kid = kids.at(pid.children()[c]);
      for (std::size_t i = 0; i < kid.vertex_count(); ++i) {
        if (i < 4 && kid.corner_nodata[i]) continue;
        const auto& v = kid.vertex(i);
        const double d2 = (v.x - x) * (v.x - x) + (v.y - y) * (v.y - y);
        if (d2 < best_d2) best_d2 = d2, best_z = v.z;
      }
    }
    EXPECT_EQ(p->corners[static_cast<std::size_t>(corner)].z, best_z) << corner;
  }
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

// A parent from its 16 grandchildren (sources at depth 2): corners and border exactly as from its
// children alone (what its neighbours share), an error bound over the grandchildren's data, and
// the bad inputs named.
TEST(Parent, FromGrandchildrenKeepsTheChildrensBorderAndBoundsTheError) {
  const geo::TileId pid{9, 100, 140};
  const auto grandchildren = children_block(10, 200, 280, 0.05);  // the 4 × 4 under pid
  std::map<geo::TileId, LodTile> children;
  LodOptions o;
  o.max_points = 300;
  for (const auto& c : pid.children()) {
    auto built = build_parent(c, kids_of(c, grandchildren), o);
    ASSERT_TRUE(built.ok()) << built.error().message;
    children.emplace(c, std::move(*built));
  }
  const Children kids = kids_of(pid, children);
  Sources sources;
  sources.depth = 2;
  std::vector<TinTile> finest;
  for (const auto& [id, t] : grandchildren) {
    sources.tiles.push_back(t);
    finest.push_back(t.tile);
  }
  auto deep = build_from_sources(pid, kids, sources, o);
  ASSERT_TRUE(deep.ok()) << deep.error().message;
  auto shallow = build_parent(pid, kids, o);
  ASSERT_TRUE(shallow.ok()) << shallow.error().message;
  const TinTile &d = deep->tile, &s = shallow->tile;
  EXPECT_TRUE(tile::check_structure(d).ok());
  EXPECT_LE(d.vertex_count(), o.max_points);
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(d.corners[k].z, s.corners[k].z) << k;
    EXPECT_EQ(d.corner_nodata[k], s.corner_nodata[k]) << k;
  }
  auto same = [](const std::vector<tile::Vertex>& a, const std::vector<tile::Vertex>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (a[i].x != b[i].x || a[i].y != b[i].y || a[i].z != b[i].z) return false;
    }
    return true;
  };
  EXPECT_TRUE(same(d.north, s.north) && same(d.east, s.east) && same(d.south, s.south) &&
              same(d.west, s.west));
  // The grandchildren are reduced grids: their own bounds plus the parent's difference to them.
  double grandchildren_error = 0;
  for (const auto& t : finest)
    grandchildren_error = std::max(grandchildren_error, t.geometric_error);
  EXPECT_GE(d.geometric_error, testing::data_point_max_difference(d, finest));
  for (const auto& [id, c] : children) EXPECT_GE(d.geometric_error, c.tile.geometric_error);
  EXPECT_GT(d.geometric_error, grandchildren_error);

  auto error_of = [&](const Sources& bad) {
    auto r = build_from_sources(pid, kids, bad, o);
    return r.ok() ? std::string("accepted") : r.error().message;
  };
  Sources none;
  none.depth = 2;
  EXPECT_NE(error_of(none).find("no source tiles"), std::string::npos) << error_of(none);
  Sources twice = sources;
  twice.tiles.push_back(sources.tiles.front());
  EXPECT_NE(error_of(twice).find("given twice"), std::string::npos) << error_of(twice);
  Sources outside = sources;
  outside.tiles.front().tile.id.x += 4;  // the next parent's grandchild
  EXPECT_NE(error_of(outside).find("is not a source of"), std::string::npos) << error_of(outside);
  Sources wrong_level = sources;
  wrong_level.depth = 3;
  EXPECT_NE(error_of(wrong_level).find("is not a source of"), std::string::npos)
      << error_of(wrong_level);
}

// A one-child parent that takes its child's vertices (Sources::candidates_from_children) and
// measures worse than its finer tiles is thinned again from its sources, and the better tile
// stays (parent.hpp, "Budget"). The thinning counters (`stats`) describe the kept tile's
// thinning only. Here the first one stays by construction: the source's points east of its
// middle weigh 1,000 m (thinning.hpp, weight rule), more of them than the parent's budget, so
// thinning from the source fills the budget there and leaves the west half flat, while the child
// (thinned from the same points unweighted) spread its vertices over the hills. The child records
// 0 m, so that any error of the parent with its vertices sends it to the source.
TEST(Parent, StatisticsCountOnlyTheKeptAttempt) {
  const geo::TileId pid{9, 100, 140};
  const geo::TileId cid = pid.children()[0], gid = cid.children()[0];
  const TinTile grid = grid_tile(gid, 32, hills);
  Children kids;
  {
    Children one;
    one.tiles[0] = LodTile{grid, {}, {}, {}};  // unreduced: exact
    LodOptions child_options;
    child_options.max_points = 40;
    auto child = build_parent(cid, one, child_options);
    ASSERT_TRUE(child.ok()) << child.error().message;
    kids.tiles[0] = std::move(*child);
  }
  kids.tiles[0]->tile.geometric_error = 0;
  const double middle = 0.5 * (gid.bounds().min_x + gid.bounds().max_x);
  TinTile weighted = grid;
  std::size_t heavy = 0;
  for (tile::Vertex& v : weighted.interior) {
    if (v.x > middle) v.weight = 1000, ++heavy;
  }
  Sources sources;
  sources.depth = 2;
  sources.tiles.push_back(LodTile{weighted, {}, {}, {}});
  LodOptions o;
  o.max_points = 1024;  // the parent's budget: a quarter of it (the child covers 1/16) + border
  ASSERT_GT(heavy, o.max_points / 4 + 4 * side_budget(o));

  sources.candidates_from_children = true;
  ThinStats kept_stats;
  auto kept = build_from_sources(pid, kids, sources, o, &kept_stats);
  ASSERT_TRUE(kept.ok()) << kept.error().message;
  sources.candidates_from_children = false;
  ThinStats thinned_stats;
  auto thinned = build_from_sources(pid, kids, sources, o, &thinned_stats);
  ASSERT_TRUE(thinned.ok()) << thinned.error().message;
  // The first attempt (the child's vertices) stayed: the re-thinned tile measures worse.
  ASSERT_LT(kept->tile.geometric_error, thinned->tile.geometric_error);
  EXPECT_NE(tile::encode(kept->tile), tile::encode(thinned->tile));
  // Its counters: the child's vertices fit the budget, so no greedy stage ran, and every input
  // point but duplicates and removed ones is a vertex of the kept tile.
  EXPECT_EQ(kept_stats.greedy_inserted, 0u);
  EXPECT_GT(thinned_stats.greedy_inserted, 0u);
  EXPECT_EQ(kept_stats.input_points - kept_stats.border_removed - kept_stats.interior_removed -
                kept_stats.duplicates,
            kept->tile.vertex_count());
  EXPECT_LT(kept_stats.input_points, thinned_stats.input_points);
}

// The re-thinning's guard ignores an excess within rounding: a first attempt whose chained error
// lies a few hundred ulps above the finer tiles' stays, even where thinning from the sources would
// measure better. Here it does: the child was thinned from a surface with a 50 m bump inside the
// source's tile (none on its border), so its vertices are off the source's surface.
TEST(Parent, AnExcessWithinRoundingIsNotThinnedAgain) {
  const geo::TileId pid{9, 100, 140};
  const geo::TileId cid = pid.children()[0], gid = cid.children()[0];
  const TinTile grid = grid_tile(gid, 32, hills);
  const geo::MercatorRect g = gid.bounds();
  auto bumped = [&](double x, double y) {
    const double u = std::sin(M_PI * (x - g.min_x) / (g.max_x - g.min_x));
    const double v = std::sin(M_PI * (y - g.min_y) / (g.max_y - g.min_y));
    return hills(x, y) + 50.0 * u * u * v * v;
  };
  Children kids;
  {
    Children one;
    one.tiles[0] = LodTile{grid_tile(gid, 32, bumped), {}, {}, {}};
    LodOptions child_options;
    child_options.max_points = 40;
    auto child = build_parent(cid, one, child_options);
    ASSERT_TRUE(child.ok()) << child.error().message;
    kids.tiles[0] = std::move(*child);
  }
  Sources sources;
  sources.depth = 2;
  sources.tiles.push_back(LodTile{grid, {}, {}, {}});
  sources.candidates_from_children = true;
  LodOptions o;
  o.max_points = 1024;
  auto build_with_child_error = [&](double e) {
    kids.tiles[0]->tile.geometric_error = e;
    auto built = build_from_sources(pid, kids, sources, o);
    EXPECT_TRUE(built.ok()) << built.error().message;
    return std::move(*built);
  };
  // A child recording more than any attempt measures: the first attempt (its vertices) stays.
  const LodTile first = build_with_child_error(1e9);
  const std::vector<ChainInput> chain = {sources.tiles.front().as_chain_input()};
  const double first_error = chain_error(first.tile, chain, witness_count(o)).geometric_error;
  ASSERT_GT(first_error, 0.0);
  // A child recording 0: the first attempt exceeds it, the re-thinned tile is better and stays.
  const LodTile rethinned = build_with_child_error(0);
  ASSERT_LT(rethinned.tile.geometric_error, first_error);
  ASSERT_NE(rethinned.tile.interior.size(), first.tile.interior.size());
  // A child recording the first attempt's error less 1e-13 of it (rounding): the first stays.
  const LodTile near = build_with_child_error(first_error * (1 - 1e-13));
  EXPECT_EQ(near.tile.interior.size(), first.tile.interior.size());
  EXPECT_EQ(near.tile.triangles, first.tile.triangles);
  EXPECT_DOUBLE_EQ(near.tile.geometric_error, first_error);
}

TEST(Watertight, DetectsADifferentSharedPoint) {
  const std::uint32_t z = 9, x0 = 100, y0 = 140;
  auto kids = children_block(z, x0, y0, 0.1);
  std::vector<TinTile> level;
  level.reserve(kids.size());
  for (const auto& [id, t] : kids) level.push_back(t.tile);
  ASSERT_TRUE(check_level_watertight(level).ok());
  ASSERT_FALSE(level[0].east.empty());
  level[0].east[0].z += 0.001;
  EXPECT_FALSE(check_level_watertight(level).ok());
}

// The largest |coarse − fine| by brute force, independent of the library: the difference of two
// piecewise-linear surfaces peaks at a vertex of either mesh or where a coarse edge crosses a
// fine edge; both surfaces are evaluated there by brute-force barycentrics, the fine surface on
// its data triangles only, the coarse one on all of its triangles (error.hpp). *crossings
// receives the number of proper edge crossings found.
double brute_max_difference(const TinTile& coarse, const std::vector<const TinTile*>& fines,
                            std::size_t* crossings = nullptr) {
  double brute = 0;
  auto probe = [&](double x, double y) {
    const auto zc = testing::brute_height(coarse, x, y, false);
    for (const TinTile* fine : fines) {
      const geo::MercatorRect fr = fine->id.bounds();
      if (x < fr.min_x || x > fr.max_x || y < fr.min_y || y > fr.max_y) continue;
      const auto zf = testing::brute_height(*fine, x, y, true);
      if (zc && zf) brute = std::max(brute, std::abs(*zc - *zf));
    }
  };
  auto edges = [](const TinTile& t, bool data_only) {
    std::vector<std::pair<tile::Vertex, tile::Vertex>> e;
    const auto v = t.vertices();
    for (const auto& tr : t.triangles) {
      bool nodata = false;
      for (auto i : tr) nodata = nodata || (i < 4 && t.corner_nodata[i]);
      if (nodata && data_only) continue;
      for (std::size_t k = 0; k < 3; ++k) e.emplace_back(v[tr[k]], v[tr[(k + 1) % 3]]);
    }
    return e;
  };
  for (const auto& p : coarse.vertices()) probe(p.x, p.y);
  std::size_t found = 0;
  for (const TinTile* fine : fines) {
    for (const auto& p : fine->vertices()) probe(p.x, p.y);
    for (const auto& [a, b] : edges(coarse, false)) {
      for (const auto& [c, e] : edges(*fine, true)) {
        const double den = (b.x - a.x) * (e.y - c.y) - (b.y - a.y) * (e.x - c.x);
        if (den == 0) continue;
        const double s = ((c.x - a.x) * (e.y - c.y) - (c.y - a.y) * (e.x - c.x)) / den;
        const double u = ((c.x - a.x) * (b.y - a.y) - (c.y - a.y) * (b.x - a.x)) / den;
        if (s <= 0 || s >= 1 || u <= 0 || u >= 1) continue;
        ++found;
        probe(a.x + s * (b.x - a.x), a.y + s * (b.y - a.y));
      }
    }
  }
  if (crossings) *crossings = found;
  return brute;
}

// A tile over `id` from random points of `f` (corners, a few points on each side, the rest
// inside), triangulated with every point kept.
TinTile random_tile(const geo::TileId& id, int n, std::uint32_t seed, const testing::Surface& f) {
  const geo::MercatorRect r = id.bounds();
  std::uint64_t state = seed * 2654435761u + 1;
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1p-53;
  };
  auto v = [&](double x, double y) { return tile::Vertex{x, y, f(x, y), 0}; };
  ThinInput in;
  in.id = id;
  in.corners = {v(r.min_x, r.max_y), v(r.max_x, r.max_y), v(r.min_x, r.min_y), v(r.max_x, r.min_y)};
  for (int i = 1; i <= 3; ++i) {
    const double t = i / 4.0 + (uniform() - 0.5) * 0.1;
    in.north.push_back(v(r.min_x + t * r.width(), r.max_y));
    in.south.push_back(v(r.min_x + t * r.width(), r.min_y));
    in.east.push_back(v(r.max_x, r.max_y - t * r.height()));
    in.west.push_back(v(r.min_x, r.max_y - t * r.height()));
  }
  for (int i = 0; i < n; ++i) {
    in.interior.push_back(v(r.min_x + (0.001 + 0.998 * uniform()) * r.width(),
                            r.min_y + (0.001 + 0.998 * uniform()) * r.height()));
  }
  auto t = thin_tile(in, testing::keep_everything());
  EXPECT_TRUE(t.ok()) << (t.ok() ? "" : t.error().message);
  return t.ok() ? *t : TinTile{};
}

double valley(double x, double y) { return 300.0 + 40.0 * std::cos(x * 2100.0 - y * 1300.0); }

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
  EXPECT_GT(d.crossings, 0u);
  EXPECT_NEAR(d.area, r.width() * r.height(), 1e-12 * r.width() * r.height() + 1e-30);
  // Vertex sampling alone misses it.
  auto m = measured_max_error(coarse, {fine});
  ASSERT_TRUE(m.ok());
  EXPECT_LT(*m, 1e-9);
}

TEST(MeasuredError, ATileMeasuredAgainstItselfIsExactNextToSliversToFarCorners) {
  // A level-0 tile over a few metres of data (a small LiDAR crop's one-tile levels): its
  // triangles from the data's hull to the map's corners are slivers 1e-6 wide and 1 long. Every
  // vertex of the tile lies on the tile's own surface, so measured against itself the error is 0
  // up to rounding; barycentrics taken relative to a far corner were off by 1e-10, enough to put a
  // vertex 7 mm beyond a hull edge inside the sliver and read 0.029 m there (issue #20).
  // The three points are that vertex q and that edge a–b, from nm_4_6_crop.las's pyramid; the
  // tile holds the two triangles there: the sliver (NE corner, a, b) and (q, b, a) beyond it.
  const geo::TileId id{0, 0, 0};
  const geo::MercatorRect r = id.bounds();
  auto v = [](double x, double y, double z) { return tile::Vertex{x, y, z, 0}; };
  TinTile t;
  t.id = id;
  t.corners = {v(r.min_x, r.max_y, 2158.5), v(r.max_x, r.max_y, 2158.5),
               v(r.min_x, r.min_y, 2158.5), v(r.max_x, r.min_y, 2158.5)};
  t.corner_nodata = {true, true, true, true};
  t.interior = {v(-0.59028927470709014, 0.20779051711088137, 2161.48),   // q (4)
                v(-0.59028927415188348, 0.20779058102774384, 2161.51),   // a (5)
                v(-0.59028927673307152, 0.20778980806287725, 2161.53)};  // b (6)
  t.triangles = {{1, 5, 6}, {4, 6, 5}};                                  // both counter-clockwise
  // The sliver does not hold q: q lies beyond a–b, seen from the NE corner (the tests' own
  // orientation, on differences small enough to be exact here).
  auto orient = [](const tile::Vertex& p, const tile::Vertex& q, const tile::Vertex& s) {
    return (q.x - p.x) * (s.y - p.y) - (q.y - p.y) * (s.x - p.x);
  };
  ASSERT_LT(orient(t.interior[1], t.interior[2], t.interior[0]), 0.0);
  ASSERT_GT(orient(t.interior[1], t.interior[2], t.corners[1]), 0.0);
  auto m = measured_max_error(t, {t});
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_LT(*m, 1e-6);
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

  std::size_t crossings = 0;
  const double brute = brute_max_difference(coarse, {&fine}, &crossings);
  ASSERT_GT(crossings, 0u);

  const TinTile* f = &fine;
  const auto d = surface_difference(coarse, std::span<const TinTile* const>(&f, 1));
  EXPECT_GT(brute, 1.0);  // the thinning really changed the surface
  EXPECT_NEAR(d.max_abs, brute, 1e-9 * (1 + brute));
  const geo::MercatorRect r = id.bounds();
  EXPECT_NEAR(d.area, r.width() * r.height(), 1e-9 * r.width() * r.height());
  // The RMS is the fine vertices' RMS, each weighted by a third of the area of its triangles
  // (error.hpp), computed here by brute force; on this dense lattice it is close to the area
  // RMS of the difference, estimated by dense sampling.
  {
    const auto v = fine.vertices();
    std::vector<double> weight(v.size(), 0.0);
    for (const auto& tr : fine.triangles) {
      const auto &a = v[tr[0]], &b = v[tr[1]], &c = v[tr[2]];
      const double area = std::abs((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)) / 2;
      for (auto i : tr) weight[i] += area / 3;
    }
    double wsum = 0, wsq = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const double diff = *testing::brute_height(coarse, v[i].x, v[i].y, true) - v[i].z;
      wsum += weight[i], wsq += weight[i] * diff * diff;
    }
    EXPECT_NEAR(d.rms(), std::sqrt(wsq / wsum), 1e-9 * std::sqrt(wsq / wsum));
  }
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
  EXPECT_NEAR(d.rms(), std::sqrt(sum_sq / n), 0.05 * std::sqrt(sum_sq / n));
}

TEST(SurfaceDifference, MaximumMatchesABruteForceOverlayOnScatteredPoints) {
  // Scattered points (no lattice alignment) thinned hard: most fine edges cross coarse edges.
  const geo::TileId id{12, 2100, 1400};
  const TinTile fine = random_tile(id, 400, 7, hills);
  TinTile coarse = fine;
  LodOptions o;
  o.max_points = 30;
  o.border_points_per_side = 2;
  ASSERT_TRUE(reduce_finest_tile(coarse, o).ok());
  ASSERT_EQ(coarse.vertex_count(), 30u);
  std::size_t crossings = 0;
  const double brute = brute_max_difference(coarse, {&fine}, &crossings);
  ASSERT_GT(crossings, 100u);
  const TinTile* f = &fine;
  const auto d = surface_difference(coarse, std::span<const TinTile* const>(&f, 1));
  EXPECT_GT(brute, 1.0);
  EXPECT_NEAR(d.max_abs, brute, 1e-9 * (1 + brute));
}

TEST(SurfaceDifference, MaximumMatchesABruteForceOverlayWhenCoarseVerticesAreNotFineVertices) {
  // Two unrelated triangulations of two surfaces over one tile: coarse vertices lie inside fine
  // triangles and on fine edges, where only evaluating the fine surface at them finds the peak.
  const geo::TileId id{12, 2100, 1400};
  const TinTile fine = grid_tile(id, 8, valley);
  // Rough heights: the coarse surface peaks at its own vertices, inside fine triangles.
  const TinTile coarse = random_tile(
      id, 60, 11, [](double x, double y) { return 300.0 + 50.0 * std::sin(1e7 * x + 3e7 * y); });
  const double brute = brute_max_difference(coarse, {&fine});
  const TinTile* f = &fine;
  const auto d = surface_difference(coarse, std::span<const TinTile* const>(&f, 1));
  EXPECT_GT(brute, 1.0);
  EXPECT_NEAR(d.max_abs, brute, 1e-9 * (1 + brute));
  // And the other way round.
  const TinTile* c = &coarse;
  const auto e = surface_difference(fine, std::span<const TinTile* const>(&c, 1));
  EXPECT_NEAR(e.max_abs, brute_max_difference(fine, {&coarse}), 1e-9 * (1 + brute));
}

TEST(SurfaceDifference, CountsCoarseNodataTrianglesWhereTheyCoverFineData) {
  // Two tiles with a NODATA corner: the fine tile's fan covers no data, so it is not measured;
  // the coarse tile's fan covers fine data (the fans differ: other points) and is measured
  // there, as a client draws it. With the corner at z = 0 (a wall, as tiles were before #20)
  // that is most of the relief; continued from the data (docs/tile-format.md §2.1) it is not.
  const geo::TileId id{12, 2100, 1400};
  TinTile fine = random_tile(id, 300, 5, hills);
  TinTile coarse = random_tile(id, 12, 9, hills);
  for (TinTile* t : {&fine, &coarse}) t->corner_nodata[1] = true;
  const TinTile* f = &fine;
  for (const double corner_z : {0.0, hills(coarse.corners[1].x, coarse.corners[1].y)}) {
    coarse.corners[1].z = corner_z;
    const double brute = brute_max_difference(coarse, {&fine});
    const auto d = surface_difference(coarse, std::span<const TinTile* const>(&f, 1));
    EXPECT_GT(brute, 0.1);
    EXPECT_NEAR(d.max_abs, brute, 1e-9 * (1 + brute)) << corner_z;
    if (corner_z == 0) {
      EXPECT_GT(brute, 200.0);  // the wall, under coarse NODATA triangles
    }
  }
}

TEST(SurfaceDifference, ParentAgainstItsFourChildrenMatchesABruteForceOverlay) {
  // The parent's walks cross the children's shared borders; every child is measured.
  const geo::TileId pid{11, 1050, 700};
  std::array<std::optional<TinTile>, 4> kids;
  std::vector<TinTile> copies;
  for (std::size_t i = 0; i < 4; ++i) {
    kids[i] = grid_tile(pid.children()[i], 16, hills);
    copies.push_back(*kids[i]);
  }
  LodOptions o;
  o.max_points = 60;
  auto p = build_parent(pid, kids, o);
  ASSERT_TRUE(p.ok()) << p.error().message;
  std::vector<const TinTile*> fines;
  fines.reserve(copies.size());
  for (const auto& c : copies) fines.push_back(&c);
  const double brute = brute_max_difference(*p, fines);
  EXPECT_GT(brute, 1.0);
  // The overlay of the surfaces peaks between the children's points too; the stored error is
  // over the data points, exact over unreduced children (+ the allowance).
  std::vector<TinTile> children(copies.begin(), copies.end());
  const double at_points = testing::data_point_max_difference(*p, children);
  EXPECT_LE(at_points, brute);
  EXPECT_GE(p->geometric_error, at_points);
  EXPECT_NEAR(p->geometric_error, at_points, 1e-8 * brute + error_rounding_allowance(*p));
}

}  // namespace
}  // namespace tinstream::lod
