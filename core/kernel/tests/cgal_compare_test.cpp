// Our triangulations against CGAL's (Exact_predicates_inexact_constructions_kernel), on the same
// points. Vertices are matched by coordinates (the first input index with those coordinates), so
// duplicate handling does not matter; triangles are compared as sets of sorted index triples.
// The only heavy CGAL translation unit of the test suite.
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

#include "test_support.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<std::uint32_t, K>;
using Tds = CGAL::Triangulation_data_structure_2<Vb>;
using Cgal_dt = CGAL::Delaunay_triangulation_2<K, Tds>;
using CFb = CGAL::Constrained_triangulation_face_base_2<K>;
using CTds = CGAL::Triangulation_data_structure_2<Vb, CFb>;
using Cgal_cdt = CGAL::Constrained_Delaunay_triangulation_2<K, CTds, CGAL::Exact_predicates_tag>;

using test::sorted;
using Key = std::pair<double, double>;

struct Canon {
  std::map<Key, std::uint32_t> first;
  explicit Canon(const std::vector<Point3>& pts) {
    for (std::size_t i = 0; i < pts.size(); ++i)
      first.emplace(Key{pts[i].x, pts[i].y}, static_cast<std::uint32_t>(i));
  }
  std::uint32_t operator()(double x, double y) const { return first.at(Key{x, y}); }
};

std::set<VertexTriple> ours(const Triangulation& t, const Canon& c) {
  std::set<VertexTriple> s;
  t.for_each_finite_triangle([&](TriangleId, const Triangle& tr) {
    VertexTriple k;
    for (int i = 0; i < 3; ++i)
      k[static_cast<std::size_t>(i)] =
          c(t.xy(tr.v[static_cast<std::size_t>(i)]).x, t.xy(tr.v[static_cast<std::size_t>(i)]).y);
    s.insert(sorted(k));
  });
  return s;
}

template <typename Tr>
std::set<VertexTriple> theirs(const Tr& tr, const Canon& c) {
  std::set<VertexTriple> s;
  for (auto f : tr.finite_face_handles()) {
    VertexTriple k;
    for (int i = 0; i < 3; ++i)
      k[static_cast<std::size_t>(i)] = c(f->vertex(i)->point().x(), f->vertex(i)->point().y());
    s.insert(sorted(k));
  }
  return s;
}

std::vector<std::pair<K::Point_2, std::uint32_t>> cgal_points(const std::vector<Point3>& pts) {
  std::vector<std::pair<K::Point_2, std::uint32_t>> v;
  v.reserve(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    v.emplace_back(K::Point_2(pts[i].x, pts[i].y), static_cast<std::uint32_t>(i));
  return v;
}

// Every triangle of ours that CGAL does not have must have a cocircular neighbour (a tie that
// either answer may break differently); otherwise the difference is a bug.
std::size_t non_tie_differences(const Triangulation& t, const Canon& c,
                                const std::set<VertexTriple>& cgal) {
  std::size_t bad = 0;
  const Mesh& m = t.mesh();
  t.for_each_finite_triangle([&](TriangleId id, const Triangle& tr) {
    VertexTriple k;
    for (int i = 0; i < 3; ++i)
      k[static_cast<std::size_t>(i)] =
          c(t.xy(tr.v[static_cast<std::size_t>(i)]).x, t.xy(tr.v[static_cast<std::size_t>(i)]).y);
    if (cgal.count(sorted(k))) return;
    bool tie = false;
    for (int i = 0; i < 3; ++i) {
      const TriangleId u = tr.n[static_cast<std::size_t>(i)];
      if (u == kNone || m.is_ghost(u)) continue;
      const VertexId q = m.tri(u).v[static_cast<std::size_t>(m.mirror(id, i))];
      if (incircle(t.xy(tr.v[0]), t.xy(tr.v[1]), t.xy(tr.v[2]), t.xy(q)) == 0.0) tie = true;
    }
    if (!tie) ++bad;
  });
  return bad;
}

void compare_delaunay(const std::vector<Point3>& pts, bool expect_unique) {
  Triangulation t;
  t.insert_bulk(pts);
  Cgal_dt dt;
  const auto cp = cgal_points(pts);
  dt.insert(cp.begin(), cp.end());
  const Canon c(pts);
  const auto a = ours(t, c), b = theirs(dt, c);
  EXPECT_EQ(t.num_vertices(), dt.number_of_vertices());
  EXPECT_EQ(a.size(), b.size());
  if (expect_unique) {
    EXPECT_TRUE(a == b) << "triangle sets differ";
  } else {
    EXPECT_EQ(non_tie_differences(t, c, b), 0u);
  }
  const Status s = t.check_valid(CheckLevel::expensive);
  EXPECT_TRUE(s.ok()) << s.error().message;
}

TEST(CgalDelaunay, UniformRandom100kMatchesCgal) {
  compare_delaunay(test::uniform_points(100000, 71), true);
}

TEST(CgalDelaunay, Clustered100kMatchesCgal) {
  compare_delaunay(test::clustered_points(100000, 72), true);
}

TEST(CgalDelaunay, MercatorTileScale100kMatchesCgal) {
  compare_delaunay(test::mercator_tile_points(100000, 73), true);
}

TEST(CgalDelaunay, ManyDuplicatesMatchCgal) {
  auto pts = test::uniform_points(60000, 74);
  std::mt19937 rng(75);
  for (int k = 0; k < 60000; ++k) {
    Point3 d = pts[rng() % 60000];
    d.z += 1.0;
    pts.push_back(d);
  }
  compare_delaunay(pts, true);
}

TEST(CgalDelaunay, CocircularLatticeAgreesUpToTies) {
  compare_delaunay(test::lattice_points(320), false);
}

TEST(CgalDelaunay, AutzenLidarAgreesUpToTies) {
  std::vector<Point3> pts;
  if (!test::read_las_xyz(test::autzen_path(), pts))
    GTEST_SKIP() << "real data not found: " << test::autzen_path();
  ASSERT_GT(pts.size(), 100000u);
  compare_delaunay(pts, false);
}

TEST(CgalDelaunay, RemovingHalfThePointsMatchesCgalRemove) {
  const auto pts = test::uniform_points(30000, 76);
  Triangulation t;
  const auto ids = t.insert_bulk(pts);
  Cgal_dt dt;
  const auto cp = cgal_points(pts);
  dt.insert(cp.begin(), cp.end());
  std::map<std::uint32_t, Cgal_dt::Vertex_handle> handle;
  for (auto v : dt.finite_vertex_handles()) handle[v->info()] = v;
  std::mt19937 rng(77);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (rng() % 2) continue;
    ASSERT_TRUE(t.remove_vertex(ids[i].vertex).ok());
    dt.remove(handle.at(static_cast<std::uint32_t>(i)));
  }
  const Canon c(pts);
  EXPECT_TRUE(ours(t, c) == theirs(dt, c));
  EXPECT_TRUE(t.check_valid(CheckLevel::expensive).ok());
}

TEST(CgalConstrained, TileBorderAndRandomSegmentsMatchCgal) {
  auto pts = test::uniform_points(100000, 78, 0.001, 0.999);
  std::vector<std::array<Point3, 2>> segs;
  segs.reserve(4 + 100 * 100);
  const Point3 corners[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (int i = 0; i < 4; ++i) segs.push_back({corners[i], corners[(i + 1) % 4]});
  std::mt19937_64 rng(79);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  for (int i = 0; i < 100; ++i) {  // 1e4 segments, one per cell: no crossings
    for (int j = 0; j < 100; ++j) {
      segs.push_back({Point3{(i + u(rng)) / 100, (j + u(rng)) / 100, 0},
                      Point3{(i + u(rng)) / 100, (j + u(rng)) / 100, 0}});
    }
  }
  std::vector<Point3> all = pts;
  for (const auto& s : segs) {
    all.push_back(s[0]);
    all.push_back(s[1]);
  }
  Triangulation t(Rect{0, 0, 1, 1});
  t.insert_bulk(pts);
  for (const auto& s : segs) ASSERT_TRUE(t.insert_constraint(s[0], s[1]).ok());
  Cgal_cdt cdt;
  const auto cp = cgal_points(pts);
  cdt.insert(cp.begin(), cp.end());
  for (const auto& s : segs)
    cdt.insert_constraint(K::Point_2(s[0].x, s[0].y), K::Point_2(s[1].x, s[1].y));
  const Canon c(all);
  EXPECT_EQ(t.num_vertices(), cdt.number_of_vertices());
  EXPECT_TRUE(ours(t, c) == theirs(cdt, c));
  const Status s = t.check_valid(CheckLevel::expensive);
  EXPECT_TRUE(s.ok()) << s.error().message;
  for (std::size_t k = 0; k < 50; ++k) {
    const auto& sg = segs[k * 97 % segs.size()];
    EXPECT_TRUE(
        t.is_constrained_edge(*t.find_vertex(sg[0].x, sg[0].y), *t.find_vertex(sg[1].x, sg[1].y)) ||
        k * 97 % segs.size() < 4);
  }
}

}  // namespace
}  // namespace tinstream::kernel
