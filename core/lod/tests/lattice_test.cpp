// The lattice scan of gridded input (src/lattice.hpp, LodOptions::lattice_scan): the lattice is
// recognised exactly, a triangle's runs cover every cell of the closed triangle (exact
// predicates), and both thinning stages choose what the general path (every point filed under
// its triangle) chooses.
#include "../src/lattice.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "../src/greedy.hpp"
#include "lod_test_support.hpp"
#include "tinstream/kernel/predicates.hpp"
#include "tinstream/lod/thinning.hpp"

namespace tinstream::lod {
namespace {

using detail::find_lattice;
using tile::Vertex;

using testing::kTile;

// Rows spaced like a geographic grid in Web Mercator (not uniform), columns uniform.
std::vector<Vertex> mercator_like(int w, int h, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> dz(-5.0, 5.0);
  std::vector<Vertex> pts;
  for (int j = 0; j < h; ++j) {
    const double lat = 0.3 + 0.001 * j;
    const double y = std::log(std::tan(M_PI / 4 + lat / 2));
    for (int i = 0; i < w; ++i) pts.push_back({0.25 + 1e-3 * i, y, 100.0 + dz(rng), 0.0});
  }
  std::shuffle(pts.begin(), pts.end(), rng);
  return pts;
}

TEST(Lattice, FindsARectilinearLatticeInAnyOrder) {
  const auto pts = mercator_like(37, 23, 1);
  const auto l = find_lattice(pts);
  ASSERT_TRUE(l.has_value());
  EXPECT_EQ(l->xs.size(), 37u);
  EXPECT_EQ(l->ys.size(), 23u);
  for (std::size_t c = 0; c < l->cells(); ++c) {
    const Vertex& p = pts[l->point[c]];
    EXPECT_EQ(p.x, l->xs[c % l->width()]);
    EXPECT_EQ(p.y, l->ys[c / l->width()]);
    EXPECT_EQ(p.z, l->z[c]);
  }
  EXPECT_TRUE(l->weight.empty());
}

TEST(Lattice, RejectsGapsDuplicatesAndStrays) {
  const auto pts = mercator_like(9, 7, 2);
  auto missing = pts;
  missing.erase(missing.begin() + 20);
  EXPECT_FALSE(find_lattice(missing).has_value());
  auto duplicate = pts;
  duplicate[20] = duplicate[21];  // one position twice, one missing: same count
  EXPECT_FALSE(find_lattice(duplicate).has_value());
  auto stray = pts;
  stray[5].x += 1e-12;  // off every column
  EXPECT_FALSE(find_lattice(stray).has_value());
  auto bad = pts;
  bad[3].z = std::nan("");
  EXPECT_FALSE(find_lattice(bad).has_value());
}

// Every cell of the closed triangle (exact orientation tests) is visited exactly once, and a
// visited cell outside it is within the documented millionth of a cell.
TEST(Lattice, RunsCoverEveryCellOfTheClosedTriangle) {
  const auto pts = mercator_like(60, 50, 3);
  const auto l = find_lattice(pts);
  ASSERT_TRUE(l.has_value());
  std::mt19937 rng(4);
  std::uniform_int_distribution<std::size_t> ci(0, l->width() - 1), cj(0, l->ys.size() - 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int lattice_vertices = 0;
  for (int trial = 0; trial < 300; ++trial) {
    kernel::XY v[3];
    for (auto& p : v) {
      if (trial % 2 == 0) {  // lattice points: edges through cells, like the meshes' own
        p = {l->xs[ci(rng)], l->ys[cj(rng)]};
        ++lattice_vertices;
      } else {
        p = {l->xs.front() + u(rng) * (l->xs.back() - l->xs.front()),
             l->ys.front() + u(rng) * (l->ys.back() - l->ys.front())};
      }
    }
    const double o = kernel::orient2d(v[0], v[1], v[2]);
    if (o == 0) continue;
    if (o < 0) std::swap(v[1], v[2]);
    std::vector<int> seen(l->cells(), 0);
    l->for_each_run(v[0], v[1], v[2], [&](std::size_t j, std::size_t i0, std::size_t i1) {
      ASSERT_LE(i0, i1);
      for (std::size_t i = i0; i <= i1; ++i) ++seen[j * l->width() + i];
    });
    for (std::size_t c = 0; c < l->cells(); ++c) {
      const kernel::XY q{l->xs[c % l->width()], l->ys[c / l->width()]};
      const bool inside = kernel::orient2d(v[0], v[1], q) >= 0 &&
                          kernel::orient2d(v[1], v[2], q) >= 0 &&
                          kernel::orient2d(v[2], v[0], q) >= 0;
      ASSERT_LE(seen[c], 1);
      if (inside) {
        ASSERT_EQ(seen[c], 1) << "trial " << trial << " missed cell " << c;
      } else if (seen[c]) {
        // Outside: only by the tolerance (a millionth of a cell, in x).
        double worst = 0;
        for (int k = 0; k < 3; ++k) {
          const kernel::XY& a = v[k];
          const kernel::XY& b = v[(k + 1) % 3];
          const double cross = (b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x);
          if (cross < 0 && b.y != a.y) worst = std::max(worst, -cross / std::abs(b.y - a.y));
        }
        EXPECT_LT(worst, 2e-6 * 1e-3) << "trial " << trial;
      }
    }
  }
  EXPECT_GT(lattice_vertices, 0);
}

// A grid tile with heights that leave no ties (pseudo-random), optionally weighted.
tile::TinTile noisy_grid(int n, std::uint32_t seed, bool weighted) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> dz(-3.0, 3.0);
  auto f = [&](double x, double y) {
    return 200.0 + 30.0 * std::sin(x * 2.1e4) * std::cos(y * 1.7e4) + dz(rng);
  };
  std::uniform_real_distribution<double> dw(0.0, 1.0);
  std::function<double(double, double)> w;
  if (weighted) w = [&](double, double) { return dw(rng) < 0.01 ? 4.0 : 0.0; };
  return testing::grid_tile(kTile, n, f, w);
}

// The triangulation thin_tile starts the greedy stage from: corners and the whole border,
// constrained.
kernel::Triangulation border_triangulation(const tile::TinTile& t) {
  const geo::MercatorRect r = t.id.bounds();
  kernel::Triangulation tri(kernel::Rect{r.min_x, r.min_y, r.max_x, r.max_y});
  std::vector<kernel::Point3> pts;
  for (const auto& c : t.corners) pts.push_back({c.x, c.y, c.z, c.weight});
  for (const auto* side : {&t.north, &t.east, &t.south, &t.west}) {
    for (const auto& v : *side) pts.push_back({v.x, v.y, v.z, v.weight});
  }
  const auto ins = tri.insert_bulk(pts);
  // Constrain the outer boundary edge by edge (the border chains, in order along each side).
  auto chain = [&](std::vector<kernel::VertexId> ids) {
    for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
      EXPECT_TRUE(tri.insert_constraint(ids[k], ids[k + 1]).ok());
    }
  };
  std::size_t k = 4;
  const std::array<std::array<std::size_t, 2>, 4> ends = {{{0, 1}, {1, 3}, {2, 3}, {0, 2}}};
  const std::array<const std::vector<Vertex>*, 4> sides = {&t.north, &t.east, &t.south, &t.west};
  for (std::size_t s = 0; s < 4; ++s) {
    std::vector<kernel::VertexId> ids = {ins[ends[s][0]].vertex};
    for (std::size_t j = 0; j < sides[s]->size(); ++j) ids.push_back(ins[k++].vertex);
    ids.push_back(ins[ends[s][1]].vertex);
    chain(ids);
  }
  return tri;
}

// The greedy stage alone: the lattice scan inserts the same points as filing them, and the error
// it reports is the brute-force maximum over the points left out (kernel interpolation).
TEST(Lattice, GreedyInsertsWhatFilingInsertsAndReportsTheTrueError) {
  for (bool weighted : {false, true}) {
    const tile::TinTile grid = noisy_grid(48, 7, weighted);
    const auto lattice = find_lattice(grid.interior);
    ASSERT_TRUE(lattice.has_value());
    for (std::size_t budget : {260u, 500u, 1000u}) {
      kernel::Triangulation filed_tri = border_triangulation(grid);
      kernel::Triangulation scan_tri = border_triangulation(grid);
      auto filed = detail::greedy_insert(filed_tri, grid.interior, {}, budget, 0.0, nullptr);
      auto scanned = detail::greedy_insert(scan_tri, grid.interior, {}, budget, 0.0, &*lattice);
      ASSERT_TRUE(filed.ok() && scanned.ok());
      ASSERT_GT(scanned->inserted, 0u);
      EXPECT_EQ(scanned->inserted, filed->inserted);
      std::size_t same = 0;
      for (std::size_t i = 0; i < grid.interior.size(); ++i) {
        same += (filed->vertex[i] == kernel::kNone) == (scanned->vertex[i] == kernel::kNone);
      }
      EXPECT_EQ(same, grid.interior.size()) << "budget " << budget << " weighted " << weighted;
      EXPECT_NEAR(scanned->max_error, filed->max_error, 1e-9 * (1 + filed->max_error));
      EXPECT_EQ(scanned->orphans.size(), 0u);  // the candidates are scanned, not filed
      double brute = 0;
      for (std::size_t i = 0; i < grid.interior.size(); ++i) {
        if (scanned->vertex[i] != kernel::kNone) continue;
        const Vertex& p = grid.interior[i];
        const auto z = scan_tri.interpolate(p.x, p.y);
        ASSERT_TRUE(z.has_value());
        brute = std::max(brute, std::abs(*z - p.z) + p.weight);
      }
      EXPECT_NEAR(scanned->max_error, brute, 1e-9 * (1 + brute)) << "budget " << budget;
    }
  }
}

// Max |surface − z| over every input point of `grid`, brute force over the thinned tile.
double brute_max_error(const tile::TinTile& thinned, const tile::TinTile& grid) {
  double worst = 0;
  for (const auto& p : grid.vertices()) {
    const auto z = testing::brute_height(thinned, p.x, p.y, false);
    EXPECT_TRUE(z.has_value());
    if (z) worst = std::max(worst, std::abs(*z - p.z));
  }
  return worst;
}

std::set<std::pair<double, double>> positions(const std::vector<Vertex>& v) {
  std::set<std::pair<double, double>> s;
  for (const auto& p : v) s.insert({p.x, p.y});
  return s;
}

// The whole thinning (greedy, then the drop stage scanning the removed stars' cells): the same
// tile as the general path. (With weights the two may differ by a swap: a point on the outline
// of a removed star counts on the lattice, in the general path only when it was filed inside.)
TEST(Lattice, ThinTileKeepsWhatTheGeneralPathKeeps) {
  for (bool weighted : {false, true}) {
    const tile::TinTile grid = noisy_grid(40, 9, weighted);  // 39² interior points
    for (std::size_t budget : {50u, 200u, 350u}) {           // the scan needs more than 4 × budget
      LodOptions o;
      o.max_points = budget;
      ThinStats scan_st, filed_st;
      auto scanned = thin_tile(thin_input(grid), o, &scan_st);
      o.lattice_scan = false;
      auto filed = thin_tile(thin_input(grid), o, &filed_st);
      ASSERT_TRUE(scanned.ok() && filed.ok());
      o.lattice_scan = true;
      o.max_points = 400;  // 4 × 400 > 39²: the general path
      ThinStats small_st;
      ASSERT_TRUE(thin_tile(thin_input(grid), o, &small_st).ok());
      EXPECT_FALSE(small_st.lattice);
      EXPECT_GT(small_st.greedy_inserted, 0u);
      EXPECT_TRUE(scan_st.lattice);
      EXPECT_FALSE(filed_st.lattice);
      ASSERT_GT(scan_st.greedy_inserted, 0u);
      EXPECT_EQ(scan_st.greedy_inserted, filed_st.greedy_inserted);
      EXPECT_NEAR(scan_st.greedy_error, filed_st.greedy_error, 1e-9 * (1 + filed_st.greedy_error));
      EXPECT_EQ(scanned->vertex_count(), budget);
      EXPECT_TRUE(tile::check_structure(*scanned).ok());
      const auto a = positions(scanned->interior), b = positions(filed->interior);
      std::vector<std::pair<double, double>> differ;
      std::set_symmetric_difference(a.begin(), a.end(), b.begin(), b.end(),
                                    std::back_inserter(differ));
      EXPECT_LE(differ.size(), weighted ? 2u : 0u) << "budget " << budget;
      if (!weighted) {
        EXPECT_NEAR(scan_st.last_error, filed_st.last_error, 1e-9 * (1 + filed_st.last_error));
      }
      const double scan_max = brute_max_error(*scanned, grid);
      const double filed_max = brute_max_error(*filed, grid);
      EXPECT_LE(scan_max, 1.05 * filed_max) << "budget " << budget << " weighted " << weighted;
    }
  }
}

}  // namespace
}  // namespace tinstream::lod
