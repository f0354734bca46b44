// Lee's drop heuristic on one tile: border sides in 1-D first, then the interior in 2-D with the
// border constrained (thinning.hpp has the contract).
//
// Interior bookkeeping. Every point that left the surface (a removed candidate, a border point
// dropped in 1-D, an input orphan) is an "orphan" kept with its original z and filed under the
// live triangle that contains it, as an intrusive singly linked list per triangle slot:
//
//   head[t] ──▶ orphan i ──next[i]──▶ orphan j ──▶ … ──▶ kNone
//
// Invariant: every orphan inside the rectangle is filed under exactly one live triangle that
// contains it (closed triangle). Removing v re-files the orphans of v's star (and v itself) into
// the triangles that replace the star, which are exactly removal_preview(v) (the kernel writes
// back the same hole it previews and touches nothing outside it).
#include "tinstream/lod/thinning.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <queue>
#include <string>

#include "exchange.hpp"
#include "greedy.hpp"
#include "indexed_heap.hpp"
#include "lattice.hpp"
#include "plane.hpp"
#include "removal_bound.hpp"
#include "tie_break.hpp"
#include "tinstream/kernel/triangulation.hpp"
#include "tinstream/lod/error.hpp"

namespace tinstream::lod {

using detail::FiledPoints;
using detail::IndexedHeap;
using detail::Plane;
using kernel::kNone;
using kernel::TriangleId;
using kernel::Triangulation;
using kernel::VertexId;
using kernel::VertexTriple;
using kernel::XY;
using tile::Vertex;

std::size_t greedy_target(const LodOptions& options) {
  if (!(options.greedy_factor > 0)) return 0;
  const double t = std::ceil(options.greedy_factor * static_cast<double>(options.max_points));
  if (!(t < 1e15)) return 0;
  return std::max(options.max_points, static_cast<std::size_t>(t));
}

std::size_t side_budget(const LodOptions& options) {
  if (options.border_points_per_side != 0) return options.border_points_per_side;
  const auto root =
      static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(options.max_points))));
  const std::size_t cap = options.max_points > 4 ? (options.max_points - 4) / 8 : 0;
  return std::min(root, cap);
}

namespace {

// Quantized-mesh steps across a tile (2^15 − 1): the greedy stage's outline tolerance is one of
// them (greedy.hpp, coverage first).
constexpr double kOutlineSteps = 32767.0;

struct QueueEntry {
  double error;  // effective (error + weight)
  double key_a;  // tie-break: position
  double key_b;
  std::uint32_t id;  // index / vertex id
  std::uint32_t version;
  bool operator>(const QueueEntry& o) const {
    if (error != o.error) return error > o.error;
    if (key_a != o.key_a) return key_a > o.key_a;
    if (key_b != o.key_b) return key_b > o.key_b;
    return id > o.id;
  }
};
using MinQueue = std::priority_queue<QueueEntry, std::vector<QueueEntry>, std::greater<>>;

class InteriorThinner {
 public:
  // `orphans`: points already filed by triangle (the greedy stage's), more may be added.
  // `lattice`: the input's interior points (all of them, any state) as a lattice whose cells are
  // scanned for the error (the filed orphans are then the others only), or null.
  InteriorThinner(Triangulation& tri, std::vector<std::uint8_t> candidate, FiledPoints orphans,
                  const detail::Lattice* lattice, std::span<const VertexId> nodata_corners)
      : nodata_corners_(nodata_corners.begin(), nodata_corners.end()),
        tri_(tri),
        candidate_(std::move(candidate)),
        heap_(candidate_.size()),
        level_(candidate_.size(), kPreviewBound),
        orph_(std::move(orphans)),
        bound_(candidate_.size()),
        lattice_(lattice) {
    if (orph_.head.size() < tri_.mesh().triangle_slots())
      orph_.head.resize(tri_.mesh().triangle_slots(), kNone);
  }

  void add_orphan(const Vertex& p) {
    const TriangleId t = tri_.locate_triangle(p.x, p.y);
    if (t == kNone) return;  // outside the rectangle: not part of this tile's surface
    orph_.push(p.x, p.y, p.z, t);
  }

  void seed_queue() {
    mark_coverage();
    for (VertexId v = 1; v < candidate_.size(); ++v) {
      if (candidate_[v] && tri_.is_vertex(v)) evaluate_and_push(v);
    }
  }

  // Whether run(max_points, epsilon) can remove anything: above budget, or when a key could be
  // below epsilon. Every key is an error (≥ 0) plus cost_of(v) ≥ v's weight, so with no more than
  // max_points vertices and every candidate's weight ≥ epsilon the first key on top stops run():
  // then seed_queue() (a ring bound for every vertex) is skipped: a parent whose candidates fit
  // its budget (the one-child levels above the data, the smaller tiles of a level) removes nothing.
  bool may_remove(std::size_t max_points, double epsilon) const {
    if (tri_.num_vertices() > max_points) return true;
    for (VertexId v = 1; v < candidate_.size(); ++v) {
      if (candidate_[v] && tri_.is_vertex(v) && !(tri_.weight(v) >= epsilon)) return true;
    }
    return false;
  }

  // Removes while above budget or below epsilon. Returns the number removed.
  Result<std::size_t> run(std::size_t max_points, double epsilon, double* last_error) {
    std::size_t removed = 0;
    while (!heap_.empty()) {
      const std::uint32_t v = heap_.top();
      const double error = heap_.key(v);
      if (tri_.num_vertices() <= max_points && error >= epsilon) break;
      if (level_[v] == kRingBound) {  // the ring's bound on top: the preview's, look again
        push_previewed(v);
        continue;
      }
      if (level_[v] == kPreviewBound) {  // the preview's bound on top: the exact error
        heap_.set(v, exact_error(v));
        level_[v] = kExact;
        continue;
      }
      heap_.pop();
      Status s = remove(v);
      if (!s.ok()) return s.error();
      *last_error = error;
      ++removed;
    }
    return removed;
  }

 private:
  // What removing v costs beside its vertical error: its weight, and kCoverageCost when it is next
  // to a NODATA corner (its removal would widen that corner's fan over the data, greedy.hpp).
  double cost_of(VertexId v) const {
    return tri_.weight(v) + (v < coverage_.size() && coverage_[v] ? detail::kCoverageCost : 0.0);
  }

  // Marks the vertices next to a NODATA corner (coverage_). Removing any other vertex leaves the
  // corners' stars as they are (its star's new triangles use its ring only), so the marks change
  // only when a marked vertex goes.
  void mark_coverage() {
    coverage_.assign(tri_.vertex_id_bound(), 0);
    for (const VertexId c : nodata_corners_) {
      if (!tri_.is_vertex(c)) continue;
      for (const VertexId w : tri_.adjacent_vertices(c)) {
        if (w < coverage_.size()) coverage_[w] = 1;
      }
    }
  }

  // Calls f(t) for the finite triangles around v, walking its fan in the mesh (the kernel's
  // incident_triangles() allocates a vector each call). Requires: v a live vertex.
  template <typename F>
  void for_each_star_triangle(VertexId v, F&& f) const {
    const kernel::Mesh& m = tri_.mesh();
    const TriangleId t0 = m.vertex_triangle(v);
    TriangleId t = t0;
    do {
      const int k = m.index_of(t, v);
      const TriangleId next = m.tri(t).n[k == 2 ? 0 : k + 1];
      if (next == kNone) {  // a cut mesh (not made here): the kernel walks both ways
        for (TriangleId u : tri_.incident_triangles(v, true)) f(u);
        return;
      }
      t = next;
    } while (t != t0);
    do {
      if (!m.is_ghost(t)) f(t);
      const int k = m.index_of(t, v);
      t = m.tri(t).n[k == 2 ? 0 : k + 1];
    } while (t != t0);
  }

  // star_: v's finite triangles (for_each_star_triangle's order); ring_: its neighbours, as
  // adjacent_vertices(v) lists them (the same fan order), without that call's two vectors.
  void gather_star(VertexId v) {
    star_.clear(), ring_.clear();
    const kernel::Mesh& m = tri_.mesh();
    const TriangleId t0 = m.vertex_triangle(v);
    TriangleId t = t0;
    do {
      if (m.is_ghost(t)) break;  // on the hull: the general walks below
      const int k = m.index_of(t, v);
      const kernel::Triangle& T = m.tri(t);
      star_.push_back(t);
      ring_.push_back(T.v[k == 2 ? 0 : k + 1]);
      t = T.n[k == 2 ? 0 : k + 1];
    } while (t != t0 && t != kNone);
    if (t == t0 && !m.is_ghost(t)) return;  // a closed fan of finite triangles
    star_.clear();
    for_each_star_triangle(v, [&](TriangleId u) { star_.push_back(u); });
    ring_ = tri_.adjacent_vertices(v);
  }

  // The planes of the replacement triangles `tris`, for surface_at.
  void set_planes(std::span<const VertexTriple> tris) const {
    planes_.clear();
    for (const auto& t : tris) {
      planes_.emplace_back(tri_.xy(t[0]), tri_.xy(t[1]), tri_.xy(t[2]), tri_.z(t[0]), tri_.z(t[1]),
                           tri_.z(t[2]));
    }
  }
  // Index of the set_planes triangle containing (x, y) (largest smallest barycentric weight),
  // and the interpolated z.
  double surface_at(double x, double y, std::size_t* which) const {
    // The first triangle whose smallest weight is ≥ 0 (Plane::contains: the same arithmetic,
    // stopping at the first negative weight, and the same height as at()); the full scan below
    // only when rounding puts (x, y) in none. (Until 2026-11-28 every triangle tried took all
    // three weights: the same answers.)
    for (std::size_t k = 0; k < planes_.size(); ++k) {
      double z;
      if (planes_[k].contains(x, y, &z)) {
        if (which) *which = k;
        return z;
      }
    }
    double best_w = -std::numeric_limits<double>::infinity();
    std::size_t best = 0;
    for (std::size_t k = 0; k < planes_.size(); ++k) {
      const double w = planes_[k].min_weight(x, y);
      if (w > best_w) best_w = w, best = k;
      if (w >= 0) break;
    }
    if (which) *which = best;
    double w;
    return planes_[best].at(x, y, &w);
  }

  // The kernel does not re-triangulate a star that is the whole triangulation (it takes that for
  // "only collinear points remain"). Here that happens exactly when v is the last interior vertex
  // (a second interior vertex would own a triangle without v), so the replacement is the
  // triangulation of the fixed border polygon alone.
  std::optional<double> evaluate_last(VertexId v) const {
    Triangulation rest(*tri_.domain());
    std::vector<kernel::Point3> ring;
    for (VertexId w : tri_.adjacent_vertices(v))
      ring.push_back({tri_.xy(w).x, tri_.xy(w).y, tri_.z(w), 0});
    rest.insert_bulk(ring);
    if (rest.dimension() != 2) return std::nullopt;
    auto at = [&](double x, double y) { return rest.interpolate(x, y); };
    const XY& p = tri_.xy(v);
    const auto zv = at(p.x, p.y);
    if (!zv) return std::nullopt;
    double err = std::abs(tri_.z(v) - *zv);
    if (lattice_) {
      for (const auto& t : rest.finite_triangles()) err = std::max(err, lattice_error(t, rest));
    }
    for_each_star_triangle(v, [&](TriangleId t) {
      if (t >= orph_.head.size()) return;
      for (std::uint32_t i = orph_.head[t]; i != kNone; i = orph_.next[i]) {
        if (const auto z = at(orph_.x[i], orph_.y[i]))
          err = std::max(err, std::abs(orph_.z[i] - *z));
      }
    });
    return err + cost_of(v);
  }

  // Largest |z − surface| over the lattice cells in triangle t of `tri`.
  double lattice_error(const VertexTriple& t, const Triangulation& tri) const {
    return detail::max_deviation(*lattice_, tri.xy(t[0]), tri.xy(t[1]), tri.xy(t[2]), tri.z(t[0]),
                                 tri.z(t[1]), tri.z(t[2]));
  }

  bool is_last(VertexId v, const Result<std::vector<VertexTriple>>& preview) const {
    return preview.ok() && preview->empty() && tri_.num_vertices() > 3 && !tri_.is_on_hull(v);
  }

 public:
  // The interior vertex removed without the kernel (see evaluate_last), or kNone.
  VertexId removed_last() const { return removed_last_; }

 private:
  // Effective error of removing v, or nullopt when v cannot be removed. Except for the last
  // interior vertex, a lower bound (*is_exact says which it is): the error at v itself, plus on
  // a lattice the few filed orphans, without the lattice cells or (general path) the orphans;
  // the preview and that error are kept for exact_error().
  std::optional<double> evaluate(VertexId v, bool* is_exact) const {
    auto preview = tri_.removal_preview(v);
    *is_exact = true;
    if (is_last(v, preview)) return evaluate_last(v);
    if (!preview.ok() || preview->empty()) return std::nullopt;
    set_planes(*preview);
    preview_of_ = v;
    preview_ = std::move(*preview);
    const XY& p = tri_.xy(v);
    double err = std::abs(tri_.z(v) - surface_at(p.x, p.y, nullptr));
    *is_exact = false;
    if (lattice_) err = std::max(err, orphan_error(v));  // (few: the lattice's cells are not)
    bound_[v] = {err, static_cast<std::uint32_t>(bound_tris_.size()),
                 static_cast<std::uint32_t>(preview_.size())};
    bound_tris_.insert(bound_tris_.end(), preview_.begin(), preview_.end());
    return err + cost_of(v);
  }

  // Largest |z − surface| over the orphans filed under v's triangles, the surface being the
  // set_planes() triangles.
  double orphan_error(VertexId v) const {
    double err = 0;
    for_each_star_triangle(v, [&](TriangleId t) {
      if (t >= orph_.head.size()) return;
      for (std::uint32_t i = orph_.head[t]; i != kNone; i = orph_.next[i]) {
        err = std::max(err, std::abs(orph_.z[i] - surface_at(orph_.x[i], orph_.y[i], nullptr)));
      }
    });
    return err;
  }

  // v's effective error from its lower bound (the last evaluate(v), on the current star: every
  // change of the star evaluates v again) and the lattice cells, or the orphans, of its kept
  // preview.
  double exact_error(VertexId v) const {
    const Bound& b = bound_[v];
    const std::span<const VertexTriple> tris(bound_tris_.data() + b.first, b.count);
    double err = b.error;
    if (lattice_) {
      for (const auto& t : tris) err = std::max(err, lattice_error(t, tri_));
    } else {
      set_planes(tris);
      err = std::max(err, orphan_error(v));
    }
    return err + cost_of(v);
  }

  // Keys v by a lower bound of its effective error, the cheapest first: from its ring alone
  // (removal_bound.hpp), else from its removal preview (evaluate()). run() tightens a key that
  // reaches the top of the heap, one level at a time up to the exact error, so the order of
  // removals is the one of exact keys throughout (an exact key on top is at most every other
  // vertex's exact error), and the vertices that never get near the top are never previewed
  // (on bigtujunga at 50k vertices: 39k kernel previews instead of 134k) and their cells and
  // orphans never visited.
  void evaluate_and_push(VertexId v) {
    if (const auto b = detail::removal_error_bound(tri_, v)) {
      level_[v] = kRingBound;
      heap_.set(v, *b + cost_of(v));
      return;
    }
    push_previewed(v);
  }

  // Keys v by evaluate(): its preview's bound (or exact error), or drops it when v cannot go.
  void push_previewed(VertexId v) {
    bool is_exact = false;
    const auto e = evaluate(v, &is_exact);
    if (!e) {
      heap_.erase(v);
      return;
    }
    level_[v] = is_exact ? kExact : kPreviewBound;
    heap_.set(v, *e);
  }

  Status remove(VertexId v) {
    // (The last evaluate() was usually v's own, on the current mesh: its preview is reused.)
    auto preview = preview_of_ == v ? Result<std::vector<VertexTriple>>(std::move(preview_))
                                    : tri_.removal_preview(v);
    preview_of_ = kNone;
    if (is_last(v, preview)) {
      // Nothing is left to evaluate after it; the caller re-triangulates the border alone.
      candidate_[v] = 0;
      removed_last_ = v;
      return {};
    }
    if (!preview.ok()) return preview.error();
    const std::vector<VertexTriple> tris = std::move(*preview);
    gather_star(v);
    const std::vector<TriangleId>& star = star_;
    const std::vector<VertexId>& ring = ring_;
    gathered_.clear();
    for (TriangleId t : star) {
      if (t >= orph_.head.size()) continue;
      for (std::uint32_t i = orph_.head[t]; i != kNone; i = orph_.next[i]) gathered_.push_back(i);
    }
    const XY pv = tri_.xy(v);
    const double zv = tri_.z(v);
    Status s = tri_.remove_vertex(v);
    if (!s.ok()) return s;
    candidate_[v] = 0;
    for (TriangleId t : star) {
      if (t < orph_.head.size()) orph_.head[t] = kNone;
    }
    // The ids of the replacement triangles (the star's slots, reused).
    new_ids_.assign(tris.size(), kNone);
    for (std::size_t k = 0; k < tris.size(); ++k) {
      const auto& want = tris[k];
      for_each_star_triangle(want[0], [&](TriangleId t) {
        if (tri_.mesh().index_of(t, want[1]) >= 0 && tri_.mesh().index_of(t, want[2]) >= 0) {
          new_ids_[k] = t;
        }
      });
      if (new_ids_[k] == kNone) {
        return Error(ErrorCode::internal, "lod: replacement triangle of vertex " +
                                              std::to_string(v) + " not found after removal");
      }
      if (new_ids_[k] >= orph_.head.size())
        orph_.head.resize(static_cast<std::size_t>(new_ids_[k]) + 1, kNone);
    }
    set_planes(tris);
    for (std::uint32_t i : gathered_) {
      std::size_t k;
      surface_at(orph_.x[i], orph_.y[i], &k);
      const TriangleId t = new_ids_[k];
      orph_.next[i] = orph_.head[t];
      orph_.head[t] = i;
    }
    if (!lattice_) {  // (on a lattice, v's cell is scanned with the others)
      std::size_t k;
      surface_at(pv.x, pv.y, &k);
      orph_.push(pv.x, pv.y, zv, new_ids_[k]);
    }
    // A vertex next to a NODATA corner went: the corner's new neighbours (in v's ring) cost more.
    if (v < coverage_.size() && coverage_[v]) mark_coverage();
    // Eager update of the former neighbours. (Lazily re-evaluating them only when they reach the
    // top of the heap is ~1.5× faster but worse: on bigtujunga at 50k vertices the max error
    // went from 9.57 m to 11.0 m, since a removal can also *lower* a neighbour's error.)
    for (VertexId w : ring) {
      if (w < candidate_.size() && candidate_[w]) evaluate_and_push(w);
    }
    return {};
  }

  std::vector<VertexId> nodata_corners_;
  std::vector<std::uint8_t> coverage_;  // by vertex id: next to a NODATA corner (mark_coverage)
  Triangulation& tri_;
  std::vector<std::uint8_t> candidate_;  // by vertex id: an interior point that may go
  IndexedHeap heap_;                     // candidates by (effective error, vertex id)
  // By vertex: what its key is (removal_bound.hpp's bound, its preview's bound, exact).
  enum Level : std::uint8_t { kRingBound, kPreviewBound, kExact };
  std::vector<std::uint8_t> level_;
  FiledPoints orph_;                   // the orphans, by triangle slot
  mutable std::vector<Plane> planes_;  // scratch of surface_at
  // The removal preview of the last evaluate() that had one (of preview_of_ on the current
  // mesh; kNone once a removal changed it).
  mutable VertexId preview_of_ = kNone;
  mutable std::vector<VertexTriple> preview_;
  // By vertex: its last evaluate()'s lower bound (without the weight) and its preview,
  // bound_tris_[first, first + count) (appended; a few MB over a whole thinning).
  struct Bound {
    double error = 0;
    std::uint32_t first = 0, count = 0;
  };
  mutable std::vector<Bound> bound_;
  mutable std::vector<VertexTriple> bound_tris_;
  std::vector<std::uint32_t> gathered_;
  std::vector<TriangleId> star_;  // remove(): v's triangles (gather_star)
  std::vector<VertexId> ring_;    // remove(): v's neighbours (gather_star)
  std::vector<TriangleId> new_ids_;
  const detail::Lattice* lattice_;
  VertexId removed_last_ = kNone;
};

std::string tile_name(const geo::TileId& id) { return "tile " + id.to_string(); }

}  // namespace

std::vector<Vertex> thin_border_side(std::span<const Vertex> side, bool along_x, std::size_t budget,
                                     double epsilon, std::vector<Vertex>* removed,
                                     std::array<bool, 2> nodata_ends) {
  const std::size_t n = side.size();
  if (n <= 2) return {side.begin(), side.end()};
  auto pos = [&](std::size_t i) { return along_x ? side[i].x : side[i].y; };
  std::vector<std::uint32_t> prev(n), next(n), version(n, 0);
  std::vector<std::uint8_t> alive(n, 1);
  for (std::size_t i = 0; i < n; ++i) {
    prev[i] = static_cast<std::uint32_t>(i == 0 ? 0 : i - 1);
    next[i] = static_cast<std::uint32_t>(i + 1 == n ? n - 1 : i + 1);
  }
  // Max over the side's input points strictly between i's surviving neighbours of the distance to
  // the chord joining them (i included, the removed ones too).
  auto error_of = [&](std::size_t i) {
    const std::size_t a = prev[i], b = next[i];
    const double ta = pos(a), tb = pos(b), za = side[a].z, zb = side[b].z;
    double err = 0;
    for (std::size_t j = a + 1; j < b; ++j) {
      const double f = (pos(j) - ta) / (tb - ta);
      err = std::max(err, std::abs(side[j].z - (za + (zb - za) * f)));
    }
    // Coverage first: the data point next to a NODATA end marks where the data begin.
    const bool keeps_coverage = (i == 1 && nodata_ends[0]) || (i + 2 == n && nodata_ends[1]);
    return err + side[i].weight + (keeps_coverage ? detail::kCoverageCost : 0.0);
  };
  MinQueue queue;
  auto push = [&](std::size_t i) {
    ++version[i];
    queue.push(
        {error_of(i), static_cast<double>(i), 0.0, static_cast<std::uint32_t>(i), version[i]});
  };
  for (std::size_t i = 1; i + 1 < n; ++i) push(i);
  std::size_t count = n - 2;
  while (!queue.empty()) {
    const QueueEntry top = queue.top();
    if (!alive[top.id] || top.version != version[top.id]) {
      queue.pop();
      continue;
    }
    if (count <= budget && top.error >= epsilon) break;
    queue.pop();
    const std::size_t i = top.id;
    alive[i] = 0;
    --count;
    next[prev[i]] = next[i];
    prev[next[i]] = prev[i];
    if (prev[i] != 0) push(prev[i]);
    if (next[i] != n - 1) push(next[i]);
  }
  std::vector<Vertex> kept;
  kept.reserve(count + 2);
  for (std::size_t i = 0; i < n; ++i) {
    if (alive[i]) {
      kept.push_back(side[i]);
    } else if (removed) {
      removed->push_back(side[i]);
    }
  }
  return kept;
}

namespace {

// One tile's thinning (thin_tile), step by step: the border from the border points alone; the
// constrained triangulation of corners + border (+ the interior without the greedy stage); the
// interior (greedy insertion up to its target for large inputs, then removal by error); back to a
// tile. Each step reads what the previous ones left in the members.
class TileThinner {
 public:
  TileThinner(const ThinInput& in, const LodOptions& options, ThinStats& st, const TieContext* ties)
      : in_(in),
        options_(options),
        st_(st),
        ties_(ties),
        r_(in.rect ? *in.rect : in.id.bounds()),
        tri_(kernel::Rect{r_.min_x, r_.min_y, r_.max_x, r_.max_y}) {}

  Result<tile::TinTile> run() {
    thin_border();
    if (Status s = triangulate_fixed(); !s) return s.error();
    if (Status s = constrain_border(); !s) return s.error();
    if (Status s = thin_interior(); !s) return s.error();
    if (Status s = exchange(); !s) return s.error();
    auto out = to_tile();
    if (!out) return out;
    // Cocircular quadrilaterals (a grid's cells) take the diagonal the known points favour, else
    // the one the finer tiles drew.
    const std::array<std::span<const Vertex>, 3> own{in_.interior, in_.orphans, dropped_};
    if (!ties_) {
      detail::break_delaunay_ties(*out, own, {});
      return out;
    }
    std::vector<std::span<const Vertex>> known(own.begin(), own.end());
    known.insert(known.end(), ties_->known.begin(), ties_->known.end());
    detail::break_delaunay_ties(*out, known, ties_->drawn, own);
    return out;
  }

 private:
  // Per-side budgets: the automatic one is spread over the perimeter by length (equal for the
  // square quadtree tiles; a wider-than-high rectangle gives its long sides more).
  std::size_t budget_for(bool along_x) const {
    const std::size_t base_budget = side_budget(options_);
    if (options_.border_points_per_side != 0) return base_budget;
    const double len = along_x ? r_.width() : r_.height();
    const double mean = 0.5 * (r_.width() + r_.height());
    if (!(mean > 0)) return base_budget;
    return static_cast<std::size_t>(
        std::floor(static_cast<double>(base_budget) * len / mean + 0.5));
  }

  // The side from corner c0 to c1, thinned (thin_border_side); its dropped points go to dropped_.
  std::vector<Vertex> thin_side(const std::vector<Vertex>& list, int c0, int c1, bool along_x) {
    std::vector<Vertex> side;
    side.reserve(list.size() + 2);
    side.push_back(in_.corners[static_cast<std::size_t>(c0)]);
    side.insert(side.end(), list.begin(), list.end());
    side.push_back(in_.corners[static_cast<std::size_t>(c1)]);
    std::vector<Vertex> kept =
        thin_border_side(side, along_x, budget_for(along_x), options_.epsilon, &dropped_,
                         {in_.corner_nodata[static_cast<std::size_t>(c0)],
                          in_.corner_nodata[static_cast<std::size_t>(c1)]});
    return std::vector<Vertex>(kept.begin() + 1, kept.end() - 1);
  }

  // 1. The border, side by side, from the border points alone.
  void thin_border() {
    st_.input_points = 4 + in_.north.size() + in_.east.size() + in_.south.size() + in_.west.size() +
                       in_.interior.size();
    sides_ = {thin_side(in_.north, 0, 1, true), thin_side(in_.east, 1, 3, false),
              thin_side(in_.south, 2, 3, true), thin_side(in_.west, 0, 2, false)};
    st_.border_removed = dropped_.size();
  }

  // 2. Triangulates corners + border (+ every interior point unless greedy).
  Status triangulate_fixed() {
    n_fixed_ = 4 + sides_[0].size() + sides_[1].size() + sides_[2].size() + sides_[3].size();
    target_ = greedy_target(options_);
    greedy_ = target_ != 0 && n_fixed_ + in_.interior.size() > target_;
    // (The interior goes in here only without the greedy stage, which chooses its points.)
    pts_.reserve(n_fixed_ + (greedy_ ? 0 : in_.interior.size()));
    auto add = [&](const Vertex& v) { pts_.push_back({v.x, v.y, v.z, v.weight}); };
    for (const auto& c : in_.corners) add(c);
    for (const auto& side : sides_) {
      for (const auto& v : side) add(v);
    }
    if (!greedy_) {
      for (const auto& v : in_.interior) add(v);
    }
    ins_ = tri_.insert_bulk(pts_);
    for (std::size_t i = 0; i < n_fixed_; ++i) {
      if (ins_[i].outcome != kernel::InsertOutcome::inserted) {
        return invalid_argument("lod: " + tile_name(in_.id) + ": corner or edge point #" +
                                std::to_string(i) + " is a duplicate or lies outside the tile");
      }
    }
    // By interior point: its vertex, or kNone (a duplicate, or not selected by the greedy stage).
    interior_vertex_.assign(in_.interior.size(), kNone);
    for (std::size_t i = n_fixed_; i < pts_.size(); ++i) {
      switch (ins_[i].outcome) {
        case kernel::InsertOutcome::inserted:
          interior_vertex_[i - n_fixed_] = ins_[i].vertex;
          break;
        case kernel::InsertOutcome::duplicate:
          ++st_.duplicates;
          break;
        default:
          return invalid_argument("lod: " + tile_name(in_.id) + ": interior point #" +
                                  std::to_string(i - n_fixed_) +
                                  " lies outside the tile or is not finite");
      }
    }
    if (tri_.dimension() != 2)
      return Error(ErrorCode::internal, "lod: " + tile_name(in_.id) + ": degenerate triangulation");
    // The NODATA corners' vertices (coverage first, greedy.hpp).
    for (std::size_t c = 0; c < 4; ++c) {
      if (in_.corner_nodata[c]) nodata_corners_.push_back(ins_[c].vertex);
    }
    return {};
  }

  // 2. (continued) Constrains the border chains, in edge order (corner ids 0..3 are ins_[0..3]).
  Status constrain_border() {
    std::size_t k = 4;
    const std::array<std::array<int, 2>, 4> ends = {{{0, 1}, {1, 3}, {2, 3}, {0, 2}}};
    for (std::size_t side = 0; side < 4; ++side) {
      std::vector<VertexId> chain;
      chain.push_back(ins_[static_cast<std::size_t>(ends[side][0])].vertex);
      for (std::size_t j = 0; j < sides_[side].size(); ++j) chain.push_back(ins_[k++].vertex);
      chain.push_back(ins_[static_cast<std::size_t>(ends[side][1])].vertex);
      for (std::size_t j = 0; j + 1 < chain.size(); ++j) {
        Status c = tri_.insert_constraint(chain[j], chain[j + 1]);
        if (!c.ok())
          return Error(ErrorCode::internal,
                       "lod: " + tile_name(in_.id) + ": border constraint: " + c.error().message);
      }
    }
    if (tri_.num_vertices() != pts_.size() - st_.duplicates) {
      return Error(ErrorCode::internal,
                   "lod: " + tile_name(in_.id) + ": a border constraint added vertices");
    }
    return {};
  }

  // Gridded input (the interior a complete lattice inside the rectangle, more than 4 ×
  // max_points): both stages scan lattice cells instead of filing every point under its
  // triangle. Smaller inputs (every pass-4 parent) stay on the general path: there the greedy
  // stage inserts most points anyway and the scan saves nothing (N00E010's ingest: same LOD CPU),
  // while its drop-stage cost also counts the cells on a star's outline, which made different
  // choices than the general path and a larger chained error bound at the coarse levels.
  std::optional<detail::Lattice> find_lattice() const {
    if (!greedy_ || !options_.lattice_scan || in_.interior.size() <= 4 * options_.max_points) {
      return std::nullopt;
    }
    auto lattice = detail::find_lattice(in_.interior);
    if (lattice && !(lattice->xs.front() >= r_.min_x && lattice->xs.back() <= r_.max_x &&
                     lattice->ys.front() >= r_.min_y && lattice->ys.back() <= r_.max_y)) {
      lattice.reset();  // points outside: the general path reports them
    }
    return lattice;
  }

  // 3. Thins the interior: greedy insertion up to the target (large inputs), then removal.
  Status thin_interior() {
    FiledPoints filed;
    const std::optional<detail::Lattice> lattice = find_lattice();
    st_.lattice = lattice.has_value();
    if (greedy_) {
      std::vector<Vertex> extra = in_.orphans;
      extra.insert(extra.end(), dropped_.begin(), dropped_.end());
      auto g = detail::greedy_insert(tri_, in_.interior, extra, target_, options_.epsilon,
                                     lattice ? &*lattice : nullptr, nodata_corners_,
                                     std::max(r_.width(), r_.height()) / kOutlineSteps);
      if (!g.ok()) {
        return Error(g.error().code, "lod: " + tile_name(in_.id) + ": " + g.error().message);
      }
      interior_vertex_ = std::move(g->vertex);
      st_.duplicates = g->duplicates;
      st_.greedy_inserted = g->inserted;
      st_.greedy_error = g->max_error;
      filed = std::move(g->orphans);
    }
    std::vector<std::uint8_t> candidate(tri_.vertex_id_bound(), 0);
    for (VertexId v : interior_vertex_) {
      if (v != kNone) candidate[v] = 1;
    }
    {
      InteriorThinner thinner(tri_, std::move(candidate), std::move(filed),
                              lattice ? &*lattice : nullptr, nodata_corners_);
      if (!greedy_) {
        for (const auto& o : in_.orphans) thinner.add_orphan(o);
        for (const auto& o : dropped_) thinner.add_orphan(o);
      }
      if (thinner.may_remove(options_.max_points, options_.epsilon)) {
        thinner.seed_queue();
        auto removed = thinner.run(options_.max_points, options_.epsilon, &st_.last_error);
        if (!removed.ok())
          return Error(ErrorCode::internal,
                       "lod: " + tile_name(in_.id) + ": " + removed.error().message);
        removed_last_ = thinner.removed_last();
      }
    }
    if (removed_last_ != kNone) {  // the last interior vertex went (evaluate_last)
      border_only_.emplace(kernel::Rect{r_.min_x, r_.min_y, r_.max_x, r_.max_y});
      border_ins_ =
          border_only_->insert_bulk(std::span<const kernel::Point3>(pts_.data(), n_fixed_));
      for (std::size_t i = 0; i < n_fixed_; ++i) {
        if (border_ins_[i].outcome != kernel::InsertOutcome::inserted) {
          return Error(ErrorCode::internal,
                       "lod: " + tile_name(in_.id) + ": border re-triangulation failed");
        }
      }
    }
    return {};
  }

  // 3. (continued) Exchange steps (LodOptions::exchange_steps) on the surface the drop stage left.
  Status exchange() {
    if (options_.exchange_steps == 0 || removed_last_ != kNone) return {};
    detail::ExchangeInput ex;
    ex.candidates = in_.interior;
    ex.candidate_vertex = &interior_vertex_;
    ex.others = {in_.orphans, dropped_};
    ex.nodata_corners = nodata_corners_;
    ex.outline_tolerance = std::max(r_.width(), r_.height()) / kOutlineSteps;
    auto e = detail::exchange_steps(tri_, ex, options_.exchange_steps);
    if (!e.ok()) {
      return Error(e.error().code, "lod: " + tile_name(in_.id) + ": " + e.error().message);
    }
    st_.exchanged = e->steps;
    return {};
  }

  // 4. Back to a tile: corners, thinned sides, surviving interior (input order), triangles.
  Result<tile::TinTile> to_tile() {
    tile::TinTile out;
    out.id = in_.id;
    out.corners = in_.corners;
    out.corner_nodata = in_.corner_nodata;
    out.north = sides_[0], out.east = sides_[1], out.south = sides_[2], out.west = sides_[3];
    std::vector<std::uint32_t> index(tri_.vertex_id_bound(), kNone);
    for (std::size_t c = 0; c < 4; ++c) index[ins_[c].vertex] = static_cast<std::uint32_t>(c);
    std::uint32_t next_index = 4;
    for (std::size_t i = 4; i < n_fixed_; ++i) index[ins_[i].vertex] = next_index++;
    for (std::size_t j = 0; j < in_.interior.size(); ++j) {
      const VertexId v = interior_vertex_[j];
      if (v == kNone || !tri_.is_vertex(v) || v == removed_last_) continue;
      index[v] = next_index++;
      out.interior.push_back(in_.interior[j]);
    }
    st_.interior_removed = in_.interior.size() - st_.duplicates - out.interior.size();
    if (border_only_) {
      // Only the fixed points are left; their tile numbering is their insertion order.
      index.assign(border_only_->vertex_id_bound(), kNone);
      for (std::size_t i = 0; i < n_fixed_; ++i)
        index[border_ins_[i].vertex] = static_cast<std::uint32_t>(i);
    }
    const Triangulation& final_tri = border_only_ ? *border_only_ : tri_;
    out.triangles.reserve(final_tri.num_finite_triangles());
    for (const auto& t : final_tri.finite_triangles()) {
      tile::Triangle m{index[t[0]], index[t[1]], index[t[2]]};
      if (m[0] == kNone || m[1] == kNone || m[2] == kNone) {
        return Error(ErrorCode::internal,
                     "lod: " + tile_name(in_.id) + ": triangle over an unknown vertex");
      }
      out.triangles.push_back(m);
    }
    out.update_z_range();
    return out;
  }

  const ThinInput& in_;
  const LodOptions& options_;
  ThinStats& st_;
  const TieContext* ties_;  // null: the candidates alone
  const geo::MercatorRect r_;
  std::vector<Vertex> dropped_;               // border points the border thinning dropped
  std::array<std::vector<Vertex>, 4> sides_;  // thinned north, east, south, west
  Triangulation tri_;
  std::vector<kernel::Point3> pts_;  // corners, sides, (interior without greedy) as inserted
  std::vector<kernel::InsertResult> ins_;
  std::size_t n_fixed_ = 0;  // corners + sides
  std::size_t target_ = 0;   // the greedy stage's target (0: none)
  bool greedy_ = false;
  std::vector<VertexId> interior_vertex_;  // by interior point: its vertex or kNone
  std::vector<VertexId> nodata_corners_;
  VertexId removed_last_ = kNone;
  std::optional<Triangulation> border_only_;  // when the last interior vertex went
  std::vector<kernel::InsertResult> border_ins_;
};

}  // namespace

Result<tile::TinTile> thin_tile(const ThinInput& in, const LodOptions& options, ThinStats* stats,
                                const TieContext* ties) {
  if (options.max_points < 4) {
    return invalid_argument("lod: max_points must be at least 4 (the corners), got " +
                            std::to_string(options.max_points));
  }
  if (!(options.epsilon >= 0)) return invalid_argument("lod: epsilon must be ≥ 0");
  if (!(options.greedy_factor >= 0)) return invalid_argument("lod: greedy_factor must be ≥ 0");
  ThinStats local;
  ThinStats& st = stats ? *stats : local;
  st = ThinStats{};
  return TileThinner(in, options, st, ties).run();
}

ThinInput thin_input(const tile::TinTile& tile) {
  ThinInput in;
  in.id = tile.id;
  in.corners = tile.corners;
  in.corner_nodata = tile.corner_nodata;
  in.north = tile.north, in.east = tile.east, in.south = tile.south, in.west = tile.west;
  in.interior = tile.interior;
  return in;
}

std::size_t witness_count(const LodOptions& options) {
  return options.witnesses == std::numeric_limits<std::size_t>::max() ? options.max_points / 8
                                                                      : options.witnesses;
}

Result<LodTile> reduce_finest(const tile::TinTile& finest, const LodOptions& options,
                              ThinStats* stats) {
  auto reduced = thin_tile(thin_input(finest), options, stats);
  if (!reduced.ok()) return reduced.error();
  LodTile out;
  out.tile = std::move(*reduced);
  const ChainInput original{&finest, nullptr, {}, {}};
  ChainedError e =
      chain_error(out.tile, std::span<const ChainInput>(&original, 1), witness_count(options));
  out.tile.geometric_error = e.geometric_error;
  out.tile.rms_error = e.rms_error;
  out.tile.source_points = finest.source_points;
  out.bounds = std::move(e.bounds);
  out.reaches = std::move(e.reaches);
  out.witnesses = std::move(e.witnesses);
  return out;
}

Status reduce_finest_tile(tile::TinTile& tile, const LodOptions& options, ThinStats* stats) {
  auto reduced = reduce_finest(tile, options, stats);
  if (!reduced.ok()) return reduced.error();
  tile = std::move(reduced->tile);
  return {};
}

Status reduce_finest_tile(tile::TinTile& tile, double epsilon, std::size_t max_points,
                          ThinStats* stats) {
  LodOptions o;
  o.epsilon = epsilon;
  o.max_points = max_points;
  return reduce_finest_tile(tile, o, stats);
}

}  // namespace tinstream::lod
