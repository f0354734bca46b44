#include "tinstream/triangulate/finest_tiles.hpp"

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/convex_hull_2.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <numbers>
#include <random>
#include <set>
#include <thread>
#include <tuple>

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::triangulate {
namespace {

namespace fs = std::filesystem;
using subdivide::InputPoint;

struct Fixture {
  fs::path dir;
  subdivide::SortedRun run;
  std::vector<tile::TinTile> tiles;
  TriangulateSummary summary;
};

// Runs pass 2 and pass 3 on `points`; tiles keyed by id.
Fixture build(const std::vector<InputPoint>& points, std::uint32_t max_points, unsigned threads,
              const std::string& name) {
  Fixture f;
  f.dir =
      fs::temp_directory_path() / ("tinstream-tri-test-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(f.dir);
  fs::create_directories(f.dir);
  subdivide::SubdivideOptions opt;
  opt.tmp_dir = f.dir;
  opt.max_points = max_points;
  std::size_t pos = 0;
  auto run = subdivide::subdivide(
      [&](std::vector<InputPoint>& batch) -> Result<std::size_t> {
        const std::size_t n = std::min<std::size_t>(4096, points.size() - pos);
        batch.insert(batch.end(), points.begin() + static_cast<std::ptrdiff_t>(pos),
                     points.begin() + static_cast<std::ptrdiff_t>(pos + n));
        pos += n;
        return n;
      },
      opt);
  EXPECT_TRUE(run.ok()) << run.error().message;
  f.run = *run;
  std::mutex mutex;  // the sink runs on the workers, concurrently
  auto summary = build_finest_tiles(f.run, threads, [&](tile::TinTile&& t) {
    std::lock_guard lock(mutex);
    f.tiles.push_back(std::move(t));
    return Status{};
  });
  EXPECT_TRUE(summary.ok()) << summary.error().message;
  if (summary) f.summary = *summary;
  std::sort(f.tiles.begin(), f.tiles.end(),
            [](const auto& a, const auto& b) { return a.id < b.id; });
  return f;
}

std::vector<InputPoint> random_points(std::size_t n, std::uint64_t seed, double x0, double y0,
                                      double span) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<InputPoint> pts;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = x0 + span * u(rng), y = y0 + span * u(rng);
    pts.push_back({x, y, 100.0 + 50.0 * std::sin(x * 3e4) + 30.0 * std::cos(y * 2e4)});
  }
  return pts;
}

const tile::TinTile* find(const Fixture& f, const geo::TileId& id) {
  for (const auto& t : f.tiles) {
    if (t.id == id) return &t;
  }
  return nullptr;
}

void expect_same_vertices(const std::vector<tile::Vertex>& a, const std::vector<tile::Vertex>& b,
                          const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].x, b[i].x) << what << " #" << i;
    EXPECT_EQ(a[i].y, b[i].y) << what << " #" << i;
    EXPECT_EQ(a[i].z, b[i].z) << what << " #" << i;
  }
}

// Shared borders of same-level neighbours are bit-identical (watertight).
void expect_watertight(const Fixture& f) {
  int shared = 0;
  for (const auto& t : f.tiles) {
    if (auto east = t.id.neighbour(geo::Direction::east)) {
      if (const auto* n = find(f, *east)) {
        expect_same_vertices(t.border(geo::Direction::east), n->border(geo::Direction::west),
                             t.id.quadkey() + " east");
        ++shared;
      }
    }
    if (auto south = t.id.neighbour(geo::Direction::south)) {
      if (const auto* n = find(f, *south)) {
        expect_same_vertices(t.border(geo::Direction::south), n->border(geo::Direction::north),
                             t.id.quadkey() + " south");
        ++shared;
      }
    }
  }
  EXPECT_GT(shared, 0);
}

// Every triangle of every tile is CCW and has no tile vertex strictly inside its circumcircle.
void expect_delaunay_tiles(const Fixture& f) {
  for (const auto& t : f.tiles) {
    ASSERT_TRUE(tile::check_structure(t).ok())
        << t.id.quadkey() << ": " << tile::check_structure(t).error().message;
    const auto v = t.vertices();
    for (const auto& tri : t.triangles) {
      const kernel::XY a{v[tri[0]].x, v[tri[0]].y}, b{v[tri[1]].x, v[tri[1]].y},
          c{v[tri[2]].x, v[tri[2]].y};
      ASSERT_GT(kernel::orient2d(a, b, c), 0.0);
      for (const auto& p : v) {  // O(n·t) — keep inputs small
        ASSERT_LE(kernel::incircle(a, b, c, {p.x, p.y}), 0.0) << t.id.quadkey();
      }
    }
  }
}

using K = CGAL::Exact_predicates_inexact_constructions_kernel;

// The height a NODATA corner must get (docs/tile-format.md §2.1), by brute force: the input point
// nearest to it (dx² + dy²; ties to the smaller x, then y; of exact duplicates the lowest z, the
// one pass 2 keeps).
double nearest_input_height(const std::vector<InputPoint>& pts, kernel::XY c) {
  const InputPoint* best = nullptr;
  double best_d2 = 0;
  for (const auto& p : pts) {
    const double d2 = (p.x - c.x) * (p.x - c.x) + (p.y - c.y) * (p.y - c.y);
    if (!best || d2 < best_d2 ||
        (d2 == best_d2 && std::tie(p.x, p.y, p.z) < std::tie(best->x, best->y, best->z))) {
      best = &p, best_d2 = d2;
    }
  }
  return best->z;
}

// No two vertices of a tile closer than 1e-12 (normalised units), by brute force.
void expect_no_close_vertices(const tile::TinTile& t) {
  const auto v = t.vertices();
  for (std::size_t i = 0; i < v.size(); ++i) {
    for (std::size_t j = i + 1; j < v.size(); ++j) {
      ASSERT_GE(std::hypot(v[i].x - v[j].x, v[i].y - v[j].y), 1e-12)
          << t.id.quadkey() << ": vertices " << i << " and " << j;
    }
  }
}

// Edge points must be exactly the crossings of the GLOBAL Delaunay triangulation's edges with the
// tile borders, on all four sides (computed here from CGAL's triangulation of all points).
void expect_edge_points_match_global(const Fixture& f, const std::vector<InputPoint>& pts) {
  CGAL::Delaunay_triangulation_2<K> dt;
  std::map<std::pair<double, double>, double> z_of;
  std::vector<K::Point_2> in;
  for (const auto& p : pts) {
    in.emplace_back(p.x, p.y);
    auto [it, fresh] = z_of.emplace(std::make_pair(p.x, p.y), p.z);
    if (!fresh) it->second = std::min(it->second, p.z);
  }
  dt.insert(in.begin(), in.end());
  for (const auto& t : f.tiles) {
    const auto r = t.id.bounds();
    const double rmax = FinestTileOptions{}.max_circumradius_tiles * r.width();
    auto kept = [&](CGAL::Delaunay_triangulation_2<K>::Face_handle face) {
      if (dt.is_infinite(face)) return false;
      const auto& p0 = face->vertex(0)->point();
      const auto& p1 = face->vertex(1)->point();
      const auto& p2 = face->vertex(2)->point();
      return canonical_circumradius2({p0.x(), p0.y()}, {p1.x(), p1.y()}, {p2.x(), p2.y()}) <=
             rmax * rmax;
    };
    // Per side: (coordinate along the border, z) of every crossing and every point on it.
    struct Side {
      const char* name;
      const std::vector<tile::Vertex>& edge_points;  // corners excluded
      bool horizontal;  // north/south: the line y = at; east/west: x = at
      double at;
    };
    const Side sides[4] = {{"north", t.north, true, r.max_y},
                           {"south", t.south, true, r.min_y},
                           {"west", t.west, false, r.min_x},
                           {"east", t.east, false, r.max_x}};
    for (const Side& side : sides) {
      const double lo = side.horizontal ? r.min_x : r.min_y;
      const double hi = side.horizontal ? r.max_x : r.max_y;
      // (across, along) of a point for this side.
      auto split = [&](double x, double y) {
        return side.horizontal ? std::make_pair(y, x) : std::make_pair(x, y);
      };
      std::set<std::pair<double, double>> expected, got;
      for (auto e = dt.finite_edges_begin(); e != dt.finite_edges_end(); ++e) {
        if (!kept(e->first) && !kept(e->first->neighbor(e->second))) continue;
        const auto& pa = e->first->vertex(e->first->cw(e->second))->point();
        const auto& pb = e->first->vertex(e->first->ccw(e->second))->point();
        const bool a_first = pa.x() < pb.x() || (pa.x() == pb.x() && pa.y() < pb.y());
        const auto& p = a_first ? pa : pb;
        const auto& q = a_first ? pb : pa;
        const auto [p_across, p_along] = split(p.x(), p.y());
        const auto [q_across, q_along] = split(q.x(), q.y());
        if ((p_across < side.at && q_across > side.at) ||
            (p_across > side.at && q_across < side.at)) {
          const double s = (side.at - p_across) / (q_across - p_across);
          const double along = p_along + s * (q_along - p_along);
          const double zp = z_of.at({p.x(), p.y()}), zq = z_of.at({q.x(), q.y()});
          if (along > lo && along < hi) expected.emplace(along, zp + s * (zq - zp));
        }
      }
      for (const auto& p : pts) {
        const auto [across, along] = split(p.x, p.y);
        if (across == side.at && along > lo && along < hi) expected.emplace(along, p.z);
      }
      for (const auto& v : side.edge_points) got.emplace(split(v.x, v.y).second, v.z);
      EXPECT_EQ(got, expected) << t.id.quadkey() << " " << side.name;
    }
    // Corners: NODATA exactly when no kept global triangle holds them, else on its plane (only
    // corners strictly inside a global triangle or outside the hull: no tie to break here).
    const kernel::XY corner_xy[4] = {
        {r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}};
    for (std::size_t k = 0; k < 4; ++k) {
      using DT = CGAL::Delaunay_triangulation_2<K>;
      DT::Locate_type lt;
      int li = 0;
      const auto face = dt.locate(K::Point_2(corner_xy[k].x, corner_xy[k].y), lt, li);
      if (lt == DT::EDGE || lt == DT::VERTEX) continue;
      if (lt != DT::FACE || !kept(face)) {
        EXPECT_TRUE(t.corner_nodata[k]) << t.id.quadkey() << " corner " << k;
        EXPECT_EQ(t.corners[k].z, nearest_input_height(pts, corner_xy[k]))
            << t.id.quadkey() << " corner " << k;
        continue;
      }
      ASSERT_FALSE(t.corner_nodata[k]) << t.id.quadkey() << " corner " << k;
      double x[3], y[3], z[3];
      for (int i = 0; i < 3; ++i) {
        x[i] = face->vertex(i)->point().x();
        y[i] = face->vertex(i)->point().y();
        z[i] = z_of.at({x[i], y[i]});
      }
      const double det = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
      const double px = corner_xy[k].x - x[0], py = corner_xy[k].y - y[0];
      const double u = (px * (y[2] - y[0]) - py * (x[2] - x[0])) / det;
      const double w = ((x[1] - x[0]) * py - (y[1] - y[0]) * px) / det;
      EXPECT_NEAR(t.corners[k].z, z[0] + u * (z[1] - z[0]) + w * (z[2] - z[0]), 1e-6)
          << t.id.quadkey() << " corner " << k;
    }
  }
}

// Every input point is a vertex of the tile that owns it (TileId::containing).
void expect_no_point_lost(const Fixture& f, const std::vector<InputPoint>& pts) {
  std::map<geo::TileId, std::set<std::pair<double, double>>> vertices;
  for (const auto& t : f.tiles) {
    for (const auto& v : t.vertices()) vertices[t.id].emplace(v.x, v.y);
  }
  for (const auto& p : pts) {
    const auto id = geo::TileId::containing({p.x, p.y}, f.run.finest_level);
    ASSERT_TRUE(vertices[id].count({p.x, p.y})) << id.quadkey() << " lost " << p.x << "," << p.y;
  }
}

// Watertight, Delaunay, nothing lost, edge points from the global triangulation.
void expect_global_tiles(const Fixture& f, const std::vector<InputPoint>& pts) {
  expect_watertight(f);
  expect_delaunay_tiles(f);
  expect_no_point_lost(f, pts);
  expect_edge_points_match_global(f, pts);
}

TEST(FinestTiles, RandomPointsGiveWatertightGloballyDelaunayTiles) {
  const auto pts = random_points(6000, 1, 0.1, 0.2, 3e-4);
  const Fixture f = build(pts, 400, 2, "random");
  ASSERT_GT(f.tiles.size(), 8u);
  EXPECT_EQ(f.tiles.size(), f.run.tiles.size());
  expect_global_tiles(f, pts);
}

TEST(FinestTiles, HaloIsABandNotWholeNeighbours) {
  // Realistic density: a few thousand points per tile, ~10 per sub-cell.
  const auto pts = random_points(120000, 7, 0.1, 0.2, 1e-3);
  const Fixture f = build(pts, 4000, 2, "halo");
  // Away from the data's outer boundary the halo is a band, not whole neighbours: little more
  // than one triangulation per point.
  auto cells = PointCells::build(f.run);
  ASSERT_TRUE(cells.ok());
  auto reader = subdivide::SortedRunReader::open(f.run.path);
  ASSERT_TRUE(reader.ok());
  std::uint32_t x0 = ~0u, x1 = 0, y0 = ~0u, y1 = 0;
  for (const auto& t : f.run.tiles) {
    x0 = std::min(x0, t.id.x), x1 = std::max(x1, t.id.x);
    y0 = std::min(y0, t.id.y), y1 = std::max(y1, t.id.y);
  }
  int interior = 0;
  for (const auto& t : f.run.tiles) {
    if (t.id.x < x0 + 2 || t.id.x + 2 > x1 || t.id.y < y0 + 2 || t.id.y + 2 > y1) continue;
    FinestTileStats stats;
    ASSERT_TRUE(build_finest_tile(t.id, **cells, *reader, {}, &stats).ok());
    EXPECT_LT(stats.gathered_points, 3 * t.count / 2) << t.id.quadkey();
    ++interior;
  }
  EXPECT_GT(interior, 0);
  // Over all tiles (boundary ones included) the overhead stays moderate.
  EXPECT_LT(f.summary.gathered_points, 3 * pts.size());
}

TEST(FinestTiles, SparseTilesAtTheDataEdgeStayWatertight) {
  // A few points per tile (one dense spot deepens the finest level for the whole layer): tiles at
  // the data's edge may hold one or two points of their own, too few for a triangle. They must
  // still gather their halo (once, such a tile stopped at once and lost its edge points).
  const auto pts = random_points(6000, 1, 0.1, 0.2, 3e-4);
  const Fixture f = build(pts, 20, 2, "sparse");
  ASSERT_GT(f.tiles.size(), 300u);
  expect_global_tiles(f, pts);
}

TEST(FinestTiles, DenseSlightlyCurvedLineStaysGlobalAndCheap) {
  // A dense line of points on a slightly curved arc (a densified breakline or survey transect):
  // consecutive points form slivers whose circumcircles are huge and sweep along the whole halo
  // band. Testing every nearby point against every such circle made the halo quadratic (3.7e9
  // in-circle tests for a 2e6-point cloud with such a line); each candidate point is now located
  // and asked once. The tiles must still be exactly the global Delaunay ones.
  auto pts = random_points(6000, 5, 0.1, 0.2, 3e-4);
  for (int i = 0; i < 8000; ++i) {
    const double x = 0.1 + 3e-4 * (i + 0.5) / 8000;
    const double d = x - 0.10015;
    pts.push_back({x, 0.20015 + 50.0 * d * d, 100.0 + 1e6 * d});  // radius of curvature 0.01
  }
  const Fixture f = build(pts, 400, 2, "curved-line");
  ASSERT_GT(f.tiles.size(), 16u);
  expect_global_tiles(f, pts);
  // Work: a few dozen in-circle tests per point (was thousands).
  EXPECT_LT(f.summary.circle_tests, 100 * pts.size()) << f.summary.circle_tests;
}

TEST(FinestTiles, CurvedConcaveHullWithClustersMatchesGlobalOnEveryBorder) {
  // The halo asks only the local triangles that meet a tile's border (the others cannot change
  // its edge points or corners). Inputs where that matters: a crescent (curved, concave data hull
  // running through tiles, with long slivers and huge circles along it, some only touching a tile
  // at a corner), dense clusters (very uneven density: sparse tiles whose triangles span corners)
  // and a dense, slightly curved line across the crescent's opening. Every side and corner of
  // every tile must be the global triangulation's.
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double cx = 0.10015, cy = 0.20015;
  auto height = [](double x, double y) {
    return 100.0 + 50.0 * std::sin(x * 3e4) + 30.0 * std::cos(y * 2e4);
  };
  std::vector<InputPoint> pts;
  for (int i = 0; i < 4000; ++i) {
    const double rad = std::sqrt(0.36e-8 + u(rng) * (1.44e-8 - 0.36e-8));  // 0.6e-4 .. 1.2e-4
    const double a = 1.4 * std::numbers::pi * u(rng);
    const double x = cx + rad * std::cos(a), y = cy + rad * std::sin(a);
    pts.push_back({x, y, height(x, y)});
  }
  for (int k = 0; k < 3; ++k) {
    const double a = 0.3 + 0.9 * k;
    const double mx = cx + 0.9e-4 * std::cos(a), my = cy + 0.9e-4 * std::sin(a);
    for (int i = 0; i < 500; ++i) {
      const double x = mx + 4e-6 * gauss(rng), y = my + 4e-6 * gauss(rng);
      pts.push_back({x, y, height(x, y)});
    }
  }
  for (int i = 0; i < 1500; ++i) {  // an arc of radius 1e-3 under the opening
    const double t = -0.08 + 0.16 * (i + 0.5) / 1500;
    const double x = cx + 0.6e-4 + 1e-3 * std::sin(t), y = cy - 1e-3 + 1e-3 * std::cos(t) - 0.3e-4;
    pts.push_back({x, y, height(x, y)});
  }
  const Fixture f = build(pts, 150, 2, "crescent");
  ASSERT_GT(f.tiles.size(), 30u);
  expect_global_tiles(f, pts);
}

TEST(FinestTiles, BorderCirclesReachingDeepIntoTheTileMatchGlobal) {
  // The halo starts from a band along each tile's border (the ring and the own border cells) and
  // must pull in own cells further inside when a border triangle's circle reaches them. Here it
  // must: every tile has two points per border cell on a line just inside each side (the
  // neighbour's line, shifted by half a step, just outside), so the triangles across each border
  // have flat circles reaching 1.3 cells into the tile, where a row of points 1.1 cells deep lies
  // in them. A band that stopped at the border cells gives other edge points than CGAL's.
  const geo::TileId base{12, 2000, 1500};
  const double width = base.bounds().width();
  const double step = width / 32;  // half a cell (16 cells per tile side)
  const double depth = 0.05 * step;
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<InputPoint> pts;
  auto add = [&](double x, double y) { pts.push_back({x, y, 100.0 + 10.0 * u(rng)}); };
  for (std::uint32_t ty = 0; ty < 4; ++ty) {
    for (std::uint32_t tx = 0; tx < 4; ++tx) {
      const auto r = geo::TileId{12, base.x + tx, base.y + ty}.bounds();
      for (int k = 0; k < 32; ++k) {
        const double j = 0.01 * step * u(rng);
        add(r.min_x + (k + 0.25) * step + j, r.max_y - depth);  // north
        add(r.min_x + (k + 0.75) * step + j, r.min_y + depth);  // south
        add(r.min_x + depth, r.min_y + (k + 0.25) * step + j);  // west
        add(r.max_x - depth, r.min_y + (k + 0.75) * step + j);  // east
      }
      for (int k = 2; k < 30; ++k) {  // the row 1.1 cells deep along each side
        const double along = (k + 0.5 + 0.01 * u(rng)) * step;
        const double in = (2.2 + 0.05 * u(rng)) * step;
        add(r.min_x + along, r.max_y - in);
        add(r.min_x + along, r.min_y + in);
        add(r.min_x + in, r.min_y + along);
        add(r.max_x - in, r.min_y + along);
      }
    }
  }
  const Fixture f = build(pts, 300, 2, "deep-circles");
  ASSERT_EQ(f.run.finest_level, 12u);
  ASSERT_EQ(f.tiles.size(), 16u);
  expect_global_tiles(f, pts);
}

TEST(FinestTiles, PlanarSurfaceInterpolatesEdgeAndCornerPointsOnThePlane) {
  auto pts = random_points(3000, 2, -0.3, 0.4, 2e-4);
  for (auto& p : pts) p.z = 1000.0 + 2e5 * (p.x + 0.3) - 1e5 * (p.y - 0.4);
  const Fixture f = build(pts, 300, 1, "plane");
  for (const auto& t : f.tiles) {
    const auto vertices = t.vertices();
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      if (i < 4 && t.corner_nodata[i]) continue;
      const auto& v = vertices[i];
      EXPECT_NEAR(v.z, 1000.0 + 2e5 * (v.x + 0.3) - 1e5 * (v.y - 0.4), 1e-6) << t.id.quadkey();
    }
  }
}

// An edge point (where a surface edge crosses a tile side) is a point of the data's surface: it
// takes the smaller of its edge's two input weights, so the thinning ranks it like the data it
// lies between (with weight 0 beside inputs of weight 1, every coarser level dropped the seams
// first: autzen's level 18 measured 0.24 m there instead of 0.036 m, bench/lod/RESULTS.md).
TEST(FinestTiles, EdgePointsTakeTheSmallerWeightOfTheirEdge) {
  auto pts = random_points(3000, 5, -0.3, 0.4, 2e-4);
  for (auto& p : pts) p.weight = 2.5f;
  const Fixture same = build(pts, 300, 1, "weights-same");
  std::size_t side_points = 0;
  for (const auto& t : same.tiles) {
    for (const auto* side : {&t.north, &t.east, &t.south, &t.west}) {
      for (const auto& v : *side) {
        ++side_points;
        EXPECT_EQ(v.weight, 2.5) << t.id.quadkey() << " side point " << v.x << ", " << v.y;
      }
    }
  }
  EXPECT_GT(side_points, 100u);
  // Two weights by half: min, not an interpolation, gives only those two values, and both.
  for (auto& p : pts) p.weight = p.x < -0.3 + 1e-4 ? 1.0f : 4.0f;
  const Fixture mixed = build(pts, 300, 1, "weights-mixed");
  std::size_t ones = 0, fours = 0;
  for (const auto& t : mixed.tiles) {
    for (const auto* side : {&t.north, &t.east, &t.south, &t.west}) {
      for (const auto& v : *side) {
        EXPECT_TRUE(v.weight == 1.0 || v.weight == 4.0) << v.weight;
        ones += v.weight == 1.0, fours += v.weight == 4.0;
      }
    }
  }
  EXPECT_GT(ones, 10u);
  EXPECT_GT(fours, 10u);
}

TEST(FinestTiles, CornersOutsideTheDataAreNodata) {
  // A thin diagonal strip: many tile corners lie outside the data's convex hull.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // Heights rise along the strip (3,100 … 3,400 m), so a corner's height says where it came from.
  std::vector<InputPoint> pts;
  for (int i = 0; i < 3000; ++i) {
    const double s = u(rng);
    pts.push_back(
        {0.5 + 3e-4 * s + 1e-6 * u(rng), 0.5 + 3e-4 * s + 1e-6 * u(rng), 3100.0 + 300.0 * s});
  }
  const Fixture f = build(pts, 300, 2, "strip");
  int nodata = 0;
  for (const auto& t : f.tiles) {
    const auto r = t.id.bounds();
    const kernel::XY corner_xy[4] = {
        {r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}};
    for (std::size_t k = 0; k < 4; ++k) {
      // Never a wall: within the data's heights; a NODATA corner takes the nearest input point's.
      EXPECT_GE(t.corners[k].z, 3100.0) << t.id.quadkey() << " corner " << k;
      EXPECT_LE(t.corners[k].z, 3400.0) << t.id.quadkey() << " corner " << k;
      if (t.corner_nodata[k]) {
        ++nodata;
        EXPECT_EQ(t.corners[k].z, nearest_input_height(pts, corner_xy[k]))
            << t.id.quadkey() << " corner " << k;
      }
    }
  }
  EXPECT_GT(nodata, 0);
  expect_watertight(f);
  expect_no_point_lost(f, pts);
}

TEST(FinestTiles, GridAlignedLatticeWithPointsOnTileBordersStaysWatertight) {
  // A DEM-like lattice whose rows and columns fall exactly on tile borders (all cocircular).
  const std::uint32_t level = 12;
  const geo::TileId base{level, 2000, 1500};
  const auto r = base.bounds();
  const double step = r.width() / 16;
  std::vector<InputPoint> pts;
  for (int i = -20; i < 52; ++i) {
    for (int j = -20; j < 52; ++j) {
      const double x = r.min_x + i * step, y = r.max_y - j * step;
      pts.push_back({x, y, 10.0 + (i * 7 % 13) + (j * 5 % 11)});
    }
  }
  const Fixture f = build(pts, 400, 2, "lattice");
  ASSERT_GT(f.tiles.size(), 4u);
  expect_watertight(f);
  expect_no_point_lost(f, pts);
  for (const auto& t : f.tiles) {
    ASSERT_TRUE(tile::check_structure(t).ok()) << t.id.quadkey();
  }
}

TEST(FinestTiles, LatticeCellsStraddlingTileBordersStayWatertight) {
  // Every lattice square is cocircular and the tile borders cut through the squares: which
  // diagonal each square gets decides the edge points, so ties must be broken the same way by
  // every tile whatever its neighbourhood.
  const geo::TileId base{12, 2000, 1500};
  const auto r = base.bounds();
  const double step = r.width() / 16;
  std::vector<InputPoint> pts;
  for (int i = -20; i < 52; ++i) {
    for (int j = -20; j < 52; ++j) {
      const double x = r.min_x + (i + 0.5) * step, y = r.max_y - (j + 0.5) * step;
      pts.push_back({x, y, 10.0 + (i * 7 % 13) + (j * 5 % 11)});
    }
  }
  const Fixture f = build(pts, 400, 2, "lattice-offset");
  ASSERT_GT(f.tiles.size(), 4u);
  expect_watertight(f);
  expect_no_point_lost(f, pts);
  // Every tile corner is the centre of a lattice square, which a Delaunay diagonal crosses: the
  // corner is on that edge (exactly), so it gets no edge point beside it (#20: these were 1e-14
  // away and became duplicate vertices in quantised encodings).
  std::size_t corners_on_edges = 0;
  for (const auto& t : f.tiles) {
    expect_no_close_vertices(t);
    for (std::size_t k = 0; k < 4; ++k) corners_on_edges += t.corner_nodata[k] ? 0 : 1;
  }
  EXPECT_GT(corners_on_edges, 4u);
}

TEST(FinestTiles, MetreLatticeCentredOnTileCornersGivesNoEdgePointBesideACorner) {
  // A DEM in EPSG:3857 aligned with the tiles, its cell centres half a cell inside a level-10
  // tile, converted from metres the way the ingest does (x = X / (π·a)): the finest tiles'
  // corners are the centres of lattice squares up to rounding, so their Delaunay diagonals pass
  // 1e-14 from the corners (#20: 63 of 64 finest tiles had such an edge point).
  const double a = 6378137.0, half = std::numbers::pi * a;
  const geo::TileId tile{10, 541, 510};
  const double tile_m = 2 * half / 1024, cell = tile_m / 128;
  const double x0 = -half + tile.x * tile_m, y0 = half - tile.y * tile_m;
  std::vector<InputPoint> pts;
  for (int i = 0; i < 128; ++i) {
    for (int j = 0; j < 128; ++j) {
      const double x = x0 + (i + 0.5) * cell, y = y0 - (j + 0.5) * cell;
      pts.push_back({x / half, y / half, 300.0 + 40.0 * std::sin(i * 0.37) * std::cos(j * 0.23)});
    }
  }
  const Fixture f = build(pts, 1100, 2, "metre-lattice");
  ASSERT_EQ(f.run.finest_level, 12u);
  ASSERT_EQ(f.tiles.size(), 16u);
  expect_watertight(f);
  expect_no_point_lost(f, pts);
  std::size_t inner_corners = 0;
  for (const auto& t : f.tiles) {
    expect_no_close_vertices(t);
    ASSERT_TRUE(tile::check_structure(t).ok()) << t.id.quadkey();
    for (std::size_t k = 0; k < 4; ++k) inner_corners += t.corner_nodata[k] ? 0 : 1;
  }
  // The 3 × 3 inner grid points, four tiles each, have data; the outer ring lies outside it.
  EXPECT_EQ(inner_corners, 36u);
}

TEST(FinestTiles, DataPointARoundingErrorFromABorderIsThatBordersVertexInBothTiles) {
  // A point 7.7e-13 inside a tile's south border (#20: the demo's sparse sample had one): the
  // edges from it cross the border beside it, which gave two edge points and the point itself
  // within 1e-12 of each other (near-duplicate vertices, zero-area triangles once quantised).
  // It is moved onto the border instead, as a vertex of both tiles' shared side.
  const geo::TileId base{12, 2000, 1500};
  const auto r = base.bounds();
  auto pts = random_points(4800, 11, r.min_x, r.max_y - 4 * r.width(), 4 * r.width());
  const geo::TileId north{12, 2001, 1501};
  const auto nr = north.bounds();
  const InputPoint close{(nr.min_x + nr.max_x) / 2, nr.min_y + 7.7e-13, 500.0};
  // A point right below it: their edge crosses the border at close.x, 7.7e-13 from it.
  pts.push_back({close.x, nr.min_y - 1e-6 * nr.width(), 480.0});
  pts.push_back(close);
  const Fixture f = build(pts, 400, 2, "border-close");
  ASSERT_EQ(f.run.finest_level, 12u);
  expect_watertight(f);
  for (const auto& t : f.tiles) expect_no_close_vertices(t);
  const auto* n = find(f, north);
  const auto* s = find(f, geo::TileId{12, 2001, 1502});
  ASSERT_TRUE(n && s);
  auto on_side = [&](const std::vector<tile::Vertex>& side) {
    return std::count_if(side.begin(), side.end(), [&](const tile::Vertex& v) {
      return v.x == close.x && v.y == nr.min_y && v.z == close.z;
    });
  };
  EXPECT_EQ(on_side(n->south), 1);
  EXPECT_EQ(on_side(s->north), 1);
  for (const auto& v : n->interior) EXPECT_FALSE(v.x == close.x && v.y == close.y);
  // Every other point stays where it was.
  pts.pop_back();
  expect_no_point_lost(f, pts);
}

TEST(FinestTiles, PointCellsHullIsTheDataHull) {
  // PointCells::build skips the hull of tiles enclosed by their diagonal neighbours; the result
  // must still be the exact convex hull of all points (CGAL's), on a ring (inner tiles enclosed,
  // a concave inner boundary whose tiles are not), a dense disc and a lattice whose points lie
  // on tile borders (bounding boxes touch, so nothing counts as enclosed there).
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<std::vector<InputPoint>> inputs(3);
  for (int i = 0; i < 20000; ++i) {
    const double a = 2 * std::numbers::pi * u(rng), r = 1e-4 * (1.0 + u(rng));
    inputs[0].push_back({0.3 + r * std::cos(a), 0.4 + r * std::sin(a), u(rng)});
    const double r2 = 2e-4 * std::sqrt(u(rng));
    inputs[1].push_back({-0.2 + r2 * std::cos(a), 0.1 + r2 * std::sin(a), u(rng)});
  }
  const double step = std::ldexp(1.0, -19);  // level-18 tile = 8 steps of the lattice
  for (int i = 0; i < 120; ++i) {
    for (int j = 0; j < 120; ++j) inputs[2].push_back({0.25 + i * step, 0.5 + j * step, 1.0 * i});
  }
  for (std::size_t k = 0; k < inputs.size(); ++k) {
    const Fixture f = build(inputs[k], 300, 2, "hull" + std::to_string(k));
    ASSERT_GT(f.run.tiles.size(), 16u);
    auto cells = PointCells::build(f.run, 2);
    ASSERT_TRUE(cells.ok()) << cells.error().message;
    std::vector<K::Point_2> all, expected;
    for (const auto& p : inputs[k]) all.emplace_back(p.x, p.y);
    CGAL::convex_hull_2(all.begin(), all.end(), std::back_inserter(expected));
    std::set<std::pair<double, double>> want, got;
    for (const auto& p : expected) want.emplace(p.x(), p.y());
    for (const auto& p : (*cells)->hull()) got.emplace(p.x, p.y);
    EXPECT_EQ(got, want) << "input " << k;
    EXPECT_EQ((*cells)->hull().size(), expected.size()) << "input " << k;
  }
}

TEST(FinestTiles, SinkRunsOnTheWorkersAndItsErrorOrACancelStopsTheRun) {
  const auto pts = random_points(6000, 5, 0.1, 0.2, 3e-4);
  const Fixture f = build(pts, 200, 2, "sink");
  ASSERT_GT(f.run.tiles.size(), 12u);
  // The sink is called on the worker threads, never on the calling one.
  std::mutex mutex;
  std::set<std::thread::id> sink_threads;
  auto all = build_finest_tiles(f.run, 2, [&](tile::TinTile&&) {
    std::lock_guard lock(mutex);
    sink_threads.insert(std::this_thread::get_id());
    return Status{};
  });
  ASSERT_TRUE(all.ok()) << all.error().message;
  EXPECT_EQ(all->tiles, f.run.tiles.size());
  EXPECT_FALSE(sink_threads.empty());
  EXPECT_EQ(sink_threads.count(std::this_thread::get_id()), 0u);
  // The sink's first error is the run's result, and later tiles are not handed over.
  std::atomic<int> calls{0};
  auto failed = build_finest_tiles(f.run, 2, [&](tile::TinTile&&) -> Status {
    if (++calls == 3) return io_error("disk full on purpose");
    return {};
  });
  ASSERT_FALSE(failed.ok());
  EXPECT_EQ(failed.error().message, "disk full on purpose");
  EXPECT_LT(calls.load(), static_cast<int>(f.run.tiles.size()));
  // Progress reported on the calling thread; false cancels.
  std::uint64_t last_done = 0;
  bool progress_on_caller = true;
  const auto caller = std::this_thread::get_id();
  auto cancelled = build_finest_tiles(
      f.run, 2, [](tile::TinTile&&) { return Status{}; }, {},
      [&](const Progress& p) {
        progress_on_caller = progress_on_caller && std::this_thread::get_id() == caller;
        last_done = p.done;
        return p.done < 2;
      });
  ASSERT_FALSE(cancelled.ok());
  EXPECT_EQ(cancelled.error().code, ErrorCode::cancelled);
  EXPECT_TRUE(progress_on_caller);
  EXPECT_GE(last_done, 2u);
}

TEST(FinestTiles, WrongLevelRejected) {
  const auto pts = random_points(500, 4, 0.1, 0.1, 1e-4);
  const Fixture f = build(pts, 100, 1, "level");
  auto cells = PointCells::build(f.run);
  ASSERT_TRUE(cells.ok());
  auto reader = subdivide::SortedRunReader::open(f.run.path);
  ASSERT_TRUE(reader.ok());
  const geo::TileId coarse = f.run.tiles[0].id.parent();
  auto t = build_finest_tile(coarse, **cells, *reader);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.error().message.find("finest level"), std::string::npos);
}

}  // namespace
}  // namespace tinstream::triangulate
