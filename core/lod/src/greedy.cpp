// Greedy insertion stage of the interior thinning (greedy.hpp has the contract and the layout).
#include "greedy.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "indexed_heap.hpp"

namespace tinstream::lod::detail {

using kernel::kNone;
using kernel::TriangleId;
using kernel::Triangulation;
using kernel::VertexId;

namespace {

// The linear interpolant of one triangle, set up once for many points: barycentric weights
// relative to its first corner (for accuracy far from the origin).
struct Plane {
  double ax, ay, az, bx, by, cx, cy, dzb, dzc, inv_det;

  Plane(const Triangulation& tri, TriangleId t) {
    const auto& v = tri.mesh().tri(t).v;
    const kernel::XY &a = tri.xy(v[0]), &b = tri.xy(v[1]), &c = tri.xy(v[2]);
    ax = a.x, ay = a.y, az = tri.z(v[0]);
    bx = b.x - ax, by = b.y - ay, cx = c.x - ax, cy = c.y - ay;
    dzb = tri.z(v[1]) - az, dzc = tri.z(v[2]) - az;
    inv_det = 1.0 / (bx * cy - by * cx);
  }
  // Height at (x, y); *min_weight (≥ 0 inside up to rounding) the smallest barycentric weight.
  double at(double x, double y, double* min_weight) const {
    const double qx = x - ax, qy = y - ay;
    const double wb = (qx * cy - qy * cx) * inv_det;
    const double wc = (bx * qy - by * qx) * inv_det;
    *min_weight = std::min(std::min(wb, wc), 1.0 - wb - wc);
    return az + wb * dzb + wc * dzc;
  }
};

enum State : std::uint8_t { kCandidate, kInserted, kGone, kExtra };

class GreedyInserter {
 public:
  GreedyInserter(Triangulation& tri, std::span<const tile::Vertex> candidates,
                 std::span<const tile::Vertex> extra)
      : tri_(tri), nc_(candidates.size()), heap_(tri.mesh().triangle_slots()) {
    const std::size_t n = candidates.size() + extra.size();
    pts_.reserve(n);
    pts_.insert(pts_.end(), candidates.begin(), candidates.end());
    pts_.insert(pts_.end(), extra.begin(), extra.end());
    state_.assign(n, kCandidate);
    for (std::size_t i = nc_; i < n; ++i) state_[i] = kExtra;
    next_.assign(n, kNone);
    grow();
  }

  // Files every point under its triangle and ranks the triangles.
  Status file_all() {
    for (std::size_t i = 0; i < pts_.size(); ++i) {
      const tile::Vertex& p = pts_[i];
      const TriangleId t = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)
                               ? tri_.locate_triangle(p.x, p.y)
                               : kNone;
      if (t == kNone) {
        if (state_[i] == kCandidate) {
          return invalid_argument("interior point #" + std::to_string(i) +
                                  " lies outside the tile or is not finite");
        }
        state_[i] = kGone;  // an extra point outside: not part of this surface
        continue;
      }
      next_[i] = head_[t];
      head_[t] = static_cast<std::uint32_t>(i);
    }
    for (TriangleId t = 0; t < head_.size(); ++t) {
      if (head_[t] != kNone) rank(t);
    }
    return {};
  }

  Status run(std::size_t max_vertices, double epsilon, GreedyResult& out) {
    out.vertex.assign(nc_, kNone);
    while (tri_.num_vertices() < max_vertices && !heap_.empty()) {
      const TriangleId t = heap_.top();
      const double e = -heap_.key(t);
      if (!(e > 0) || e < epsilon) break;
      const std::uint32_t i = best_[t];
      const tile::Vertex& p = pts_[i];
      const kernel::InsertResult r = tri_.insert({p.x, p.y, p.z, p.weight});
      if (r.outcome == kernel::InsertOutcome::duplicate) {
        state_[i] = kGone;
        ++out.duplicates;
        rank(t);
        continue;
      }
      if (r.outcome != kernel::InsertOutcome::inserted) {
        return Error(ErrorCode::internal,
                     "greedy insertion of interior point #" + std::to_string(i) + " failed");
      }
      state_[i] = kInserted;
      out.vertex[i] = r.vertex;
      ++out.inserted;
      refile_star(r.vertex);
    }
    // Hand the points still filed over to the drop stage.
    for (TriangleId t = 0; t < head_.size(); ++t) {
      for (std::uint32_t i = head_[t]; i != kNone; i = next_[i]) {
        if (state_[i] == kCandidate || state_[i] == kExtra)
          out.orphans.push(pts_[i].x, pts_[i].y, pts_[i].z, t);
      }
    }
    return {};
  }

 private:
  void grow() {
    const std::size_t slots = tri_.mesh().triangle_slots();
    if (head_.size() >= slots) return;
    head_.resize(slots, kNone);
    best_.resize(slots, kNone);
    heap_.grow(slots);
  }

  double effective_error(std::uint32_t i, double surface) const {
    return std::abs(pts_[i].z - surface) + pts_[i].weight;
  }

  // Recomputes t's best candidate from its list (unlinking points that left) and its heap key.
  void rank(TriangleId t) {
    const Plane plane(tri_, t);
    double best_e = -1, w;
    std::uint32_t best = kNone;
    for (std::uint32_t* link = &head_[t]; *link != kNone;) {
      const std::uint32_t i = *link;
      if (state_[i] == kGone || state_[i] == kInserted) {
        *link = next_[i];
        continue;
      }
      if (state_[i] == kCandidate) {
        const double e = effective_error(i, plane.at(pts_[i].x, pts_[i].y, &w));
        if (e > best_e) best_e = e, best = i;
      }
      link = &next_[i];
    }
    set_best(t, best, best_e);
  }

  void set_best(TriangleId t, std::uint32_t best, double error) {
    best_[t] = best;
    if (best == kNone) {
      heap_.erase(t);
    } else {
      heap_.set(t, -error);
    }
  }

  // After inserting v: every point listed under a slot of v's new star moves to the star
  // triangle that contains it (largest smallest barycentric weight), and the star is re-ranked.
  void refile_star(VertexId v) {
    grow();
    star_ = tri_.incident_triangles(v, true);
    gathered_.clear();
    for (TriangleId s : star_) {
      for (std::uint32_t i = head_[s]; i != kNone; i = next_[i]) {
        if (state_[i] == kCandidate || state_[i] == kExtra) gathered_.push_back(i);
      }
      head_[s] = kNone;
    }
    planes_.clear();
    for (TriangleId s : star_) planes_.emplace_back(tri_, s);
    star_best_.assign(star_.size(), kNone);
    star_error_.assign(star_.size(), -1.0);
    for (std::uint32_t i : gathered_) {
      double best_w = -std::numeric_limits<double>::infinity(), z = 0, w;
      std::size_t k = 0;
      for (std::size_t s = 0; s < planes_.size(); ++s) {
        const double zs = planes_[s].at(pts_[i].x, pts_[i].y, &w);
        if (w > best_w) best_w = w, z = zs, k = s;
        if (w >= 0) break;
      }
      next_[i] = head_[star_[k]];
      head_[star_[k]] = i;
      if (state_[i] != kCandidate) continue;
      const double e = effective_error(i, z);
      if (e > star_error_[k]) star_error_[k] = e, star_best_[k] = i;
    }
    for (std::size_t k = 0; k < star_.size(); ++k) set_best(star_[k], star_best_[k], star_error_[k]);
  }

  Triangulation& tri_;
  std::size_t nc_;
  std::vector<tile::Vertex> pts_;     // candidates, then extra points
  std::vector<std::uint8_t> state_;   // by point
  std::vector<std::uint32_t> next_;   // by point
  std::vector<std::uint32_t> head_;   // by triangle slot
  std::vector<std::uint32_t> best_;   // by triangle slot: its candidate of largest error
  IndexedHeap heap_;                  // slots by −(largest effective error), then slot id
  std::vector<TriangleId> star_;
  std::vector<std::uint32_t> gathered_, star_best_;
  std::vector<double> star_error_;
  std::vector<Plane> planes_;
};

}  // namespace

Result<GreedyResult> greedy_insert(Triangulation& tri, std::span<const tile::Vertex> candidates,
                                   std::span<const tile::Vertex> extra, std::size_t max_vertices,
                                   double epsilon) {
  GreedyInserter g(tri, candidates, extra);
  if (Status s = g.file_all(); !s.ok()) return s.error();
  GreedyResult out;
  if (Status s = g.run(max_vertices, epsilon, out); !s.ok()) return s.error();
  return out;
}

}  // namespace tinstream::lod::detail
