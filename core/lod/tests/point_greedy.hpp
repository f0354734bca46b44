// Greedy insertion over scattered points (Garland & Heckbert), the peer that the stored pyramid's
// LiDAR levels are measured against (#20): the four corners of the points' bounding box (a little
// outside it, each at the height of the point nearest to it), then, one at a time, the point
// farthest (vertically) from the current Delaunay TIN, until the wanted vertex count. CGAL builds
// the TIN (exact predicates); the bookkeeping — points filed per face, a heap of each face's worst
// point — is this file's, written independently of core/lod. Used by lod_tests and by
// bench/lod/pyramid_vs_greedy.
#pragma once

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Projection_traits_xy_3.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <queue>
#include <vector>

namespace tinstream::testing {

struct GreedyPoint {
  double x, y, z;
};

class PointGreedy {
 public:
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Gt = CGAL::Projection_traits_xy_3<K>;
  using Vb = CGAL::Triangulation_vertex_base_2<Gt>;
  using Fb = CGAL::Triangulation_face_base_with_info_2<std::uint32_t, Gt>;
  using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
  using Dt = CGAL::Delaunay_triangulation_2<Gt, Tds>;
  using P = K::Point_3;

  explicit PointGreedy(const std::vector<GreedyPoint>& pts) : pts_(pts) {
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
      const GreedyPoint& q = pts_[chosen];
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
  // Points waiting in one face of the TIN, and the one farthest from the face's plane.
  struct Slot {
    Dt::Face_handle face;
    std::vector<std::uint32_t> points;
    std::uint32_t worst = 0;
    double error = -1;
    std::uint32_t generation = 0;
  };
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
    ids.reserve(faces.size());
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
        std::fprintf(stderr, "PointGreedy: a point fell outside the new faces\n");
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

  const std::vector<GreedyPoint>& pts_;
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

}  // namespace tinstream::testing
