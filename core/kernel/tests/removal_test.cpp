#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "test_support.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel {
namespace {

using test::sorted;

using test::expect_valid;

std::set<VertexTriple> triangle_set(const Triangulation& t) {
  std::set<VertexTriple> s;
  for (auto tr : t.finite_triangles()) s.insert(sorted(tr));
  return s;
}

TEST(Removal, RemovingAnInteriorVertexGivesTheTriangulationWithoutIt) {
  // General position: the Delaunay triangulation is unique, so removing a vertex must give the
  // same triangles as building from scratch without that point.
  const auto pts = test::uniform_points(400, 31);
  Triangulation t;
  std::vector<VertexId> ids;
  ids.reserve(pts.size());
  for (const auto& p : pts) ids.push_back(t.insert(p).vertex);
  std::mt19937 rng(5);
  for (int round = 0; round < 40; ++round) {
    const std::size_t victim = rng() % pts.size();
    if (!t.is_vertex(ids[victim])) continue;
    ASSERT_TRUE(t.remove_vertex(ids[victim]).ok());
    ids[victim] = kNone;
    Triangulation fresh;
    std::map<VertexId, VertexId> fresh_to_t;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (ids[i] != kNone) fresh_to_t[fresh.insert(pts[i]).vertex] = ids[i];
    }
    std::set<VertexTriple> expected;
    for (auto tr : fresh.finite_triangles()) {
      expected.insert(sorted({fresh_to_t[tr[0]], fresh_to_t[tr[1]], fresh_to_t[tr[2]]}));
    }
    ASSERT_EQ(triangle_set(t), expected) << "after removing input point " << victim;
  }
  expect_valid(t);
}

// Degree-4 stars have their own path (one diagonal picked with exact predicates, no flips).
// In general position the result must equal the triangulation built without the point; the
// quadrilateral links include non-convex ones, where only one diagonal is valid.
TEST(Removal, DegreeFourStarsTakeTheDelaunayDiagonal) {
  std::size_t removed = 0, non_convex = 0;
  for (std::uint32_t seed = 1; seed <= 40 && removed < 200; ++seed) {
    const auto pts = test::uniform_points(60, 500 + seed);
    Triangulation t;
    const auto res = t.insert_bulk(pts);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const VertexId v = res[i].vertex;
      if (!t.is_vertex(v) || t.is_on_hull(v)) continue;
      const std::vector<VertexId> link = t.adjacent_vertices(v);
      if (link.size() != 4) continue;
      for (std::size_t c = 0; c < 4; ++c) {
        if (orient2d(t.xy(link[(c + 3) % 4]), t.xy(link[c]), t.xy(link[(c + 1) % 4])) <= 0.0) {
          ++non_convex;
          break;
        }
      }
      ASSERT_TRUE(t.remove_vertex(v).ok());
      ++removed;
      Triangulation fresh;
      std::map<VertexId, VertexId> fresh_to_t;
      for (std::size_t j = 0; j < pts.size(); ++j) {
        if (t.is_vertex(res[j].vertex)) fresh_to_t[fresh.insert(pts[j]).vertex] = res[j].vertex;
      }
      std::set<VertexTriple> expected;
      for (auto tr : fresh.finite_triangles()) {
        expected.insert(sorted({fresh_to_t[tr[0]], fresh_to_t[tr[1]], fresh_to_t[tr[2]]}));
      }
      ASSERT_EQ(triangle_set(t), expected) << "seed " << seed << ", input point " << i;
    }
  }
  EXPECT_GE(removed, 100u);
  EXPECT_GE(non_convex, 10u);
}

// Cocircular squares: every degree-4 removal is a tie (either diagonal is Delaunay); the result
// must still be valid, checked with exact predicates after every removal.
TEST(Removal, DegreeFourStarsOnALatticeStayDelaunay) {
  Triangulation t;
  const auto res = t.insert_bulk(test::lattice_points(12));
  std::size_t removed = 0;
  for (const auto& r : res) {
    if (!t.is_vertex(r.vertex) || t.is_on_hull(r.vertex)) continue;
    if (t.adjacent_vertices(r.vertex).size() != 4) continue;
    ASSERT_TRUE(t.remove_vertex(r.vertex).ok());
    ++removed;
    ASSERT_NO_FATAL_FAILURE(expect_valid(t));
  }
  EXPECT_GE(removed, 5u);
}

TEST(Removal, PreviewEqualsTheTrianglesThatRemovalCreates) {
  const auto pts = test::clustered_points(500, 8);
  Triangulation t;
  t.insert_bulk(pts);
  std::mt19937 rng(9);
  for (int round = 0; round < 100; ++round) {
    const auto v = static_cast<VertexId>(1 + rng() % (t.vertex_id_bound() - 1));
    if (!t.is_vertex(v)) continue;
    const auto before = triangle_set(t);
    const auto preview = t.removal_preview(v);
    ASSERT_TRUE(preview.ok());
    ASSERT_EQ(triangle_set(t), before) << "preview changed the triangulation";
    ASSERT_TRUE(t.remove_vertex(v).ok());
    std::set<VertexTriple> created;
    for (const auto& tr : triangle_set(t)) {
      if (!before.count(tr)) created.insert(tr);
    }
    std::set<VertexTriple> previewed;
    for (auto tr : *preview) previewed.insert(sorted(tr));
    ASSERT_EQ(previewed, created) << "vertex " << v;
    for (const auto& tr : *preview) {  // counter-clockwise as promised
      ASSERT_GT(orient2d(t.xy(tr[0]), t.xy(tr[1]), t.xy(tr[2])), 0.0);
    }
  }
}

TEST(Removal, CopiesAndMovesRemoveLikeTheOriginal) {
  // The removal scratch (with the plan a preview leaves) belongs to one object: a copy made or
  // assigned right after a preview, and a moved-from object given a new value, must remove
  // exactly as the original does, whatever plan the original holds.
  Triangulation t;
  const auto ids = t.insert_bulk(test::uniform_points(300, 21));
  const VertexId v = ids[7].vertex, w = ids[8].vertex;
  ASSERT_TRUE(t.removal_preview(v).ok());
  Triangulation copied = t;
  Triangulation assigned;
  assigned.insert_bulk(test::uniform_points(50, 22));
  ASSERT_TRUE(assigned.removal_preview(3).ok());
  assigned = t;
  Triangulation moved_from = t;
  Triangulation moved = std::move(moved_from);
  moved_from = t;
  for (Triangulation* u : {&t, &copied, &assigned, &moved, &moved_from}) {
    ASSERT_TRUE(u->remove_vertex(w).ok());  // not the previewed vertex
    ASSERT_TRUE(u->remove_vertex(v).ok());
    expect_valid(*u);
  }
  for (const Triangulation* u : {&copied, &assigned, &moved, &moved_from}) {
    EXPECT_EQ(triangle_set(*u), triangle_set(t));
  }
}

TEST(Removal, EditsBetweenPreviewAndRemovalAreHonoured) {
  // remove_vertex reuses the plan of an immediately preceding removal_preview; any edit or other
  // preview in between must invalidate it.
  Triangulation t;
  t.insert_bulk(test::uniform_points(300, 15));
  const auto ca = t.insert({0.05, 0.05, 0}).vertex, cb = t.insert({0.95, 0.1, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(ca, cb).ok());
  std::mt19937 rng(16);
  for (int round = 0; round < 60; ++round) {
    const auto v = static_cast<VertexId>(1 + rng() % (t.vertex_id_bound() - 1));
    const auto w = static_cast<VertexId>(1 + rng() % (t.vertex_id_bound() - 1));
    if (!t.is_vertex(v) || !t.is_vertex(w) || v == w || v == ca || v == cb || w == ca || w == cb) {
      continue;
    }
    if (!t.removal_preview(v).ok()) continue;
    switch (round % 4) {
      case 3:  // a refused preview
        ASSERT_FALSE(t.removal_preview(ca).ok());
        break;
      case 0:  // an insertion in v's star
        t.insert({t.xy(v).x + 1e-3, t.xy(v).y + 1e-3, 0});
        break;
      case 1:
        ASSERT_TRUE(t.removal_preview(w).ok());
        break;
      default:
        ASSERT_TRUE(t.remove_vertex(w).ok());
        break;
    }
    ASSERT_TRUE(t.remove_vertex(v).ok());
    ASSERT_NO_FATAL_FAILURE(expect_valid(t));
  }
}

using test::Generator;

// Parallel scan lines with jitter, coordinates rounded to 1 cm as in LAS files (the benchmark's
// LiDAR-like set, small): many exactly collinear and cocircular quadruples, so the ear queue's
// floating-point order is often wrong or tied and the exact checks behind it decide.
std::vector<Point3> quantised_scan_lines(std::size_t n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> jitter(0.0, 0.05);
  const double side = std::sqrt(static_cast<double>(n)) * 0.5;
  std::vector<Point3> p;
  double y = 0.0;
  while (p.size() < n) {
    for (double x = 0.0; x < side && p.size() < n; x += 0.45) {
      const double px = std::round((x + jitter(rng)) * 100.0) / 100.0;
      const double py = std::round((y + jitter(rng) + 0.02 * x) * 100.0) / 100.0;
      p.push_back({px, py, 0.0, 0.0});
    }
    y += 0.5;
  }
  return p;
}

const Generator kRemovalGenerators[] = {
    {"uniform", [] { return test::uniform_points(250, 41); }},
    {"clustered", [] { return test::clustered_points(250, 42); }},
    {"lattice", [] { return test::lattice_points(14); }},
    {"circle", [] { return test::circle_points(48); }},
    {"duplicates", [] { return test::duplicate_heavy_points(300, 43); }},
    {"ulp_apart", [] { return test::ulp_points(250, 44); }},
    {"mercator_tile", [] { return test::mercator_tile_points(250, 45); }},
    {"quantised_scan_lines", [] { return quantised_scan_lines(300, 47); }},
    {"collinear_plus_one",
     [] {
       auto p = test::collinear_points(40, 46);
       p.push_back({0.0, 1.0, 0.0, 0.0});
       return p;
     }},
};

class RemovalProperty : public ::testing::TestWithParam<Generator> {};

TEST_P(RemovalProperty, RemovingAllPointsInRandomOrderKeepsTheStructureValid) {
  const auto pts = GetParam().make();
  Triangulation t;
  t.insert_bulk(pts);
  std::vector<VertexId> alive;
  for (VertexId v = 1; v < t.vertex_id_bound(); ++v) {
    if (t.is_vertex(v)) alive.push_back(v);
  }
  std::shuffle(alive.begin(), alive.end(), std::mt19937(77));
  std::size_t left = alive.size();
  for (VertexId v : alive) {
    const Status s = t.remove_vertex(v);
    ASSERT_TRUE(s.ok()) << s.error().message;
    --left;
    ASSERT_EQ(t.num_vertices(), left);
    ASSERT_FALSE(t.is_vertex(v));
    ASSERT_NO_FATAL_FAILURE(expect_valid(t));
  }
  EXPECT_EQ(t.num_finite_triangles(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Fixtures, RemovalProperty, ::testing::ValuesIn(kRemovalGenerators),
                         [](const auto& p) { return std::string(p.param.name); });

// remove_vertex without a preceding preview builds the hole from its edges inwards with exact
// incircle tests and leaves it to the ear queue on a tie; removal_preview(v) + remove_vertex(v)
// always takes the ear queue. Both must create the same triangles, ties included (the lattice
// and the scan lines are full of cocircular quadruples), and since they leave every vertex the
// same starting triangle, later previews (the LOD's path) must be equal element by element.
TEST(Removal, DirectRemovalCreatesThePreviewedTrianglesTiesIncluded) {
  const std::pair<const char*, std::vector<Point3>> inputs[] = {
      {"lattice", test::lattice_points(16)},
      {"scan_lines", quantised_scan_lines(400, 49)},
      {"circle", test::circle_points(40)},
      {"uniform", test::uniform_points(300, 50)},
  };
  for (const auto& [name, pts] : inputs) {
    SCOPED_TRACE(name);
    Triangulation direct;
    direct.insert_bulk(pts);
    Triangulation previewed = direct;
    std::vector<VertexId> order;
    for (VertexId v = 1; v < direct.vertex_id_bound(); ++v) {
      if (direct.is_vertex(v)) order.push_back(v);
    }
    std::shuffle(order.begin(), order.end(), std::mt19937(51));
    std::size_t compared = 0;
    for (std::size_t i = 0; i + 1 < order.size() && direct.dimension() == 2; ++i) {
      const VertexId v = order[i];
      const auto want = previewed.removal_preview(v);
      const auto got = direct.removal_preview(v);
      ASSERT_TRUE(want.ok() && got.ok());
      compared += !direct.is_on_hull(v) && got->size() >= 3 ? 1 : 0;  // degree 5 or more
      ASSERT_EQ(*got, *want) << "preview of vertex " << v << " after " << i << " removals";
      // Another vertex's preview, so that the next remove_vertex(v) plans v afresh.
      ASSERT_TRUE(direct.removal_preview(order[i + 1]).ok());
      ASSERT_TRUE(previewed.remove_vertex(v).ok());
      ASSERT_TRUE(direct.remove_vertex(v).ok());
      ASSERT_EQ(triangle_set(direct), triangle_set(previewed)) << "after removing vertex " << v;
      if (i % 50 == 0) {
        ASSERT_NO_FATAL_FAILURE(expect_valid(direct));
      }
    }
    EXPECT_GE(compared, 10u);
    expect_valid(direct);
  }
}

// The benchmark's pattern: half of a quantised scan-line set removed in scan order (each
// removal next to the previous one's new triangles), exact validity checked along the way.
TEST(Removal, HalfOfQuantisedScanLinesInScanOrderStaysDelaunay) {
  const auto pts = quantised_scan_lines(3000, 48);
  Triangulation t;
  const auto res = t.insert_bulk(pts);
  std::mt19937 rng(5);
  std::size_t removed = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (rng() % 2 == 0 || !t.is_vertex(res[i].vertex)) continue;
    const Status s = t.remove_vertex(res[i].vertex);
    ASSERT_TRUE(s.ok()) << s.error().message;
    if (++removed % 100 == 0) {
      ASSERT_NO_FATAL_FAILURE(expect_valid(t));
    }
  }
  EXPECT_GT(removed, 1200u);
  expect_valid(t);
}

TEST(Removal, HullVertexRemovalShrinksTheHull) {
  Triangulation t;
  for (const Point3& p : {Point3{0, 0, 0}, Point3{4, 0, 0}, Point3{4, 4, 0}, Point3{0, 4, 0},
                          Point3{2, 1, 0}, Point3{1, 2, 0}, Point3{3, 2, 0}}) {
    t.insert(p);
  }
  const VertexId corner = *t.find_vertex(4, 4);
  ASSERT_TRUE(t.is_on_hull(corner));
  ASSERT_TRUE(t.remove_vertex(corner).ok());
  expect_valid(t);
  EXPECT_NEAR(
      static_cast<double>(test::triangle_area_sum(t)),
      static_cast<double>(test::hull_area({{0, 0}, {4, 0}, {0, 4}, {2, 1}, {1, 2}, {3, 2}})),
      1e-12);
}

TEST(Removal, RemovingAVertexThatLeavesCollinearPointsDropsAllTriangles) {
  Triangulation t;
  for (int i = 0; i < 5; ++i) t.insert({double(i), 0, 0});
  const auto apex = t.insert({2, 3, 0});
  ASSERT_EQ(t.num_finite_triangles(), 4u);
  ASSERT_TRUE(t.removal_preview(apex.vertex)->empty());
  ASSERT_TRUE(t.remove_vertex(apex.vertex).ok());
  EXPECT_EQ(t.num_finite_triangles(), 0u);
  EXPECT_EQ(t.dimension(), 1);
  EXPECT_EQ(t.num_vertices(), 5u);
  // and it comes back when a point off the line arrives
  t.insert({1, -1, 0});
  EXPECT_EQ(t.num_finite_triangles(), 4u);
  expect_valid(t);
}

// Regression: a vertex touching every triangle is not necessarily the last point off a line.
TEST(Removal, OnlyInteriorVertexOfAConvexPolygonLeavesItsTriangulation) {
  Triangulation t;
  for (const Point3& p : {Point3{0, 0, 0}, Point3{2, 0, 0}, Point3{2, 2, 0}, Point3{0, 2, 0}})
    t.insert(p);
  const auto c = t.insert({1.0, 0.9, 5});
  ASSERT_EQ(t.num_finite_triangles(), 4u);
  const auto preview = t.removal_preview(c.vertex);
  ASSERT_TRUE(preview.ok());
  EXPECT_EQ(preview->size(), 2u);
  ASSERT_TRUE(t.remove_vertex(c.vertex).ok());
  EXPECT_EQ(t.num_finite_triangles(), 2u);
  EXPECT_EQ(t.dimension(), 2);
  expect_valid(t);
  // and the same for a hull vertex: an end of the diagonal of a convex quadrilateral touches
  // both triangles, and removing it leaves one triangle
  Triangulation h;
  for (const Point3& p : {Point3{0, 0, 0}, Point3{2, 0, 0}, Point3{2.5, 1.5, 0}, Point3{0, 1, 0}}) {
    h.insert(p);
  }
  ASSERT_EQ(h.num_finite_triangles(), 2u);
  VertexId diagonal_end = kNone;
  for (VertexId v = 1; v < h.vertex_id_bound(); ++v) {
    if (h.incident_triangles(v).size() == 2) diagonal_end = v;
  }
  ASSERT_NE(diagonal_end, kNone);
  ASSERT_TRUE(h.remove_vertex(diagonal_end).ok());
  EXPECT_EQ(h.num_finite_triangles(), 1u);
  expect_valid(h);
}

// The centre of a ring of n points (radii jittered, no four cocircular) is joined to all of
// them; removing it must give the triangulation of the ring alone. Degrees around 24 and 64
// cross the limits of the ear queue and of remove_vertex's slot reuse (above 64 the general
// write-back runs).
TEST(Removal, HighDegreeCentreLeavesTheTriangulationOfItsRing) {
  for (int n : {5, 6, 7, 24, 25, 40, 63, 64, 65, 66, 100}) {
    SCOPED_TRACE(n);
    std::mt19937 rng(static_cast<unsigned>(n));
    std::uniform_real_distribution<double> jitter(1.0, 1.0 + 0.5 / (n * n));
    std::vector<Point3> ring;
    for (int i = 0; i < n; ++i) {
      const double a = 2.0 * M_PI * i / n, r = jitter(rng);
      ring.push_back({r * std::cos(a), r * std::sin(a), 0.0});
    }
    Triangulation with, without;
    for (const Point3& p : ring) {
      with.insert(p);
      without.insert(p);
    }
    const auto c = with.insert({0.001, -0.002, 0.0});
    ASSERT_EQ(with.incident_triangles(c.vertex).size(), static_cast<std::size_t>(n));
    ASSERT_TRUE(with.remove_vertex(c.vertex).ok());
    expect_valid(with);
    EXPECT_EQ(triangle_set(with), triangle_set(without));
    // the freed and reused slots still work for further edits
    const auto d = with.insert({0.3, 0.1, 0.0});
    ASSERT_TRUE(with.remove_vertex(d.vertex).ok());
    expect_valid(with);
    EXPECT_EQ(triangle_set(with), triangle_set(without));
  }
}

TEST(Removal, RemovedVertexIdIsNotReused) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(50, 3));
  const VertexId v = 10;
  ASSERT_TRUE(t.remove_vertex(v).ok());
  const auto r = t.insert({0.123, 0.456, 0});
  EXPECT_NE(r.vertex, v);
  EXPECT_FALSE(t.is_vertex(v));
  EXPECT_FALSE(t.remove_vertex(v).ok());
}

TEST(Removal, ConstraintEndpointIsRefused) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(100, 12));
  const auto a = t.insert({0.1, 0.1, 0}).vertex, b = t.insert({0.9, 0.8, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(a, b).ok());
  const Status s = t.remove_vertex(a);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::invalid_argument);
  EXPECT_NE(s.error().message.find("constrained"), std::string::npos);
  EXPECT_FALSE(t.removal_preview(a).ok());
  EXPECT_TRUE(t.is_vertex(a));
  expect_valid(t);
}

TEST(Removal, VertexSplittingAStraightConstraintRejoinsIt) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(200, 13, 0.0, 1.0));
  const auto a = t.insert({0.0, 0.5, 0}).vertex;
  const auto m = t.insert({0.5, 0.5, 0}).vertex;
  const auto b = t.insert({1.0, 0.5, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(a, b).ok());
  ASSERT_TRUE(t.is_constrained_edge(a, m) || !t.is_edge(a, m));
  const auto preview = t.removal_preview(m);
  ASSERT_TRUE(preview.ok());
  ASSERT_TRUE(t.remove_vertex(m).ok());
  expect_valid(t);
  // the chain from a to b is still constrained and no longer passes through m
  EXPECT_FALSE(t.is_vertex(m));
  std::size_t on_line = 0;
  for (VertexId v = 1; v < t.vertex_id_bound(); ++v) {
    if (t.is_vertex(v) && t.xy(v).y == 0.5) ++on_line;
  }
  EXPECT_EQ(on_line, 2u);
  EXPECT_TRUE(t.is_constrained_edge(a, b));
}

TEST(Removal, RejoiningOnTheHullKeepsTheBorderConstrained) {
  Triangulation t(Rect{0, 0, 1, 1});
  t.insert_bulk(test::uniform_points(100, 14, 0.01, 0.99));
  const auto c0 = t.insert({0, 0, 0}).vertex, c1 = t.insert({1, 0, 0}).vertex;
  t.insert({1, 1, 0});
  t.insert({0, 1, 0});
  ASSERT_TRUE(t.insert_constraint(c0, c1).ok());
  const auto mid = t.insert({0.5, 0.0, 0}).vertex;  // lands on the constrained hull edge
  ASSERT_TRUE(t.is_constrained_edge(c0, mid));
  ASSERT_TRUE(t.is_constrained_edge(mid, c1));
  ASSERT_TRUE(t.remove_vertex(mid).ok());
  EXPECT_TRUE(t.is_constrained_edge(c0, c1));
  expect_valid(t);
}

// Found by kernel_fuzzer (core/kernel/fuzz/regressions/preview_of_a_pending_vertex): before three
// non-collinear points exist, remove_vertex drops a vertex but removal_preview refused it as "not a
// live vertex". The preview has the same refusals as the removal: here none, and no triangle.
TEST(Removal, PreviewOfAVertexBeforeTheFirstTriangleAgreesWithRemoval) {
  Triangulation t;
  const VertexId a = t.insert({0, 0, 0, 0}).vertex;
  const VertexId b = t.insert({1, 1, 0, 0}).vertex;
  t.insert({2, 2, 0, 0});  // collinear: still no triangle
  ASSERT_LT(t.dimension(), 2);
  auto preview = t.removal_preview(b);
  ASSERT_TRUE(preview.ok()) << preview.error().message;
  EXPECT_TRUE(preview->empty());
  ASSERT_TRUE(t.remove_vertex(b).ok());
  EXPECT_FALSE(t.is_vertex(b));
  EXPECT_TRUE(t.is_vertex(a));
  EXPECT_FALSE(t.removal_preview(b).ok());  // gone now: refused by both
  EXPECT_FALSE(t.remove_vertex(b).ok());
  expect_valid(t);
}

}  // namespace
}  // namespace tinstream::kernel
