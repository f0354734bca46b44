#include <gtest/gtest.h>

#include <random>

#include "test_support.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel {
namespace {

TEST(Interpolation, PlaneIsReproducedInsideAndNothingOutside) {
  auto pts = test::uniform_points(2000, 61);
  for (auto& p : pts) p.z = 2.0 * p.x - 3.0 * p.y + 1.0;
  Triangulation t;
  t.insert_bulk(pts);
  std::mt19937_64 rng(62);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int k = 0; k < 1000; ++k) {
    const double x = u(rng), y = u(rng);
    const auto z = t.interpolate(x, y);
    ASSERT_TRUE(z.has_value());
    EXPECT_NEAR(*z, 2.0 * x - 3.0 * y + 1.0, 1e-9);
  }
  EXPECT_FALSE(t.interpolate(1.5, 0.5).has_value());
  EXPECT_FALSE(t.interpolate(-0.1, -0.1).has_value());
  EXPECT_EQ(*t.interpolate(pts[7].x, pts[7].y), pts[7].z);  // at a vertex: its own elevation
}

TEST(Interpolation, EmptyOrCollinearGivesNothing) {
  Triangulation t;
  EXPECT_FALSE(t.interpolate(0, 0).has_value());
  t.insert({0, 0, 1});
  t.insert({1, 1, 1});
  EXPECT_FALSE(t.interpolate(0.5, 0.5).has_value());
}

// index_of and index_of_neighbour are branch-free; other modules test membership with
// index_of(t, v) >= 0, so a vertex not in the triangle must give -1.
TEST(Accessors, MeshIndexOfFindsEveryCornerAndNeighbourAndMinusOneOtherwise) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(200, 63));
  const Mesh& m = t.mesh();
  std::size_t checked = 0;
  for (TriangleId id = 0; id < m.triangle_slots(); ++id) {
    if (!m.is_live(id)) continue;
    const Triangle& tr = m.tri(id);
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(m.index_of(id, tr.v[static_cast<std::size_t>(i)]), i);
      const TriangleId u = tr.n[static_cast<std::size_t>(i)];
      ASSERT_NE(u, kNone);
      const int j = m.index_of_neighbour(u, id);
      EXPECT_EQ(m.tri(u).n[static_cast<std::size_t>(j)], id);
      EXPECT_EQ(m.mirror(id, i), j);
      // The vertex of u opposite the shared edge is not a corner of this triangle.
      EXPECT_EQ(m.index_of(id, m.tri(u).v[static_cast<std::size_t>(j)]), -1);
    }
    EXPECT_EQ(m.index_of(id, static_cast<VertexId>(t.vertex_id_bound() + 5)), -1);
    ++checked;
  }
  EXPECT_GT(checked, 300u);
}

TEST(Accessors, StarOfACentreVertexIsCounterClockwise) {
  Triangulation t;
  const auto c = t.insert({0, 0, 0}).vertex;
  std::vector<VertexId> ring;
  for (int i = 0; i < 6; ++i) {
    const double a = i * std::numbers::pi / 3.0 + 0.1;
    ring.push_back(t.insert({std::cos(a), std::sin(a), 0}).vertex);
  }
  const auto adj = t.adjacent_vertices(c);
  ASSERT_EQ(adj.size(), 6u);
  const auto start = std::find(adj.begin(), adj.end(), ring[0]) - adj.begin();
  for (std::size_t i = 0; i < 6; ++i)
    EXPECT_EQ(adj[(static_cast<std::size_t>(start) + i) % 6], ring[i]);
  EXPECT_EQ(t.incident_triangles(c).size(), 6u);
  EXPECT_FALSE(t.is_on_hull(c));
  EXPECT_TRUE(t.is_on_hull(ring[2]));
  EXPECT_EQ(t.adjacent_vertices(ring[0], true).size(), 4u);  // c, two hull neighbours, infinite
  EXPECT_TRUE(t.is_edge(c, ring[3]));
  EXPECT_FALSE(t.is_edge(ring[0], ring[3]));
  EXPECT_EQ(t.find_vertex(std::cos(0.1), std::sin(0.1)), ring[0]);
  EXPECT_FALSE(t.find_vertex(0.5, 0.5).has_value());
  EXPECT_EQ(t.num_finite_triangles(), 6u);
  EXPECT_EQ(t.num_vertices(), 7u);
}

TEST(Islands, RemovingTrianglesOutsideARectLeavesValidIslands) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(3000, 63));
  const Rect keep{0.25, 0.25, 0.6, 0.7};
  const std::size_t before = t.num_finite_triangles();
  const std::size_t dropped = t.remove_triangles_outside(keep);
  EXPECT_GT(dropped, 0u);
  EXPECT_EQ(t.num_finite_triangles(), before - dropped);
  EXPECT_TRUE(t.is_cut());
  const Status s = t.check_valid(CheckLevel::expensive);
  ASSERT_TRUE(s.ok()) << s.error().message;
  std::size_t cut_edges = 0;
  t.for_each_finite_triangle([&](TriangleId, const Triangle& tr) {
    const XY &a = t.xy(tr.v[0]), &b = t.xy(tr.v[1]), &c = t.xy(tr.v[2]);
    EXPECT_TRUE(keep.contains((a.x + b.x + c.x) / 3, (a.y + b.y + c.y) / 3));
    for (TriangleId n : tr.n) cut_edges += n == kNone;
  });
  EXPECT_GT(cut_edges, 0u);
  // queries still work; edits are refused
  EXPECT_TRUE(t.interpolate(0.4, 0.5).has_value());
  EXPECT_FALSE(t.interpolate(0.1, 0.1).has_value());
  EXPECT_EQ(t.insert({0.5, 0.5, 0}).outcome, InsertOutcome::rejected);
}

TEST(Islands, PredicateRemovalCanLeaveSeveralIslands) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(2000, 64));
  // keep two disjoint discs
  t.remove_triangles_if([&](const VertexTriple& tr) {
    const XY& a = t.xy(tr[0]);
    const double d1 = std::hypot(a.x - 0.25, a.y - 0.25), d2 = std::hypot(a.x - 0.75, a.y - 0.75);
    return d1 > 0.15 && d2 > 0.15;
  });
  ASSERT_TRUE(t.check_valid(CheckLevel::cheap).ok());
  EXPECT_TRUE(t.interpolate(0.25, 0.25).has_value());
  EXPECT_TRUE(t.interpolate(0.75, 0.75).has_value());  // reached across the gap
  EXPECT_FALSE(t.interpolate(0.5, 0.5).has_value());
}

TEST(Validity, FreshAndEmptyTriangulationsAreValid) {
  Triangulation t;
  EXPECT_TRUE(t.check_valid(CheckLevel::expensive).ok());
  EXPECT_EQ(t.dimension(), -1);
  t.insert({1, 1, 1});
  EXPECT_EQ(t.dimension(), 0);
  EXPECT_TRUE(t.check_valid(CheckLevel::expensive).ok());
}

}  // namespace
}  // namespace tinstream::kernel
