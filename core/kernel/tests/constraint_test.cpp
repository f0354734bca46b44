#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <set>

#include "test_support.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel {
namespace {

using test::expect_valid;

TEST(Constraint, ExistingEdgeBecomesConstrained) {
  Triangulation t;
  const auto a = t.insert({0, 0, 0}).vertex, b = t.insert({1, 0, 0}).vertex;
  t.insert({0, 1, 0});
  ASSERT_FALSE(t.is_constrained_edge(a, b));
  ASSERT_TRUE(t.insert_constraint(a, b).ok());
  EXPECT_TRUE(t.is_constrained_edge(a, b));
  EXPECT_TRUE(t.is_constrained_edge(b, a));
  expect_valid(t);
}

TEST(Constraint, SegmentAcrossManyTrianglesBecomesAnEdge) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(2000, 51));
  const auto a = t.insert({0.0, 0.3, 0}).vertex, b = t.insert({1.0, 0.71, 0}).vertex;
  ASSERT_FALSE(t.is_edge(a, b));
  ASSERT_TRUE(t.insert_constraint(a, b).ok());
  EXPECT_TRUE(t.is_constrained_edge(a, b));
  expect_valid(t);
}

TEST(Constraint, VerticesOnTheSegmentSplitIt) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(500, 52));
  const auto a = t.insert({0.0, 0.5, 0}).vertex;
  const auto m1 = t.insert({0.25, 0.5, 0}).vertex;
  const auto m2 = t.insert({0.75, 0.5, 0}).vertex;
  const auto b = t.insert({1.0, 0.5, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(a, b).ok());
  EXPECT_TRUE(t.is_constrained_edge(a, m1));
  EXPECT_TRUE(t.is_constrained_edge(m1, m2));
  EXPECT_TRUE(t.is_constrained_edge(m2, b));
  EXPECT_FALSE(t.is_edge(a, b));
  expect_valid(t);
}

TEST(Constraint, ACrossingOnTheEndOfAnotherConstraintGoesThroughThatVertex) {
  // kernel_fuzzer's vertex_on_a_new_constraint_doubled_then_removed (core/kernel/fuzz/regressions):
  // c-e passes exactly through a, the end of constraint a-d, but first crosses b-d at the rounded
  // point (4/3, 1/6); from there on it passed an ulp beside a and got a second intersection vertex
  // there, splitting a-d next to its end. Removing a then merged two constraints into a segment
  // that is no chain.
  Triangulation t(Rect{-1, -1, 17, 17});
  const auto a = t.insert({3, 1, 0}).vertex, d = t.insert({0, 0, 0}).vertex;
  const auto c = t.insert({1, 0, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(a, d).ok());
  const auto b = t.insert({8, 1, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(b, d).ok());
  const auto e = t.insert({15, 7, 0}).vertex;
  t.insert({4, 0, 0});
  t.insert({11, 8, 0});
  const std::size_t before = t.num_vertices();
  ASSERT_TRUE(t.insert_constraint(c, e).ok());
  EXPECT_EQ(t.num_vertices(), before + 1) << "one crossing (with b-d), no vertex beside a";
  EXPECT_TRUE(t.is_constrained_edge(a, e)) << "c-e goes through a";
  expect_valid(t);
  (void)t.remove_vertex(a);  // refused or done, the constraints stay chains
  expect_valid(t);
}

TEST(Constraint, TheEndOfAConstraintBentThroughAVertexIsNotRemovedAsAStraightSplit) {
  // kernel_fuzzer's bent_constraint_end_removed (core/kernel/fuzz/regressions): v lies 3.5e-18
  // beside the vertex o = (0, 0), on the x axis. Constraint v-p is routed v-o-p (o is within
  // rounding of its line), then q-o passes exactly through v. v's constrained edges v-q and v-o
  // are collinear, so its removal was taken for that of a vertex splitting q-o, and the record
  // v-p became q-p: a segment that is no chain.
  Triangulation t(Rect{-1, -1, 17, 17});
  t.insert_bulk(std::vector<Point3>{{12, 12, 0}, {12, 15, 0}, {9, 14, 0}, {2, 14, 0}});
  const auto q = t.insert({15, 0, 0}).vertex, o = t.insert({0, 0, 0}).vertex;
  const auto p = t.insert({0, 8, 0}).vertex, far = t.find_vertex(12, 15).value();
  ASSERT_TRUE(t.insert_constraint(o, far).ok());
  const auto v = t.insert({3.4685999190063599e-18, 0, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(v, p).ok());
  ASSERT_TRUE(t.is_constrained_edge(v, o) && t.is_constrained_edge(o, p)) << "v-p bent through o";
  ASSERT_TRUE(t.insert_constraint(q, o).ok());
  ASSERT_TRUE(t.is_constrained_edge(q, v)) << "q-o through v";
  expect_valid(t);
  EXPECT_EQ(t.removal_preview(v).ok(), false);
  EXPECT_EQ(t.remove_vertex(v).ok(), false) << "v ends the bent constraint v-p";
  expect_valid(t);
}

TEST(Constraint, CrossingConstraintsMeetAtANewInterpolatedVertex) {
  Triangulation t;
  const auto a = t.insert({0, 0, 0}).vertex, c = t.insert({2, 2, 10}).vertex;
  const auto b = t.insert({2, 0, 4}).vertex, d = t.insert({0, 2, 8}).vertex;
  t.insert_bulk(test::scaled(test::uniform_points(100, 53), 2.0, 0.0));
  ASSERT_TRUE(t.insert_constraint(a, c).ok());
  const std::size_t before = t.num_vertices();
  ASSERT_TRUE(t.insert_constraint(b, d).ok());
  EXPECT_EQ(t.num_vertices(), before + 1);
  const auto x = t.find_vertex(1.0, 1.0);
  ASSERT_TRUE(x.has_value());
  EXPECT_DOUBLE_EQ(t.z(*x), 6.0);  // halfway along b (4) -> d (8)
  EXPECT_TRUE(t.is_constrained_edge(a, *x) || t.check_valid(CheckLevel::expensive).ok());
  expect_valid(t);
}

TEST(Constraint, ConstrainedEdgeSurvivesLaterInsertions) {
  Triangulation t;
  const auto a = t.insert({0, 0, 0}).vertex, b = t.insert({10, 0, 0}).vertex;
  t.insert({5, 1, 0});
  t.insert({5, -1, 0});
  ASSERT_TRUE(t.insert_constraint(a, b).ok());
  // points inside the circumcircles on both sides would flip a-b in an unconstrained mesh
  t.insert({5, 0.5, 0});
  t.insert({5, -0.5, 0});
  t.insert({2, 0.1, 0});
  EXPECT_TRUE(t.is_constrained_edge(a, b));
  expect_valid(t);
  const auto m = t.insert({5, 0, 0});  // exactly on the constrained edge: splits it
  EXPECT_TRUE(t.is_constrained_edge(a, m.vertex));
  EXPECT_TRUE(t.is_constrained_edge(m.vertex, b));
  expect_valid(t);
}

TEST(Constraint, ManyRandomNonCrossingSegmentsKeepValidity) {
  Triangulation t(Rect{0, 0, 1, 1});
  t.insert_bulk(test::uniform_points(3000, 54));
  std::mt19937_64 rng(55);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // one short segment per cell of a 20 x 20 grid: they cannot cross
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      const Point3 p{(i + 0.1 + 0.8 * u(rng)) / 20.0, (j + 0.1 + 0.8 * u(rng)) / 20.0, 1.0};
      const Point3 q{(i + 0.1 + 0.8 * u(rng)) / 20.0, (j + 0.1 + 0.8 * u(rng)) / 20.0, 2.0};
      ASSERT_TRUE(t.insert_constraint(p, q).ok());
    }
  }
  expect_valid(t);
  EXPECT_EQ(t.constraint_segments().size(), 400u);
}

TEST(Constraint, CrossingRandomSegmentsKeepValidity) {
  Triangulation t;
  t.insert_bulk(test::uniform_points(500, 56));
  std::mt19937_64 rng(57);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 30; ++k) {
    const Status s = t.insert_constraint(Point3{u(rng), u(rng), 0}, Point3{u(rng), u(rng), 1}).ok()
                         ? Status{}
                         : Status{Error(ErrorCode::internal, "failed")};
    ASSERT_TRUE(s.ok()) << k;
    ASSERT_NO_FATAL_FAILURE(expect_valid(t));
  }
}

TEST(Constraint, TileBorderOnALatticeSplitsAtEveryLatticePoint) {
  Triangulation t;
  t.insert_bulk(test::lattice_points(11));
  const auto a = *t.find_vertex(0, 0), b = *t.find_vertex(10, 0);
  const auto c = *t.find_vertex(10, 10), d = *t.find_vertex(0, 10);
  for (auto [p, q] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, d}, std::pair{d, a}}) {
    ASSERT_TRUE(t.insert_constraint(p, q).ok());
  }
  const auto e = *t.find_vertex(0, 3), f = *t.find_vertex(10, 7);
  ASSERT_TRUE(t.insert_constraint(e, f).ok());
  for (int i = 0; i < 10; ++i) {
    EXPECT_TRUE(t.is_constrained_edge(*t.find_vertex(i, 0), *t.find_vertex(i + 1, 0)));
  }
  expect_valid(t);
}

TEST(Constraint, BadRequestsAreReported) {
  Triangulation t;
  const auto a = t.insert({0, 0, 0}).vertex, b = t.insert({1, 0, 0}).vertex;
  EXPECT_EQ(t.insert_constraint(a, b).error().code, ErrorCode::unsupported);  // still 1-D
  t.insert({0, 1, 0});
  EXPECT_EQ(t.insert_constraint(a, a).error().code, ErrorCode::invalid_argument);
  EXPECT_EQ(t.insert_constraint(a, 999).error().code, ErrorCode::invalid_argument);
  Triangulation d(Rect{0, 0, 1, 1});
  d.insert({0, 0, 0});
  d.insert({1, 0, 0});
  d.insert({0, 1, 0});
  EXPECT_FALSE(d.insert_constraint(Point3{0.5, 0.5, 0}, Point3{2, 2, 0}).ok());
}

// Found by kernel_fuzzer (core/kernel/fuzz/regressions/chain_check_two_long_constraints): two
// constraints from one far vertex to two near ones point the same way to within rounding; the
// checker's greedy walk along the first one reported the second as "not a chain of constrained
// edges" although it is an edge.
// Removing v, which splits the straight chain x-a-v-b made of the records x-v and v-b, re-ends
// each record at the re-join vertex beyond v: x-b and a-b (both still chains; a record re-ended
// on its own side would only shorten, which check_valid cannot see).
TEST(Constraint, RecordsEndingAtARemovedSplitVertexAreReEndedBeyondIt) {
  Triangulation t;
  t.insert_bulk(std::vector<Point3>{{0, 5, 0}, {9, 5, 0}, {0, -5, 0}, {9, -5, 0}, {4, 2, 0}});
  const auto x = t.insert({1, 0, 0}).vertex, a = t.insert({3, 0, 0}).vertex;
  const auto v = t.insert({5, 0, 0}).vertex, b = t.insert({7, 0, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(x, v).ok());
  ASSERT_TRUE(t.insert_constraint(v, b).ok());
  ASSERT_TRUE(t.is_constrained_edge(x, a) && t.is_constrained_edge(a, v)) << "x-v through a";
  ASSERT_TRUE(t.remove_vertex(v).ok());
  std::set<std::array<VertexId, 2>> records;
  for (auto s : t.constraint_segments()) {
    if (s[0] > s[1]) std::swap(s[0], s[1]);
    records.insert(s);
  }
  const auto pair = [](VertexId p, VertexId q) {
    return std::array<VertexId, 2>{std::min(p, q), std::max(p, q)};
  };
  EXPECT_EQ(records, (std::set<std::array<VertexId, 2>>{pair(x, b), pair(a, b)}));
  EXPECT_TRUE(t.is_constrained_edge(a, b));
  expect_valid(t);
}

TEST(Constraint, LongConstraintsSharingAFarEndBothPassTheChainCheck) {
  Triangulation t;
  const VertexId origin = t.insert({0, 0, 0, 0}).vertex;
  const VertexId top = t.insert({0, 15, 0, 0}).vertex;
  const VertexId mid = t.insert({0, 9, 0, 0}).vertex;
  const VertexId far = t.insert({1015000000, 0, 0, 0}).vertex;
  ASSERT_TRUE(t.insert_constraint(mid, far).ok());
  ASSERT_TRUE(t.remove_vertex(origin).ok());
  t.insert({5, 13.999999999999998, 0, 0});
  t.insert({0, 0, 0, 0});
  t.insert({0, 1, 0, 0});
  ASSERT_TRUE(t.insert_constraint(far, top).ok());
  EXPECT_TRUE(t.is_constrained_edge(far, top));
  EXPECT_TRUE(t.is_constrained_edge(far, mid));
  const Status valid = t.check_valid(CheckLevel::expensive);
  EXPECT_TRUE(valid.ok()) << valid.error().message;
}

// Found by kernel_fuzzer (regressions/chain_check_ulp_apart_intersections): a constraint crossing
// two constraints that almost coincide gets two intersection vertices one ulp apart; the short
// edge between them points anywhere, and the checker's walk by edge direction lost the chain.
TEST(Constraint, AChainThroughIntersectionsOneUlpApartPassesTheCheck) {
  Triangulation t;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{0, 0},
                                                                   {0, 1},
                                                                   {0, 4},
                                                                   {1, 0},
                                                                   {1, 1},
                                                                   {1, 2},
                                                                   {1, 3},
                                                                   {3, 3.9999999999999996},
                                                                   {2, 0},
                                                                   {2, 1},
                                                                   {3, 0},
                                                                   {1, 4}}) {
    t.insert({x, y, 0, 0});
  }
  auto at = [&](double x, double y) { return *t.find_vertex(x, y); };
  ASSERT_TRUE(t.insert_constraint(at(1, 3), at(0, 1)).ok());
  ASSERT_TRUE(t.insert_constraint(at(3, 3.9999999999999996), at(0, 1)).ok());
  ASSERT_TRUE(t.insert_constraint(at(0, 1), at(1, 2)).ok());
  ASSERT_TRUE(t.insert_constraint(at(0, 4), at(1, 0)).ok());
  // The last one crosses the second and third at (0.6, 1.6) rounded two ways.
  EXPECT_TRUE(t.find_vertex(0.6, 1.6000000000000001).has_value());
  EXPECT_TRUE(t.find_vertex(0.6, 1.5999999999999999).has_value());
  const Status valid = t.check_valid(CheckLevel::expensive);
  EXPECT_TRUE(valid.ok()) << valid.error().message;
}

}  // namespace
}  // namespace tinstream::kernel
