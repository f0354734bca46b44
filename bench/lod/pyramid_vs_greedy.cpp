// bench/lod: the stored pyramid's one-tile levels against greedy insertion from the finest data,
// for scattered data (LiDAR), where Delatin (a grid method) cannot be the peer (#20). Not a test.
//
//   pyramid_vs_greedy STORE LAYER [--tile Z/X/Y]
//
// --tile: that stored tile only, against greedy insertion from the finest data points under it;
// also where the stored tile is worst, and lod::thin_tile run on every finest data point inside
// the tile with the stored tile's corners and border (the thinning alone, without the pyramid's
// choice of candidates). REBUILD_DEPTH=d (with MAXP=the store's --max-points) also rebuilds the
// tile with build_from_sources from the stored children and the stored tiles d levels below (no
// witnesses or bounds) and says whether it is identical to the stored one.
//
// For every level whose single tile holds all the data: that stored tile's vertex count V and its
// maximum vertical error over the finest level's data points (the input points, and the edge
// points and corners on the data: the same points pyramid_quality measures at), beside the
// maximum error over the same points of a greedy-insertion TIN with V vertices built from those
// points: the four corners of the data's bounding box (a little outside it, each at the height of
// the data point nearest to it), then, one at a time, the point farthest (vertically) from the
// current Delaunay TIN (Garland & Heckbert's greedy insertion, the method Delatin implements for
// grids), until V vertices. The peer's triangulation is CGAL's (Delaunay_triangulation_2, exact
// predicates), its bookkeeping is this file's. Both errors are evaluated by this file.
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Projection_traits_xy_3.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <queue>
#include <string>
#include <vector>

#include "store_data.hpp"
#include "tinstream/lod/parent.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/codec.hpp"

namespace {

using tinstream::bench::Point3;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Gt = CGAL::Projection_traits_xy_3<K>;
using Vb = CGAL::Triangulation_vertex_base_2<Gt>;
using Fb = CGAL::Triangulation_face_base_with_info_2<std::uint32_t, Gt>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Dt = CGAL::Delaunay_triangulation_2<Gt, Tds>;
using P = K::Point_3;

// Points waiting in one face of the peer's TIN, and the one farthest from the face's plane.
struct Slot {
  Dt::Face_handle face;
  std::vector<std::uint32_t> points;
  std::uint32_t worst = 0;
  double error = -1;
  std::uint32_t generation = 0;
};

class Greedy {
 public:
  explicit Greedy(const std::vector<Point3>& pts) : pts_(pts) {
    double x0 = pts[0].x, x1 = x0, y0 = pts[0].y, y1 = y0;
    for (const auto& p : pts) {
      x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
      y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
    const double mx = (x1 - x0) * 1e-6 + 1e-12, my = (y1 - y0) * 1e-6 + 1e-12;
    const double cx[4] = {x0 - mx, x1 + mx, x1 + mx, x0 - mx};
    const double cy[4] = {y0 - my, y0 - my, y1 + my, y1 + my};
    for (int c = 0; c < 4; ++c) {
      std::uint32_t near = 0;
      double best = std::numeric_limits<double>::infinity();
      for (std::uint32_t i = 0; i < pts.size(); ++i) {
        const double d = std::hypot(pts[i].x - cx[c], pts[i].y - cy[c]);
        if (d < best) best = d, near = i;
      }
      dt_.insert(P(cx[c], cy[c], pts[near].z));
    }
    std::vector<std::uint32_t> all(pts.size());
    for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    std::vector<Dt::Face_handle> faces;
    for (auto f = dt_.finite_faces_begin(); f != dt_.finite_faces_end(); ++f) faces.push_back(f);
    distribute(all, faces);
  }

  std::size_t vertices() const { return dt_.number_of_vertices(); }

  // Inserts the worst point; false when every point is within 0 (nothing left to insert).
  bool step() {
    while (!heap_.empty()) {
      const auto [error, slot, generation] = heap_.top();
      heap_.pop();
      Slot& s = slots_[slot];
      if (s.generation != generation || s.error <= 0) continue;
      const std::uint32_t chosen = s.worst;
      const Point3& q = pts_[chosen];
      const P p(q.x, q.y, q.z);
      std::vector<Dt::Face_handle> conflicts;
      dt_.get_conflicts(p, std::back_inserter(conflicts), s.face);
      std::vector<std::uint32_t> loose;
      for (const auto& f : conflicts) {
        if (dt_.is_infinite(f)) continue;
        Slot& old = slots_[f->info()];
        for (std::uint32_t i : old.points)
          if (i != chosen) loose.push_back(i);
        release(f->info());
      }
      const Dt::Vertex_handle v = dt_.insert(p, s.face);
      std::vector<Dt::Face_handle> star;
      auto fc = dt_.incident_faces(v), end = fc;
      do {
        if (!dt_.is_infinite(fc)) star.push_back(fc);
      } while (++fc != end);
      distribute(loose, star);
      return true;
    }
    return false;
  }

  // Max |TIN − z| over every point (located afresh: an independent check of the bookkeeping).
  double max_error() const {
    double worst = 0;
    Dt::Face_handle hint;
    for (const auto& q : pts_) {
      hint = dt_.locate(P(q.x, q.y, q.z), hint);
      worst = std::max(worst, std::abs(height(hint, q.x, q.y) - q.z));
    }
    return worst;
  }

 private:
  static double height(const Dt::Face_handle& f, double x, double y) {
    const P &a = f->vertex(0)->point(), &b = f->vertex(1)->point(), &c = f->vertex(2)->point();
    const double det = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    const double wb = ((x - a.x()) * (c.y() - a.y()) - (y - a.y()) * (c.x() - a.x())) / det;
    const double wc = ((b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x())) / det;
    return (1 - wb - wc) * a.z() + wb * b.z() + wc * c.z();
  }

  std::uint32_t acquire(Dt::Face_handle f) {
    std::uint32_t id;
    if (!free_.empty()) {
      id = free_.back();
      free_.pop_back();
    } else {
      id = static_cast<std::uint32_t>(slots_.size());
      slots_.emplace_back();
    }
    Slot& s = slots_[id];
    s.face = f;
    s.points.clear();
    s.error = -1;
    f->info() = id;
    return id;
  }
  void release(std::uint32_t id) {
    ++slots_[id].generation;
    slots_[id].points.clear();
    free_.push_back(id);
  }

  // Each point into the face of `faces` that holds it (exact orientation; a point on a shared
  // edge goes to the first), then each face's worst point onto the heap.
  void distribute(const std::vector<std::uint32_t>& points,
                  const std::vector<Dt::Face_handle>& faces) {
    std::vector<std::uint32_t> ids;
    for (const auto& f : faces) ids.push_back(acquire(f));
    const Gt::Orientation_2 orient = dt_.geom_traits().orientation_2_object();
    for (std::uint32_t i : points) {
      const P p(pts_[i].x, pts_[i].y, pts_[i].z);
      std::size_t k = 0;
      for (; k < faces.size(); ++k) {
        const auto& f = faces[k];
        if (orient(f->vertex(0)->point(), f->vertex(1)->point(), p) != CGAL::RIGHT_TURN &&
            orient(f->vertex(1)->point(), f->vertex(2)->point(), p) != CGAL::RIGHT_TURN &&
            orient(f->vertex(2)->point(), f->vertex(0)->point(), p) != CGAL::RIGHT_TURN)
          break;
      }
      if (k == faces.size()) {
        std::fprintf(stderr, "pyramid_vs_greedy: a point fell outside the new faces\n");
        std::exit(1);
      }
      slots_[ids[k]].points.push_back(i);
    }
    for (std::uint32_t id : ids) {
      Slot& s = slots_[id];
      for (std::uint32_t i : s.points) {
        const double e = std::abs(height(s.face, pts_[i].x, pts_[i].y) - pts_[i].z);
        if (e > s.error) s.error = e, s.worst = i;
      }
      if (s.error > 0) heap_.push({s.error, id, s.generation});
    }
  }

  const std::vector<Point3>& pts_;
  Dt dt_;
  std::vector<Slot> slots_;
  std::vector<std::uint32_t> free_;
  struct Entry {
    double error;
    std::uint32_t slot, generation;
    bool operator<(const Entry& o) const { return error < o.error; }
  };
  std::priority_queue<Entry> heap_;
};

// A tile's largest vertical difference from the points (each located in it).
double max_error(const tinstream::tile::TinTile& tile, const std::vector<Point3>& pts) {
  const tinstream::bench::Locator here = tinstream::bench::tile_locator(tile);
  double e = 0;
  for (const auto& p : pts) {
    double w;
    e = std::max(e, std::abs(here.height(p.x, p.y, &w) - p.z));
  }
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || (argc > 3 && (argc != 5 || std::string(argv[3]) != "--tile"))) {
    std::fprintf(stderr, "usage: %s STORE LAYER [--tile Z/X/Y]\n", argv[0]);
    return 2;
  }
  std::optional<tinstream::geo::TileId> only;
  if (argc == 5) {
    unsigned z = 0, x = 0, y = 0;
    if (std::sscanf(argv[4], "%u/%u/%u", &z, &x, &y) != 3)
      return std::fprintf(stderr, "--tile wants Z/X/Y, not %s\n", argv[4]), 2;
    only = tinstream::geo::TileId{z, x, y};
  }
  auto store =
      tinstream::store::TileStore::open(argv[1], tinstream::store::TileStore::Mode::read_only);
  if (!store) return std::fprintf(stderr, "%s\n", store.error().message.c_str()), 1;
  auto info = store->layer(argv[2]);
  if (!info) return std::fprintf(stderr, "%s\n", info.error().message.c_str()), 1;
  const std::uint32_t finest = info->max_level;
  const auto fd = tinstream::bench::finest_data(*store, argv[2], finest);
  std::vector<Point3> pts;
  for (const auto& [id, p] : fd.points) {
    const std::uint32_t shift = only ? finest - only->z : 0;
    if (only && ((id.x >> shift) != only->x || (id.y >> shift) != only->y)) continue;
    pts.insert(pts.end(), p.begin(), p.end());
  }
  // One copy of each (x, y): the finest tiles share their border points.
  std::sort(pts.begin(), pts.end(),
            [](const Point3& a, const Point3& b) { return a.x != b.x ? a.x < b.x : a.y < b.y; });
  pts.erase(std::unique(pts.begin(), pts.end(),
                        [](const Point3& a, const Point3& b) { return a.x == b.x && a.y == b.y; }),
            pts.end());
  std::printf("%s layer %s: finest level %u, %zu distinct finest data points\n\n", argv[1], argv[2],
              finest, pts.size());
  std::printf(
      "| level | levels above the finest | vertices | ours: max error (m) | greedy insertion: max "
      "error (m) | ours / greedy | greedy build (s, cumulative) "
      "|\n|---:|---:|---:|---:|---:|---:|---:|\n");
  // Levels from the finest up whose one tile holds the data, largest vertex count first: one
  // greedy run serves them all (its TIN at V vertices is measured on the way up).
  struct Level {
    std::uint32_t z;
    std::size_t vertices;
    double ours;
  };
  std::vector<Level> levels;
  for (std::uint32_t z = finest + 1; z-- > info->min_level;) {
    auto ids = store->tile_ids(argv[2], z);
    if (only) {
      if (z != only->z) continue;
      ids = std::vector<tinstream::geo::TileId>{*only};
    }
    if (!ids || ids->size() != 1) continue;
    auto t = store->read_tile(argv[2], ids->front());
    if (!t || !*t) return std::fprintf(stderr, "cannot read level %u\n", z), 1;
    const tinstream::bench::Locator here = tinstream::bench::tile_locator(**t);
    double ours = 0;
    const Point3* worst = nullptr;
    for (const auto& p : pts) {
      double w;
      const double e = std::abs(here.height(p.x, p.y, &w) - p.z);
      if (e > ours) ours = e, worst = &p;
    }
    if (only) {
      // The same tile thinned by lod::thin_tile from every finest data point inside it, its
      // corners and border as stored: is it the thinning or the candidates it was given?
      tinstream::lod::ThinInput in = tinstream::lod::thin_input(**t);
      in.interior.clear();
      const auto r = only->bounds();
      for (const auto& p : pts) {
        if (p.x > r.min_x && p.x < r.max_x && p.y > r.min_y && p.y < r.max_y)
          in.interior.push_back({p.x, p.y, p.z});
      }
      tinstream::lod::LodOptions o;
      o.max_points = (**t).vertex_count();
      if (const char* g = std::getenv("GREEDY_FACTOR")) o.greedy_factor = std::atof(g);
      if (std::getenv("NO_NODATA")) in.corner_nodata = {false, false, false, false};
      tinstream::lod::ThinStats st;
      auto thinned = tinstream::lod::thin_tile(in, o, &st);
      if (thinned) {
        const double e = max_error(*thinned, pts);
        std::printf(
            "thin_tile from all %zu interior points, the stored border: %zu vertices, max "
            "error %.4f m (greedy stage %zu, its error %.4f; duplicates %zu, border removed %zu, "
            "last error %.4f)\n",
            in.interior.size(), thinned->vertex_count(), e, st.greedy_inserted, st.greedy_error,
            st.duplicates, st.border_removed, st.last_error);
      }
    }
    if (only && std::getenv("REBUILD_DEPTH")) {
      // The tile rebuilt by build_from_sources from the stored children and the stored tiles
      // REBUILD_DEPTH levels below (no witnesses or bounds: the candidates as the pyramid gives
      // them when the sources are finest tiles).
      const std::uint32_t depth =
          static_cast<std::uint32_t>(std::atoi(std::getenv("REBUILD_DEPTH")));
      tinstream::lod::Children ch;
      const auto kids = only->children();
      for (std::size_t k = 0; k < 4; ++k) {
        auto c = store->read_tile(argv[2], kids[k]);
        if (c && *c) ch.tiles[k] = tinstream::lod::LodTile{std::move(**c), {}, {}, {}};
      }
      tinstream::lod::Sources src;
      src.depth = depth;
      if (depth > 1) {
        auto deeper = store->tile_ids(argv[2], only->z + depth);
        for (const auto& id : *deeper) {
          if ((id.x >> depth) != only->x || (id.y >> depth) != only->y) continue;
          auto c = store->read_tile(argv[2], id);
          src.tiles.push_back(tinstream::lod::LodTile{std::move(**c), {}, {}, {}});
        }
      }
      tinstream::lod::LodOptions o;
      o.max_points = std::strtoul(std::getenv("MAXP") ? std::getenv("MAXP") : "16384", nullptr, 10);
      tinstream::lod::ThinStats st;
      auto rebuilt = tinstream::lod::build_from_sources(*only, ch, src, o, &st);
      if (!rebuilt) {
        std::printf("rebuild: %s\n", rebuilt.error().message.c_str());
      } else {
        const double e = max_error(rebuilt->tile, pts);
        std::printf(
            "rebuilt from depth %u (%zu sources): %zu input points, %zu vertices, max error "
            "%.4f m, identical to stored: %s; duplicates %zu, greedy %zu (error %.4f), border "
            "removed %zu, last error %.4f\n",
            depth, src.tiles.size(), st.input_points, rebuilt->tile.vertex_count(), e,
            tinstream::tile::encode(rebuilt->tile) == tinstream::tile::encode(**t) ? "yes" : "no",
            st.duplicates, st.greedy_inserted, st.greedy_error, st.border_removed, st.last_error);
      }
    }
    if (only && worst) {
      const auto r = only->bounds();
      std::printf(
          "ours: worst point at (%.4f, %.4f) of the tile (0…1 west→east, south→north), %.3f m\n\n",
          (worst->x - r.min_x) / r.width(), (worst->y - r.min_y) / r.height(), worst->z);
    }
    levels.push_back({z, (**t).vertex_count(), ours});
  }
  std::sort(levels.begin(), levels.end(),
            [](const Level& a, const Level& b) { return a.vertices < b.vertices; });
  const auto start = std::chrono::steady_clock::now();
  Greedy greedy(pts);
  for (const Level& l : levels) {
    while (greedy.vertices() < l.vertices && greedy.step()) {
    }
    const double peer = greedy.max_error();
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("| %u | %u | %zu | %.4f | %.4f | %.3f | %.2f |\n", l.z, finest - l.z, l.vertices,
                l.ours, peer, peer > 0 ? l.ours / peer : 0.0, secs);
    std::fflush(stdout);
  }
  return 0;
}
