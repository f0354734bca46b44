#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "test_support.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel {
namespace {

using test::sorted;

using test::expect_valid;

std::size_t count_containing(const Triangulation& t, VertexId v) {
  std::size_t n = 0;
  t.for_each_finite_triangle([&](TriangleId, const Triangle& tr) {
    if (tr.v[0] == v || tr.v[1] == v || tr.v[2] == v) ++n;
  });
  return n;
}

TEST(Delaunay, InsertInsideMakesThreeTriangles) {
  Triangulation t;
  t.insert({0, 0, 0});
  t.insert({4, 0, 0});
  t.insert({0, 4, 0});
  EXPECT_EQ(t.num_finite_triangles(), 1u);
  const InsertResult r = t.insert({1, 1, 7});
  ASSERT_EQ(r.outcome, InsertOutcome::inserted);
  EXPECT_EQ(t.num_finite_triangles(), 3u);
  EXPECT_EQ(count_containing(t, r.vertex), 3u);
  EXPECT_EQ(t.z(r.vertex), 7.0);
  expect_valid(t);
}

TEST(Delaunay, InsertOnEdgeMakesFourTriangles) {
  Triangulation t;
  for (const Point3& p : {Point3{0, 0, 0}, Point3{2, 0, 0}, Point3{2, 2, 0}, Point3{0, 2, 0}})
    t.insert(p);
  ASSERT_EQ(t.num_finite_triangles(), 2u);
  const InsertResult r = t.insert({1, 1, 0});  // on whichever diagonal exists
  ASSERT_EQ(r.outcome, InsertOutcome::inserted);
  EXPECT_EQ(t.num_finite_triangles(), 4u);
  EXPECT_EQ(count_containing(t, r.vertex), 4u);
  expect_valid(t);
}

TEST(Delaunay, InsertOnHullEdgeSplitsIt) {
  Triangulation t;
  for (const Point3& p : {Point3{0, 0, 0}, Point3{2, 0, 0}, Point3{1, 3, 0}}) t.insert(p);
  const InsertResult r = t.insert({1, 0, 0});
  ASSERT_EQ(r.outcome, InsertOutcome::inserted);
  EXPECT_EQ(t.num_finite_triangles(), 2u);
  EXPECT_TRUE(t.is_on_hull(r.vertex));
  expect_valid(t);
}

TEST(Delaunay, InsertOutsideHullExtendsIt) {
  Triangulation t;
  for (const Point3& p : {Point3{0, 0, 0}, Point3{1, 0, 0}, Point3{0, 1, 0}}) t.insert(p);
  t.insert({5, 5, 0});
  EXPECT_EQ(t.num_finite_triangles(), 2u);
  t.insert({2, 0, 0});  // collinear with the hull edge (0,0)-(1,0), beyond it
  expect_valid(t);
  EXPECT_DOUBLE_EQ(static_cast<double>(test::triangle_area_sum(t)),
                   static_cast<double>(test::hull_area({{0, 0}, {1, 0}, {0, 1}, {5, 5}, {2, 0}})));
}

TEST(Delaunay, DuplicateIsRejectedWithExistingId) {
  Triangulation t;
  const auto a = t.insert({0, 0, 1});
  t.insert({1, 0, 0});
  t.insert({0, 1, 0});
  const auto d = t.insert({0, 0, 99});
  EXPECT_EQ(d.outcome, InsertOutcome::duplicate);
  EXPECT_EQ(d.vertex, a.vertex);
  EXPECT_EQ(t.z(a.vertex), 1.0);
  EXPECT_EQ(t.num_vertices(), 3u);
}

TEST(Delaunay, DuplicateWhileCollinearIsRejected) {
  Triangulation t;
  const auto a = t.insert({0, 0, 1});
  t.insert({1, 1, 0});
  EXPECT_EQ(t.insert({0, 0, 5}).vertex, a.vertex);
  EXPECT_EQ(t.insert({0, 0, 5}).outcome, InsertOutcome::duplicate);
}

TEST(Delaunay, OutsideDomainIsRejected) {
  Triangulation t(Rect{0, 0, 1, 1});
  EXPECT_EQ(t.insert({0.5, 0.5, 0}).outcome, InsertOutcome::inserted);
  EXPECT_EQ(t.insert({1.0, 1.0, 0}).outcome, InsertOutcome::inserted);  // closed rectangle
  const auto r = t.insert({1.5, 0.5, 0});
  EXPECT_EQ(r.outcome, InsertOutcome::outside_domain);
  EXPECT_EQ(r.vertex, kNone);
  EXPECT_EQ(t.num_vertices(), 2u);
}

TEST(Delaunay, NonFinitePointIsRejected) {
  Triangulation t;
  EXPECT_EQ(t.insert({std::nan(""), 0, 0}).outcome, InsertOutcome::rejected);
  EXPECT_EQ(t.num_vertices(), 0u);
}

TEST(Delaunay, CollinearPointsWaitForAPointOffTheirLine) {
  Triangulation t;
  const auto pts = test::collinear_points(50, 1);
  for (const auto& p : pts) t.insert(p);
  const std::size_t n = test::distinct_count(pts);
  EXPECT_EQ(t.num_finite_triangles(), 0u);
  EXPECT_EQ(t.dimension(), 1);
  EXPECT_EQ(t.num_vertices(), n);
  t.insert({0.0, 1.0, 0});
  EXPECT_EQ(t.dimension(), 2);
  EXPECT_EQ(t.num_finite_triangles(), n - 1);  // a fan over the n - 1 segments of the line
  expect_valid(t);
}

using test::Generator;

const Generator kInsertionGenerators[] = {
    {"uniform", [] { return test::uniform_points(300, 1); }},
    {"clustered", [] { return test::clustered_points(300, 2); }},
    {"lattice", [] { return test::lattice_points(17); }},
    {"circle", [] { return test::circle_points(64); }},
    {"collinear_then_more",
     [] {
       auto p = test::collinear_points(100, 3);
       auto q = test::uniform_points(100, 4);
       p.insert(p.end(), q.begin(), q.end());
       return p;
     }},
    {"duplicates", [] { return test::duplicate_heavy_points(400, 5); }},
    {"ulp_apart", [] { return test::ulp_points(300, 6); }},
    {"mercator_tile", [] { return test::mercator_tile_points(300, 7); }},
    {"huge", [] { return test::scaled(test::uniform_points(200, 8), 1e25, 3e25); }},
    {"tiny", [] { return test::scaled(test::uniform_points(200, 9), 1e-25, -1e-24); }},
};

class DelaunayProperty : public ::testing::TestWithParam<Generator> {};

TEST_P(DelaunayProperty, EveryInsertionKeepsTheTriangulationValid) {
  const auto pts = GetParam().make();
  Triangulation t;
  std::set<std::pair<double, double>> seen;
  for (const auto& p : pts) {
    const InsertResult r = t.insert(p);
    const bool fresh = seen.insert({p.x, p.y}).second;
    ASSERT_EQ(r.outcome, fresh ? InsertOutcome::inserted : InsertOutcome::duplicate);
    ASSERT_NO_FATAL_FAILURE(expect_valid(t));
  }
  EXPECT_EQ(t.num_vertices(), seen.size());
  for (const auto& p : pts) ASSERT_TRUE(t.find_vertex(p.x, p.y).has_value());
  if (t.dimension() == 2) {
    const long double hull = test::hull_area(pts);
    EXPECT_NEAR(static_cast<double>(test::triangle_area_sum(t) / hull), 1.0, 1e-9);
  }
}

TEST_P(DelaunayProperty, BulkInsertionGivesAValidTriangulationOfAllPoints) {
  const auto pts = GetParam().make();
  Triangulation t;
  const auto results = t.insert_bulk(pts);
  ASSERT_EQ(results.size(), pts.size());
  expect_valid(t);
  EXPECT_EQ(t.num_vertices(), test::distinct_count(pts));
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_NE(results[i].vertex, kNone);
    EXPECT_EQ(t.xy(results[i].vertex).x, pts[i].x);
    EXPECT_EQ(t.xy(results[i].vertex).y, pts[i].y);
  }
  if (t.dimension() == 2) {
    EXPECT_NEAR(static_cast<double>(test::triangle_area_sum(t) / test::hull_area(pts)), 1.0, 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(Fixtures, DelaunayProperty, ::testing::ValuesIn(kInsertionGenerators),
                         [](const auto& p) { return std::string(p.param.name); });

TEST(Delaunay, GeneralPositionResultDoesNotDependOnInsertionOrder) {
  // In general position the Delaunay triangulation is unique: one-by-one and bulk must agree.
  const auto pts = test::uniform_points(3000, 21);
  Triangulation a, b;
  std::vector<VertexId> ida(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) ida[i] = a.insert(pts[i]).vertex;
  const auto rb = b.insert_bulk(pts);
  std::vector<std::uint32_t> a_to_input(a.vertex_id_bound()), b_to_input(b.vertex_id_bound());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    a_to_input[ida[i]] = static_cast<std::uint32_t>(i);
    b_to_input[rb[i].vertex] = static_cast<std::uint32_t>(i);
  }
  std::set<VertexTriple> sa, sb;
  for (auto t : a.finite_triangles())
    sa.insert(sorted({a_to_input[t[0]], a_to_input[t[1]], a_to_input[t[2]]}));
  for (auto t : b.finite_triangles())
    sb.insert(sorted({b_to_input[t[0]], b_to_input[t[1]], b_to_input[t[2]]}));
  EXPECT_EQ(sa, sb);
}

// Triangles as sets of input indices, each rotated to start at its smallest index (the
// counter-clockwise order kept).
std::set<VertexTriple> input_triangles(const Triangulation& t,
                                       const std::vector<InsertResult>& inserted) {
  std::vector<std::uint32_t> to_input(t.vertex_id_bound(), 0);
  for (std::size_t i = 0; i < inserted.size(); ++i) {
    if (inserted[i].outcome == InsertOutcome::inserted)
      to_input[inserted[i].vertex] = static_cast<std::uint32_t>(i);
  }
  std::set<VertexTriple> out;
  for (const auto& tri : t.finite_triangles()) {
    VertexTriple v{to_input[tri[0]], to_input[tri[1]], to_input[tri[2]]};
    std::rotate(v.begin(), std::min_element(v.begin(), v.end()), v.end());
    out.insert(v);
  }
  return out;
}

TEST(Delaunay, PerturbedTiesGiveOneTriangulationWhateverTheInsertionOrder) {
  // A lattice (every square cocircular), exactly cocircular integer circles and random points
  // between them: with set_perturbed_ties every insertion order — bulk, one by one forwards and
  // backwards, shuffled — gives the same triangles; without it the orders disagree (so the test
  // can tell), and every edge of the result is locally Delaunay under the perturbation, checked
  // edge by edge with perturbed_incircle (which makes it the unique perturbed triangulation).
  std::vector<Point3> pts = test::lattice_points(24, 0.25);
  for (const Point3& p : test::circle_points(0)) pts.push_back({p.x + 6.0, p.y + 3.0, 0.0, 0.0});
  for (const Point3& p : test::uniform_points(200, 5, 0.0, 6.0)) pts.push_back(p);
  auto build = [&](bool perturbed, const std::vector<std::size_t>& order, bool bulk) {
    Triangulation t;
    t.set_perturbed_ties(perturbed);
    std::vector<InsertResult> inserted(pts.size(), InsertResult{InsertOutcome::rejected, kNone});
    if (bulk) {
      std::vector<Point3> permuted;
      permuted.reserve(order.size());
      for (std::size_t i : order) permuted.push_back(pts[i]);
      const auto r = t.insert_bulk(permuted);
      for (std::size_t k = 0; k < order.size(); ++k) inserted[order[k]] = r[k];
    } else {
      for (std::size_t i : order) inserted[i] = t.insert(pts[i]);
    }
    for (const auto& r : inserted) EXPECT_EQ(r.outcome, InsertOutcome::inserted);
    expect_valid(t);
    return std::pair{input_triangles(t, inserted), std::move(t)};
  };
  std::vector<std::size_t> forwards(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) forwards[i] = i;
  std::vector<std::size_t> backwards(forwards.rbegin(), forwards.rend());
  std::vector<std::size_t> shuffled = forwards;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(7));

  const auto built = build(true, forwards, true);
  const std::set<VertexTriple>& reference = built.first;
  const Triangulation& t = built.second;
  for (const auto& order : {forwards, backwards, shuffled}) {
    EXPECT_EQ(build(true, order, false).first, reference);
    EXPECT_EQ(build(true, order, true).first, reference);
  }
  EXPECT_NE(build(false, forwards, false).first, build(false, backwards, false).first)
      << "the fixture has no ties that insertion order decides";

  // Every interior edge (a, b) with c and d on its two sides: d is outside the circle of
  // (c, a, b) under the perturbation.
  std::size_t edges = 0;
  t.for_each_finite_triangle([&](TriangleId id, const Triangle& tri) {
    for (int i = 0; i < 3; ++i) {
      const TriangleId nb = tri.n[i];
      if (nb == kNone) continue;
      const Triangle& other = t.mesh().tri(nb);
      const int j = t.mesh().index_of_neighbour(nb, id);
      if (other.v[j] == kInfiniteVertex) continue;
      ++edges;
      EXPECT_LT(perturbed_incircle(t.xy(tri.v[i]), t.xy(tri.v[(i + 1) % 3]),
                                   t.xy(tri.v[(i + 2) % 3]), t.xy(other.v[j])),
                0);
    }
  });
  EXPECT_GT(edges, 2 * pts.size());
}

TEST(Delaunay, BulkDuplicatesKeepTheFirstInInputOrder) {
  auto pts = test::uniform_points(5000, 23);
  const std::size_t n = pts.size();
  for (std::size_t i = 0; i < n; i += 3) pts.push_back({pts[i].x, pts[i].y, -1.0 - double(i), 0.0});
  Triangulation t;
  const auto r = t.insert_bulk(pts);
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(r[i].outcome, InsertOutcome::inserted) << i;
    ASSERT_EQ(t.z(r[i].vertex), pts[i].z);
  }
  for (std::size_t i = n; i < pts.size(); ++i) {
    ASSERT_EQ(r[i].outcome, InsertOutcome::duplicate);
    ASSERT_EQ(r[i].vertex, r[(i - n) * 3].vertex);
  }
}

TEST(Delaunay, LargeBulkInsertionIsValid) {
  const auto pts = test::uniform_points(200000, 99);
  Triangulation t;
  t.insert_bulk(pts);
  expect_valid(t);
  EXPECT_EQ(t.num_vertices(), pts.size());
}

// The same mesh, slot by slot: vertex coordinates and every triangle's vertices and neighbours.
void expect_same_mesh(const Triangulation& a, const Triangulation& b) {
  ASSERT_EQ(a.vertex_id_bound(), b.vertex_id_bound());
  for (VertexId v = 1; v < a.vertex_id_bound(); ++v) {
    ASSERT_EQ(a.xy(v).x, b.xy(v).x) << v;
    ASSERT_EQ(a.xy(v).y, b.xy(v).y) << v;
  }
  ASSERT_EQ(a.mesh().triangle_slots(), b.mesh().triangle_slots());
  for (TriangleId t = 0; t < a.mesh().triangle_slots(); ++t) {
    ASSERT_EQ(a.mesh().tri(t).v, b.mesh().tri(t).v) << t;
    ASSERT_EQ(a.mesh().tri(t).n, b.mesh().tri(t).n) << t;
  }
}

TEST(Delaunay, ClearedTriangulationRebuildsExactlyAsANewOne) {
  // clear() must leave no state behind (constraints, randomized walks, the cut flag, the hint):
  // a reused triangulation gives the same ids and triangles as a new one, ties included (a
  // lattice: cocircular squares, resolved by insertion order), and keeps its memory.
  Triangulation reused;
  reused.insert_bulk(test::uniform_points(3000, 31));
  ASSERT_TRUE(reused.insert_constraint({0.1, 0.1, 0, 0}, {0.9, 0.8, 0, 0}).ok());
  ASSERT_TRUE(reused.remove_vertex(5).ok());
  reused.remove_triangles_outside({0.2, 0.2, 0.8, 0.8});
  ASSERT_TRUE(reused.is_cut());
  const std::size_t memory = reused.memory_bytes();
  reused.clear();
  EXPECT_EQ(reused.num_vertices(), 0u);
  EXPECT_EQ(reused.dimension(), -1);
  EXPECT_FALSE(reused.is_cut());
  EXPECT_EQ(reused.memory_bytes(), memory);
  expect_valid(reused);

  auto pts = test::lattice_points(40, 0.25);
  const auto more = test::uniform_points(500, 37, 0.0, 9.75);
  pts.insert(pts.end(), more.begin(), more.end());
  Triangulation fresh;
  const auto rf = fresh.insert_bulk(pts);
  const auto rr = reused.insert_bulk(pts);
  ASSERT_EQ(rf.size(), rr.size());
  for (std::size_t i = 0; i < rf.size(); ++i) {
    ASSERT_EQ(rf[i].outcome, rr[i].outcome) << i;
    ASSERT_EQ(rf[i].vertex, rr[i].vertex) << i;
  }
  ASSERT_TRUE(fresh.insert_constraint(rf[3].vertex, rf[1500].vertex).ok());
  ASSERT_TRUE(reused.insert_constraint(rr[3].vertex, rr[1500].vertex).ok());
  ASSERT_TRUE(fresh.remove_vertex(rf[700].vertex).ok());
  ASSERT_TRUE(reused.remove_vertex(rr[700].vertex).ok());
  expect_same_mesh(fresh, reused);
  expect_valid(reused);
}

}  // namespace
}  // namespace tinstream::kernel
