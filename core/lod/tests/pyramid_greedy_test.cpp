// The stored pyramid against plain greedy insertion (#20): a coarse tile built through the whole
// pass 4 (reduced finest tiles, sources, chained error) needs not many more vertices for the error
// it records than a greedy-insertion TIN of the same cells needs for that error. The greedy TIN
// is built here with CGAL's Delaunay triangulation (exact predicates), independently of the code
// under test: start from the four corners, insert the cell of largest vertical error until no
// cell is farther than the target from the surface.
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>
#include <vector>

#include "dem_crop.hpp"
#include "lod_test_support.hpp"
#include "temp_store.hpp"
#include "tinstream/lod/pyramid.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::lod {
namespace {

// ---- plain greedy insertion (Garland–Heckbert without a heap: the faces are scanned) ---------
struct FaceCells {
  std::vector<std::uint32_t> cells;  // the cells inside (or on an edge of) the face
  double error = -1;                 // the largest vertical error among them; -1: none
  std::uint32_t worst = 0;
};
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<double, K>;  // info: the height
using Fb = CGAL::Triangulation_face_base_with_info_2<FaceCells, K>;
using Delaunay = CGAL::Delaunay_triangulation_2<K, CGAL::Triangulation_data_structure_2<Vb, Fb>>;

// A rows × cols grid of heights (row-major), cell (c, r) at x = c, y = r.
class GreedyTin {
 public:
  GreedyTin(const std::vector<double>& z, int cols, int rows) : z_(z), cols_(cols) {
    std::vector<std::uint32_t> all;
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const bool corner = (r == 0 || r == rows - 1) && (c == 0 || c == cols - 1);
        if (corner) {
          insert_vertex(index(c, r));
        } else {
          all.push_back(index(c, r));
        }
      }
    }
    file(all, dt_.finite_faces_begin());
  }

  std::size_t vertices() const { return dt_.number_of_vertices(); }

  // The largest vertical error of a cell that is not a vertex.
  double max_error() const {
    double e = 0;
    for (auto f = dt_.finite_faces_begin(); f != dt_.finite_faces_end(); ++f) {
      e = std::max(e, f->info().error);
    }
    return e;
  }

  // The largest vertical error over every cell, each located afresh (checks the filing).
  double max_error_by_location() const {
    double e = 0;
    Delaunay::Face_handle hint;
    for (std::uint32_t q = 0; q < z_.size(); ++q) {
      Delaunay::Locate_type lt{};
      int li = 0;
      auto f = dt_.locate(point(q), lt, li, hint);
      if (lt == Delaunay::VERTEX) continue;
      if (dt_.is_infinite(f)) f = f->neighbor(li);
      e = std::max(e, std::abs(z_[q] - plane(f, point(q))));
      hint = f;
    }
    return e;
  }

  // Inserts the worst cell; false when every cell is a vertex.
  bool insert_worst() {
    Delaunay::Face_handle worst;
    for (auto f = dt_.finite_faces_begin(); f != dt_.finite_faces_end(); ++f) {
      if (f->info().error >= 0 &&
          (worst == Delaunay::Face_handle() || f->info().error > worst->info().error)) {
        worst = f;
      }
    }
    if (worst == Delaunay::Face_handle()) return false;
    const std::uint32_t cell = worst->info().worst;
    const K::Point_2 p = point(cell);
    // The cells of the faces the insertion replaces are filed again among the new ones.
    std::vector<Delaunay::Face_handle> conflicts;
    dt_.get_conflicts(p, std::back_inserter(conflicts), worst);
    std::vector<std::uint32_t> moved;
    for (const auto& f : conflicts) {
      if (dt_.is_infinite(f)) continue;
      for (const std::uint32_t q : f->info().cells) {
        if (q != cell) moved.push_back(q);
      }
    }
    const auto v = insert_vertex(cell, worst);
    // The faces around v replace the conflicting ones (CGAL reuses faces in place): none of their
    // old cells stay.
    auto f = dt_.incident_faces(v), end = f;
    do {
      f->info() = FaceCells{};
    } while (++f != end);
    file(moved, v->face());
    return true;
  }

 private:
  std::uint32_t index(int c, int r) const { return static_cast<std::uint32_t>(r * cols_ + c); }
  K::Point_2 point(std::uint32_t i) const {
    const auto cols = static_cast<std::uint32_t>(cols_);
    const std::uint32_t row = i / cols;  // whole rows
    return {static_cast<double>(i % cols), static_cast<double>(row)};
  }
  Delaunay::Vertex_handle insert_vertex(std::uint32_t i,
                                        Delaunay::Face_handle hint = Delaunay::Face_handle()) {
    const auto v = dt_.insert(point(i), hint);
    v->info() = z_[i];
    return v;
  }
  // The height of face f's plane at p.
  static double plane(const Delaunay::Face_handle& f, const K::Point_2& p) {
    const auto &a = f->vertex(0)->point(), &b = f->vertex(1)->point(), &c = f->vertex(2)->point();
    const double za = f->vertex(0)->info(), zb = f->vertex(1)->info(), zc = f->vertex(2)->info();
    const double d = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    const double wb = ((p.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (p.y() - a.y())) / d;
    const double wc = ((b.x() - a.x()) * (p.y() - a.y()) - (p.x() - a.x()) * (b.y() - a.y())) / d;
    return za + wb * (zb - za) + wc * (zc - za);
  }
  // Files `cells` under the finite faces that contain them and renews those faces' worst cells.
  void file(const std::vector<std::uint32_t>& cells, Delaunay::Face_handle hint) {
    std::set<Delaunay::Face_handle> touched;
    for (const std::uint32_t q : cells) {
      Delaunay::Locate_type lt{};
      int li = 0;
      auto f = dt_.locate(point(q), lt, li, hint);
      ASSERT_TRUE(lt == Delaunay::FACE || lt == Delaunay::EDGE) << "cell " << q;
      if (dt_.is_infinite(f)) f = f->neighbor(li);  // on the hull: the finite side
      f->info().cells.push_back(q);
      touched.insert(f);
      hint = f;
    }
    for (const auto& f : touched) {
      auto& info = f->info();
      info.error = -1;
      for (const std::uint32_t q : info.cells) {
        const double e = std::abs(z_[q] - plane(f, point(q)));
        if (e > info.error) info.error = e, info.worst = q;
      }
    }
  }

  const std::vector<double>& z_;
  int cols_;
  Delaunay dt_;
};

// ---- the stored pyramid ----------------------------------------------------------------------
// A 257 × 257 crop of the Big Tujunga SRTM DEM (the one of Pyramid.RealDemCrop…) on an 8 × 8
// block of level-12 tiles (32 cells each), reduced as ingest reduces rasters, then three levels
// up to the level-9 tile over it (thinned from its 64 finest tiles). Its vertex count for its
// recorded error against greedy insertion from the 257² cells at that error.
TEST(PyramidQuality, StoredCoarseTileIsNotFarBehindGreedyInsertionOnARealDem) {
  constexpr int kTiles = 8, kCells = 32 * kTiles;
  constexpr int kSide = kCells + 1;
  const auto read = testing::big_tujunga_crop(kSide);
  if (!read) GTEST_SKIP() << "bigtujunga_srtm30m_utm11.tif not in the shared data";
  ASSERT_FALSE(read->empty());
  const std::vector<float>& crop = *read;
  for (const float h : crop) ASSERT_LT(h, 32767.0F) << "NODATA in the crop";
  const std::uint32_t L = 12, x0 = 2000, y0 = 1496;
  const geo::MercatorRect block{geo::tile_x_edge(L, x0), geo::tile_y_edge(L, y0 + kTiles),
                                geo::tile_x_edge(L, x0 + kTiles), geo::tile_y_edge(L, y0)};
  const double cell = block.width() / kCells;
  auto height = [&](double x, double y) {
    const auto c = static_cast<std::size_t>(std::lround((x - block.min_x) / cell));
    const auto r = static_cast<std::size_t>(std::lround((block.max_y - y) / cell));
    return static_cast<double>(crop[r * kSide + c]);
  };
  testing::TempStore ts("greedy");
  ASSERT_TRUE(ts.store);
  auto w = ts.writer("dem");
  ASSERT_TRUE(w);
  for (std::uint32_t y = y0; y < y0 + kTiles; ++y) {
    for (std::uint32_t x = x0; x < x0 + kTiles; ++x) {
      ASSERT_TRUE(w->put(testing::grid_tile({L, x, y}, kCells / kTiles, height)).ok());
    }
  }
  // Measured on this crop (ceab6f7's pass 4, sources 3 levels deep): 600 stored vertices for a
  // recorded 52.2 m, greedy insertion needs 615 for 52.2 m: 0.976 (greedy at 600 vertices:
  // 56.7 m). Children-only parents (source_depth 1, the rule before #20) record 111.7 m with 600
  // vertices where greedy needs 188: 3.19. (On a 513² crop with 1,500 points a tile: 0.975 and
  // 3.38.) The bound leaves room for tie-breaks and budget changes in the thinning, not for
  // thinning from the children's surface again.
  constexpr double kMaxRatio = 1.15;
  PyramidOptions o;
  o.lod.max_points = 600;
  o.lod.epsilon = 1.0;
  o.reduce_finest = true;
  auto summary = testing::build_stored_pyramid(*w, L, L - 3, o, 2);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  auto ids = w->tile_ids(L - 3);
  ASSERT_TRUE(ids.ok());
  ASSERT_EQ(ids->size(), 1u);
  auto top = w->get(ids->front());
  ASSERT_TRUE(top.ok() && top->has_value());

  const std::size_t stored = (*top)->vertex_count();
  const double recorded = (*top)->geometric_error;
  ASSERT_GT(recorded, 0.0);

  std::vector<double> z(crop.begin(), crop.end());
  GreedyTin greedy(z, kSide, kSide);
  double at_stored_count = -1;
  while (greedy.max_error() > recorded && greedy.insert_worst()) {
    if (greedy.vertices() == stored) at_stored_count = greedy.max_error();  // for the log
  }
  ASSERT_LE(greedy.max_error(), recorded);
  ASSERT_EQ(greedy.max_error_by_location(), greedy.max_error());
  const std::size_t needed = greedy.vertices();
  const double ratio = static_cast<double>(stored) / static_cast<double>(needed);
  std::cout << "level " << L - 3 << " tile: " << stored << " vertices recording " << recorded
            << " m; greedy insertion reaches it with " << needed << " (ratio " << ratio
            << "); greedy at " << stored << " vertices: " << at_stored_count << " m\n";
  RecordProperty("vertex_ratio", std::to_string(ratio));
  EXPECT_LE(ratio, kMaxRatio) << stored << " stored vertices, " << needed << " greedy";
}

}  // namespace
}  // namespace tinstream::lod
