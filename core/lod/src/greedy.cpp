// Greedy insertion stage of the interior thinning (greedy.hpp has the contract).
//
// The stage runs on its own small Delaunay mesh rather than on the kernel's Triangulation: the
// candidate to insert is already known to lie in a given triangle, so no point location walk is
// needed (the kernel's insert walks from its last vertex, and greedy insertions jump across the
// whole tile: that walk was ~30 % of the time on a 770k-point grid), and the mesh knows exactly
// which triangles an insertion touched. Its layout is the kernel's (counter-clockwise v[3],
// n[i] across the edge opposite v[i]); edges on the tile's boundary, and any constrained edge of
// the starting triangulation, have no neighbour (kNone) and are never flipped. Only the chosen
// points are inserted into the kernel's Triangulation at the end.
//
// Triangles touched by inserting p (all incident to p afterwards; p is always v[2]):
//
//        c                    c                         x ─── q            x ─── q
//       / \                  /|\                        │ \   │    flip    │   / │
//      /   \      split     / | \        Lawson flip    │  \  │   ─────▶   │  /  │
//     /  p  \    ─────▶    /  p  \     (x, y, p) + (y,  │   \ │            │ /   │
//    a ───── b            a ─────b      x, q) → (x, q,  p ─── y            p ─── y
//                                       p) + (q, y, p)
//
// How a triangle finds its best candidate (rank(), then publish_best()), three paths:
//   filed    the candidates are filed in buckets like the extra points; the bucket's scan
//            (rank(), or refile()'s assign_to_star() right after an insertion) names the best;
//   fan      a triangle at a NODATA corner (is_fan) scans again with the coverage cost
//            (rank_fan, or rank_fan_cells on a lattice);
//   lattice  the candidates are the cells of a Lattice and are never filed (only the extra
//            points are, from filed_from_ on): rank_cells scans the cells inside the triangle,
//            and a candidate that is no longer one has a NaN candidate_z, which never wins.
// Either way best_[t] names the candidate (pool index or cell: picked()) and heap_ orders the
// triangles by it.
#include "greedy.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <utility>

#include "indexed_heap.hpp"
#include "plane.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::lod::detail {

using kernel::kNone;
using kernel::TriangleId;
using kernel::Triangulation;
using kernel::VertexId;
using kernel::XY;

namespace {

constexpr int next3(int i) { return i == 2 ? 0 : i + 1; }
constexpr int prev3(int i) { return i == 0 ? 2 : i - 1; }

struct Tri {
  std::array<std::uint32_t, 3> v;  // local vertex ids, counter-clockwise
  std::array<std::uint32_t, 3> n;  // neighbour across the edge opposite v[i], or kNone
};

// Stars with more triangles than this locate re-filed points by angle (binary search) instead
// of trying the triangles in turn (the first insertions into the border-only mesh make stars of
// hundreds of thin triangles).
constexpr std::size_t kSmallStar = 12;
constexpr std::size_t kNoLimit = std::numeric_limits<std::size_t>::max();

// Whether four distinct points are the corners of an axis-parallel rectangle, hence exactly
// cocircular (incircle 0, no flip). Lattices are full of them, and the exact predicate decides
// each by slow expanded arithmetic once its floating-point filter fails.
bool axis_rectangle(const XY& a, const XY& b, const XY& c, const XY& d) {
  const double x1 = a.x != b.x ? b.x : (a.x != c.x ? c.x : d.x);
  const double y1 = a.y != b.y ? b.y : (a.y != c.y ? c.y : d.y);
  auto either = [](double v, double u, double w) { return v == u || v == w; };
  return x1 != a.x && y1 != a.y && either(b.x, a.x, x1) && either(c.x, a.x, x1) &&
         either(d.x, a.x, x1) && either(b.y, a.y, y1) && either(c.y, a.y, y1) &&
         either(d.y, a.y, y1);
}

// An allocator whose value-less construct() default-initializes: vector::resize then leaves
// trivial elements unset instead of zeroing memory that is written right after.
template <typename T>
struct DefaultInit : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInit<U>;
  };
  DefaultInit() = default;
  template <typename U>
  DefaultInit(const DefaultInit<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

// What became of a point (PointSet::state, by point). A filed point's copy (Filed::kind) is kept
// equal by set_state(); only kCandidate and kExtra points belong in a bucket, the others leave it
// at its next scan (rank(), refile()).
enum State : std::uint8_t {
  kCandidate,  // may be inserted
  kInserted,
  kGone,   // a duplicate, or an extra point outside the tile: neither inserted nor filed
  kExtra,  // filed, never inserted (extra points; a candidate on a boundary edge)
};

// The candidates, then the extra points, as one list (views of the caller's: no copy).
struct PointList {
  std::span<const tile::Vertex> candidates, extra;
  std::size_t size() const { return candidates.size() + extra.size(); }
  const tile::Vertex& operator[](std::size_t i) const {
    return i < candidates.size() ? candidates[i] : extra[i - candidates.size()];
  }
};

// The points of one greedy_insert call and what became of them; shared by its rounds.
struct PointSet {
  PointList pts;                    // candidates, then extra points
  std::vector<std::uint8_t> state;  // by point
  std::size_t candidates = 0;
  const Lattice* lattice = nullptr;  // when the candidates form one: they are scanned, not filed
  // With a lattice: by cell, its z while it is a candidate, NaN once it is not (a NaN error never
  // wins the scan's comparison, so the scan needs no look-up of the state).
  std::vector<double> candidate_z;
  std::span<const VertexId> nodata_vertices;  // kernel ids of the NODATA corners
  double outline_tolerance = 0;               // greedy_insert's
};

class GreedyInserter {
 public:
  GreedyInserter(Triangulation& tri, PointSet& points)
      : kernel_(tri),
        pts_(points.pts),
        state_(points.state),
        lattice_(points.lattice),
        candidate_z_(points.candidate_z),
        nodata_kernel_(points.nodata_vertices),
        tolerance_(points.outline_tolerance),
        filed_from_(points.lattice ? points.candidates : 0),
        heap_(0) {}

  // Copies the kernel's triangulation (the fixed points), files every point under its triangle
  // and ranks the triangles.
  Status start() {
    const std::vector<std::uint32_t> local_tri = copy_kernel_mesh();
    if (Status s = file_points(local_tri); !s.ok()) return s;
    for (std::uint32_t t = 0; t < tris_.size(); ++t) {
      if (count_[t] != 0 || lattice_) rank(t);
    }
    return {};
  }

  // The largest effective error of a candidate (0 when none is left).
  double top_error() const { return heap_.empty() ? 0.0 : -heap_.key(heap_.top()); }

  // Greedy insertion in the own mesh while the mesh has fewer than max_vertices vertices (see
  // settling below) and the largest effective error is > floor, > 0 and ≥ epsilon. Returns the
  // inserted points in insertion order. Duplicates count into *duplicates.
  std::vector<std::uint32_t> select(std::size_t vertices, std::size_t max_vertices, double epsilon,
                                    double floor, std::size_t* duplicates) {
    std::vector<std::uint32_t> chosen;
    // Settling: the largest error is not monotone (inserting a spike makes the pits next to it
    // stand out), so stopping exactly at max_vertices may leave a freshly raised error that the
    // drop stage cannot remove. Past max_vertices, insertion goes on while the largest error is
    // above the lowest one seen over the last tenth of the way there (at most up to twice
    // max_vertices).
    const bool limited = max_vertices != kNoLimit;
    const std::size_t watch_from = limited ? max_vertices - max_vertices / 10 : kNoLimit;
    const std::size_t hard_cap = limited ? 2 * max_vertices : kNoLimit;
    double settled = std::numeric_limits<double>::infinity();
    while (!heap_.empty()) {
      const std::uint32_t t = heap_.top();
      const double e = -heap_.key(t);
      if (!(e > 0) || e < epsilon || !(e > floor)) break;
      if (vertices >= watch_from) settled = std::min(settled, e);
      if (vertices >= max_vertices && !(e > settled && vertices < hard_cap)) break;
      const Pick pick = picked(t);
      const Outcome outcome = insert(pick, t);
      if (outcome == Outcome::inserted) {
        chosen.push_back(pick.id);
        ++vertices;
        continue;
      }
      // Not insertable (insert() changed nothing): the point stays filed as an extra one (on a
      // wall) or leaves (a duplicate), and t is ranked again without it.
      if (outcome == Outcome::duplicate) ++*duplicates;
      set_state(pick, outcome == Outcome::duplicate ? kGone : kExtra);
      rank(t);
    }
    return chosen;
  }

  // After the points inserted here went into the kernel too (point_vertex: their kernel ids, by
  // point): whether the kernel's mesh is the own one, triangle for triangle (cocircular ties
  // may be split differently). When it is, hand_over() may follow.
  bool matches_kernel(const std::vector<VertexId>& point_vertex) {
    const kernel::Mesh& mesh = kernel_.mesh();
    if (kernel_.num_finite_triangles() != tris_.size()) return false;
    const std::size_t copied = kernel_vertex_.size();
    auto kernel_id = [&](std::uint32_t v) {
      return v < copied ? kernel_vertex_[v] : point_vertex[vertex_point_[v - copied]];
    };
    kernel_slot_.resize(tris_.size());
    // Same count, so the meshes are equal when each own triangle (a, b, c) is a kernel triangle:
    // looked up among the triangles around a (both counter-clockwise).
    for (std::uint32_t t = 0; t < tris_.size(); ++t) {
      const auto& v = tris_[t].v;
      const VertexId a = kernel_id(v[0]), b = kernel_id(v[1]), c = kernel_id(v[2]);
      const TriangleId start = mesh.vertex_triangle(a);
      TriangleId u = start;
      kernel_slot_[t] = kNone;
      for (std::size_t steps = 0; steps < mesh.triangle_slots(); ++steps) {
        const int i = mesh.index_of(u, a);
        if (i < 0) return false;
        const kernel::Triangle& T = mesh.tri(u);
        if (T.v[static_cast<std::size_t>(next3(i))] == b &&
            T.v[static_cast<std::size_t>(prev3(i))] == c) {
          kernel_slot_[t] = u;
          break;
        }
        u = T.n[static_cast<std::size_t>(next3(i))];
        if (u == start || u == kNone) break;
      }
      if (kernel_slot_[t] == kNone) return false;
    }
    return true;
  }

  // The points still filed, by kernel triangle slot. Requires: nothing inserted since start(),
  // or matches_kernel() was true.
  void hand_over(FiledPoints& out) const {
    out.head.assign(kernel_.mesh().triangle_slots(), kNone);
    // (At most the live points: reserved, so that the copies do not grow by doubling beside the
    // pool, which still holds them.)
    out.x.reserve(live_), out.y.reserve(live_), out.z.reserve(live_), out.next.reserve(live_);
    for (std::uint32_t t = 0; t < tris_.size(); ++t) {
      for (std::uint32_t k = begin_[t]; k < begin_[t] + count_[t]; ++k) {
        const Filed& f = pool_[k];
        if (f.kind == kCandidate || f.kind == kExtra) out.push(f.x, f.y, f.z, kernel_slot_[t]);
      }
    }
  }

 private:
  enum class Outcome { inserted, duplicate, on_wall };

  // start(), step 1: the kernel's finite triangles and their vertices become the own mesh
  // (kernel_slot_, kernel_vertex_: where each came from; nodata_: which are NODATA corners).
  // Returns the own triangle of each kernel triangle slot (kNone: not copied).
  std::vector<std::uint32_t> copy_kernel_mesh() {
    const auto& mesh = kernel_.mesh();
    std::vector<std::uint32_t> local_vertex(kernel_.vertex_id_bound(), kNone);
    std::vector<std::uint32_t> local_tri(mesh.triangle_slots(), kNone);
    kernel_.for_each_finite_triangle([&](TriangleId t, const kernel::Triangle& T) {
      local_tri[t] = static_cast<std::uint32_t>(tris_.size());
      kernel_slot_.push_back(t);
      Tri m{};
      for (int k = 0; k < 3; ++k) {
        const VertexId v = T.v[static_cast<std::size_t>(k)];
        if (local_vertex[v] == kNone) {
          local_vertex[v] = static_cast<std::uint32_t>(xy_.size());
          kernel_vertex_.push_back(v);
          xy_.push_back(kernel_.xy(v));
          z_.push_back(kernel_.z(v));
        }
        m.v[static_cast<std::size_t>(k)] = local_vertex[v];
      }
      tris_.push_back(m);
    });
    nodata_.assign(xy_.size(), 0);
    for (const VertexId v : nodata_kernel_) {
      if (v < local_vertex.size() && local_vertex[v] != kNone) nodata_[local_vertex[v]] = 1;
    }
    // Invariant of the own mesh: an edge on the tile's boundary or constrained in the kernel has
    // no neighbour (kNone), so legalize() never flips it and insert() never walks across it.
    kernel_.for_each_finite_triangle([&](TriangleId t, const kernel::Triangle& T) {
      Tri& m = tris_[local_tri[t]];
      for (std::size_t k = 0; k < 3; ++k) {
        const TriangleId u = T.n[k];
        const bool wall =
            u == kNone || local_tri[u] == kNone || mesh.constrained(t, static_cast<int>(k));
        m.n[k] = wall ? kNone : local_tri[u];
      }
    });
    begin_.assign(tris_.size(), 0);
    count_.assign(tris_.size(), 0);
    best_.assign(tris_.size(), kNone);
    heap_.grow(tris_.size());
    return local_tri;
  }

  // start(), step 2: every point from filed_from_ on that is a candidate or an extra point goes
  // into the bucket of the triangle that contains it (counting sort: buckets in triangle order).
  // An extra point outside the tile becomes kGone; a candidate outside is an error.
  Status file_points(const std::vector<std::uint32_t>& local_tri) {
    // where[i − filed_from_]: the triangle of point i.
    std::vector<std::uint32_t> where(pts_.size() - filed_from_, kNone);
    for (std::size_t i = filed_from_; i < pts_.size(); ++i) {
      if (state_[i] != kCandidate && state_[i] != kExtra) continue;
      const tile::Vertex& p = pts_[i];
      const TriangleId t = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)
                               ? kernel_.locate_triangle(p.x, p.y)
                               : kNone;
      if (t == kNone) {
        if (state_[i] == kCandidate) {
          return invalid_argument("interior point #" + std::to_string(i) +
                                  " lies outside the tile or is not finite");
        }
        state_[i] = kGone;  // an extra point outside: not part of this surface
        continue;
      }
      where[i - filed_from_] = local_tri[t];
      ++count_[local_tri[t]];
    }
    std::uint32_t at = 0;
    for (std::uint32_t t = 0; t < tris_.size(); ++t) begin_[t] = at, at += count_[t];
    // A re-filing appends at most the live points and compaction (in place) follows once the
    // pool holds more than 1.5 × them (or could not take the next re-filing): 2.5 × never
    // reallocates.
    pool_.reserve(5 * static_cast<std::size_t>(at) / 2 + 8192);
    pool_.resize(at);
    std::fill(count_.begin(), count_.end(), 0);
    for (std::size_t i = filed_from_; i < pts_.size(); ++i) {
      const std::uint32_t t = where[i - filed_from_];
      if (t == kNone) continue;
      const tile::Vertex& p = pts_[i];
      pool_[begin_[t] + count_[t]++] = {
          p.x, p.y, p.z, static_cast<std::uint32_t>(i), state_[i], weight_index(p.weight)};
    }
    live_ = at;
    return {};
  }

  // A point filed under a triangle: a copy of its position, so that scanning a bucket reads
  // memory in order (32 bytes: its weight is an index into the few distinct weights of the
  // tile's points, weights_, or kWeightById when there are too many: then looked up by id).
  struct Filed {
    double x, y, z;
    std::uint32_t id;      // index into pts_
    std::uint8_t kind;     // State
    std::uint16_t weight;  // index into weights_, or kWeightById
  };
  static_assert(sizeof(Filed) == 32);
  static constexpr std::uint16_t kWeightById = 0xFFFF;
  static constexpr std::size_t kMaxWeights = 64;  // distinct weights kept in weights_

  Plane plane(std::uint32_t t) const {
    const auto& v = tris_[t].v;
    return Plane(xy_[v[0]], xy_[v[1]], xy_[v[2]], z_[v[0]], z_[v[1]], z_[v[2]]);
  }

  // |z − surface| + the point's weight: the same double sum as e + pts_[f.id].weight (weights_
  // holds the weights' exact values, and |…| + 0 is |…| bit for bit), without the random access
  // into the input (LiDAR points all carry a weight, 1 by default).
  double effective_error(const Filed& f, double surface) const {
    const double e = std::abs(f.z - surface);
    if (f.weight == kWeightById) [[unlikely]]
      return plus_weight(e, f.id);
    return e + weights_[f.weight];
  }
  // Out of line: the rare case (more than kMaxWeights distinct weights in one tile).
  [[gnu::noinline]] double plus_weight(double e, std::uint32_t id) const {
    return e + pts_[id].weight;
  }
  // The index of weight w in weights_ (same bits), added when new; kWeightById when full.
  std::uint16_t weight_index(double w) {
    const auto bits = std::bit_cast<std::uint64_t>(w);
    if (bits == last_weight_bits_ && last_weight_ != kWeightById) return last_weight_;
    std::size_t k = 0;
    while (k < weights_.size() && std::bit_cast<std::uint64_t>(weights_[k]) != bits) ++k;
    if (k == weights_.size()) {
      if (k == kMaxWeights) return kWeightById;
      weights_.push_back(w);
    }
    last_weight_bits_ = bits;
    last_weight_ = static_cast<std::uint16_t>(k);
    return last_weight_;
  }

  // Recomputes t's best candidate and its heap key. Scanning the bucket also compacts it: points
  // inserted or gone since leave here (their entries stay behind in the bucket until then, so
  // every bucket scan skips them).
  void rank(std::uint32_t t) {
    const Plane pl = plane(t);
    double best_e = -1, w;
    std::uint32_t best = kNone, kept = begin_[t];
    for (std::uint32_t k = begin_[t]; k < begin_[t] + count_[t]; ++k) {
      const Filed f = pool_[k];
      if (f.kind == kGone || f.kind == kInserted) continue;
      if (f.kind == kCandidate) {
        const double e = effective_error(f, pl.at(f.x, f.y, &w));
        if (e > best_e) best_e = e, best = kept;
      }
      pool_[kept++] = f;
    }
    live_ -= begin_[t] + count_[t] - kept;
    count_[t] = kept - begin_[t];
    publish_best(t, best, best_e);
  }

  // The three ways a triangle is ranked, after its bucket was scanned for the plain effective
  // error (`best`: the pool index of the largest, `best_e`): on a lattice the candidates are not
  // filed but scanned by cell (rank_cells); in a fan (a NODATA corner) the coverage cost counts
  // too (rank_fan: a second scan, rare); otherwise the scan's answer stands.
  void publish_best(std::uint32_t t, std::uint32_t best, double best_e) {
    if (lattice_) {
      rank_cells(t);
    } else if (is_fan(t)) {
      rank_fan(t);
    } else {
      set_best(t, best, best_e);
    }
  }

  // Whether t is at a NODATA corner (greedy.hpp: coverage first).
  bool is_fan(std::uint32_t t) const {
    for (const std::uint32_t v : tris_[t].v) {
      if (v < nodata_.size() && nodata_[v]) return true;
    }
    return false;
  }

  // A point of fan t outside the footprint (greedy.hpp): anywhere in t but on its data edge
  // (exact orient2d = 0 with its two data vertices, when it has one NODATA vertex), where the
  // data triangle beside it covers it, or within the outline tolerance of that edge.
  struct FanEdge {
    bool has_edge = false;
    XY a, b;
    double length = 0;     // |b − a| (once per fan, not per point)
    double tolerance = 0;  // times |b − a|: compared with the cross product
    // (b − a) × (p − a): twice the signed area, |b − a| times the distance from the edge's line.
    double cross(double x, double y) const {
      return (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
    }
    // Beyond the data edge by more than the tolerance (on its line, exactly: never).
    bool beyond(double x, double y, double c) const {
      return kernel::orient2d(a, b, XY{x, y}) != 0 && !(std::abs(c) <= tolerance);
    }
    // The rank of a candidate of this fan with effective error `error` (greedy.hpp: coverage
    // first). Covered: its error. Outside, beyond a data edge: kCoverageCost × (1 + its distance
    // from the edge's line, normalised units), so the farthest point goes in first — a vertex of
    // the hull of what the fan hides (quickhull's choice), which widens the footprint the most;
    // until 2026-11-28 the largest vertical error against the fan's continued heights went first,
    // which says little about the terrain: autzen's outline-floor levels (128 vertices) spent
    // their budget on such points, 1.68× greedy insertion's max error (bench/lod/RESULTS.md).
    // In a fan without a data edge (two or three NODATA vertices): before those, by error.
    double rank(double x, double y, double error) const {
      if (!has_edge) return 4 * kCoverageCost + error;
      const double c = cross(x, y);
      if (!beyond(x, y, c)) return error;
      return kCoverageCost * (1 + std::abs(c) / length);
    }
  };
  FanEdge fan_edge(std::uint32_t t) const {
    FanEdge fe;
    int nodata = 0, k_nodata = 0;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = tris_[t].v[static_cast<std::size_t>(k)];
      if (v < nodata_.size() && nodata_[v]) ++nodata, k_nodata = k;
    }
    if (nodata == 1) {
      fe.has_edge = true;
      fe.a = xy_[tris_[t].v[static_cast<std::size_t>((k_nodata + 1) % 3)]];
      fe.b = xy_[tris_[t].v[static_cast<std::size_t>((k_nodata + 2) % 3)]];
      fe.length = std::hypot(fe.b.x - fe.a.x, fe.b.y - fe.a.y);
      fe.tolerance = tolerance_ * fe.length;
    }
    return fe;
  }

  // Fan t's best candidate from its bucket (filed path), ranked by FanEdge::rank.
  void rank_fan(std::uint32_t t) {
    const FanEdge fe = fan_edge(t);
    const Plane pl = plane(t);
    double best_e = -1, w;
    std::uint32_t best = kNone;
    for (std::uint32_t k = begin_[t]; k < begin_[t] + count_[t]; ++k) {
      const Filed& f = pool_[k];
      if (f.kind != kCandidate) continue;
      const double e = fe.rank(f.x, f.y, effective_error(f, pl.at(f.x, f.y, &w)));
      if (e > best_e) best_e = e, best = k;
    }
    set_best(t, best, best_e);
  }

  // On a lattice: t's best candidate is the candidate cell of largest effective error inside it.
  void rank_cells(std::uint32_t t) {
    if (is_fan(t)) return rank_fan_cells(t);
    const auto& v = tris_[t].v;
    const Lattice& l = *lattice_;
    const Gradient g(xy_[v[0]], xy_[v[1]], xy_[v[2]], z_[v[0]], z_[v[1]], z_[v[2]]);
    double best_e = -1;
    std::uint32_t best = kNone;
    const std::size_t w = l.width();
    const double* weight = l.weight.empty() ? nullptr : l.weight.data();
    // (Everything the loops read is in locals, and the best cell of a row is kept in
    // registers: the compiler cannot tell that storing it does not change the gradient.)
    auto scan_row = [&](std::size_t j, std::size_t i0, std::size_t i1) {
      const double gx = g.gx, ax = g.ax;
      const double base = g.az + g.gy * (l.ys[j] - g.ay);
      const std::size_t row = j * w;
      const double* z = candidate_z_.data() + row;
      const double* x = l.xs.data();
      double row_e = best_e;
      std::size_t row_i = kNone;
      if (weight) {
        const double* wt = weight + row;
        for (std::size_t i = i0; i <= i1; ++i) {
          const double e = std::abs(z[i] - (base + gx * (x[i] - ax))) + wt[i];
          if (e > row_e) row_e = e, row_i = i;
        }
      } else {
        for (std::size_t i = i0; i <= i1; ++i) {
          const double e = std::abs(z[i] - (base + gx * (x[i] - ax)));
          if (e > row_e) row_e = e, row_i = i;
        }
      }
      if (row_i != kNone) best_e = row_e, best = static_cast<std::uint32_t>(row + row_i);
    };
    l.for_each_run(xy_[v[0]], xy_[v[1]], xy_[v[2]], scan_row, candidate_z_.data());
    set_best(t, best, best_e);
  }

  // The same for a fan (coverage first: rank_fan), cell by cell.
  void rank_fan_cells(std::uint32_t t) {
    const auto& v = tris_[t].v;
    const Lattice& l = *lattice_;
    const FanEdge fe = fan_edge(t);
    const Gradient g(xy_[v[0]], xy_[v[1]], xy_[v[2]], z_[v[0]], z_[v[1]], z_[v[2]]);
    double best_e = -1;
    std::uint32_t best = kNone;
    const std::size_t w = l.width();
    auto scan_row = [&](std::size_t j, std::size_t i0, std::size_t i1) {
      const double base = g.az + g.gy * (l.ys[j] - g.ay);
      for (std::size_t i = i0; i <= i1; ++i) {
        const std::size_t cell = j * w + i;
        double e = std::abs(candidate_z_[cell] - (base + g.gx * (l.xs[i] - g.ax)));
        if (!l.weight.empty()) e += l.weight[cell];
        e = fe.rank(l.xs[i], l.ys[j], e);
        if (e > best_e) best_e = e, best = static_cast<std::uint32_t>(cell);
      }
    };
    l.for_each_run(xy_[v[0]], xy_[v[1]], xy_[v[2]], scan_row);
    set_best(t, best, best_e);
  }

  // The candidate named by best_[t]: a pool entry, or on a lattice a cell.
  struct Pick {
    double x, y, z;
    std::uint32_t id;   // index into pts_
    std::uint32_t pos;  // pool index or cell
  };
  Pick picked(std::uint32_t t) const {
    const std::uint32_t pos = best_[t];
    if (lattice_) {
      const Lattice& l = *lattice_;
      const std::size_t w = l.width();
      return {l.xs[pos % w], l.ys[pos / w], l.z[pos], l.point[pos], pos};
    }
    const Filed& f = pool_[pos];
    return {f.x, f.y, f.z, f.id, pos};
  }
  void set_state(const Pick& c, State s) {
    state_[c.id] = s;
    if (!lattice_) pool_[c.pos].kind = s;
    if (lattice_ && s != kCandidate) candidate_z_[c.pos] = std::numeric_limits<double>::quiet_NaN();
  }

  void set_best(std::uint32_t t, std::uint32_t best, double error) {
    best_[t] = best;
    if (best == kNone) {
      heap_.erase(t);
    } else {
      heap_.set(t, -error);
    }
  }

  std::uint32_t new_tri() {
    tris_.push_back({});
    begin_.push_back(0);
    count_.push_back(0);
    best_.push_back(kNone);
    heap_.grow(tris_.size());
    return static_cast<std::uint32_t>(tris_.size() - 1);
  }
  // In triangle `of` (or none), the neighbour reference `old_t` becomes `new_t`.
  void relink(std::uint32_t of, std::uint32_t old_t, std::uint32_t new_t) {
    if (of == kNone) return;
    for (auto& n : tris_[of].n) {
      if (n == old_t) {
        n = new_t;
        return;
      }
    }
  }
  // Joins t to the star being built: its points are gathered for re-filing.
  // Its bucket stays in the pool (refile appends the new buckets after it) until refile has
  // read it.
  void take(std::uint32_t t) {
    star_.push_back(t);
    taken_.emplace_back(begin_[t], count_[t]);
    live_ -= count_[t];
    count_[t] = 0;
  }

  // Inserts the candidate `c`, found in t (t contains it up to rounding: a short walk corrects
  // it): split, Lawson flips, re-filing of the star's points, re-ranking.
  Outcome insert(const Pick& c, std::uint32_t t) {
    const XY p{c.x, c.y};
    const std::uint32_t filed_under = t;
    double o[3];
    if (!walk_to(p, t, o)) return Outcome::on_wall;
    const int zeros = (o[0] == 0) + (o[1] == 0) + (o[2] == 0);
    if (zeros >= 2) return Outcome::duplicate;
    const int edge = zeros == 1 ? (o[0] == 0 ? 0 : (o[1] == 0 ? 1 : 2)) : -1;  // p lies on it
    if (edge >= 0 && tris_[t].n[static_cast<std::size_t>(edge)] == kNone) return Outcome::on_wall;
    set_state(c, kInserted);
    const auto pv = static_cast<std::uint32_t>(xy_.size());
    xy_.push_back(p), z_.push_back(c.z), vertex_point_.push_back(c.id);
    star_.clear();
    taken_.clear();
    if (edge >= 0) {
      split_edge(t, edge, pv);
    } else {
      split_triangle(t, pv);
    }
    legalize(pv);
    refile();
    // Filed under a neighbour by rounding: that triangle's ranking still names the point.
    if (std::find(star_.begin(), star_.end(), filed_under) == star_.end()) rank(filed_under);
    compact_if_due();
    return Outcome::inserted;
  }

  // Moves t to the triangle that contains p exactly (orientations in o: o[k] of p against the
  // edge opposite v[k], all ≥ 0). False when the walk would cross a wall (p off the mesh, or
  // beyond a constrained edge) or takes more than 64 steps.
  bool walk_to(const XY& p, std::uint32_t& t, double (&o)[3]) const {
    for (int steps = 0;; ++steps) {
      const Tri& T = tris_[t];
      int out = -1;
      for (int k = 0; k < 3; ++k) {
        o[k] = kernel::orient2d(xy_[T.v[static_cast<std::size_t>(next3(k))]],
                                xy_[T.v[static_cast<std::size_t>(prev3(k))]], p);
        if (o[k] < 0 && out < 0) out = k;
      }
      if (out < 0) return true;
      const std::uint32_t u = T.n[static_cast<std::size_t>(out)];
      if (u == kNone || steps > 64) return false;
      t = u;
    }
  }

  // Compacts when the garbage reaches half the live points (the pool's memory stays within
  // 2.5 × theirs: a parent thinned from 64 sources files up to a million). That the next
  // re-filing fits in the pool's capacity is checked by refile() itself, once it knows how many
  // entries it gathered (until 2026-11-28 here, for the worst case of all live points: most
  // compactions came from that bound, not from the garbage).
  void compact_if_due() {
    if (pool_.size() > live_ + live_ / 2 + 4096) compact();
  }

  void split_triangle(std::uint32_t t, std::uint32_t p) {
    take(t);
    const Tri old = tris_[t];
    const std::uint32_t a = old.v[0], b = old.v[1], c = old.v[2];
    const std::uint32_t t1 = new_tri(), t2 = new_tri();
    star_.push_back(t1), star_.push_back(t2);
    tris_[t] = {{a, b, p}, {t1, t2, old.n[2]}};
    tris_[t1] = {{b, c, p}, {t2, t, old.n[0]}};
    tris_[t2] = {{c, a, p}, {t, t1, old.n[1]}};
    relink(old.n[0], t, t1);
    relink(old.n[1], t, t2);
    stack_ = {t, t1, t2};
  }

  // p on the edge opposite v[k] of t, shared with u: (a, b, c) + (d, c, b) become
  // (a, b, p), (c, a, p) in t's side and (d, c, p), (b, d, p) in u's.
  void split_edge(std::uint32_t t, int k, std::uint32_t p) {
    const std::uint32_t u = tris_[t].n[static_cast<std::size_t>(k)];
    take(t), take(u);
    const Tri ot = tris_[t], ou = tris_[u];
    const auto K = static_cast<std::size_t>(k);
    const std::uint32_t a = ot.v[K], b = ot.v[(K + 1) % 3], c = ot.v[(K + 2) % 3];
    std::size_t j = 0;
    while (ou.v[j] == b || ou.v[j] == c) ++j;
    const std::uint32_t d = ou.v[j];
    const std::uint32_t n_ab = ot.n[(K + 2) % 3], n_ca = ot.n[(K + 1) % 3];
    const std::uint32_t n_dc = ou.n[(j + 2) % 3], n_bd = ou.n[(j + 1) % 3];
    const std::uint32_t t2 = new_tri(), u2 = new_tri();
    star_.push_back(t2), star_.push_back(u2);
    tris_[t] = {{a, b, p}, {u2, t2, n_ab}};
    tris_[t2] = {{c, a, p}, {t, u, n_ca}};
    tris_[u] = {{d, c, p}, {t2, u2, n_dc}};
    tris_[u2] = {{b, d, p}, {u, t, n_bd}};
    relink(n_ca, t, t2);
    relink(n_bd, u, u2);
    stack_ = {t, t2, u, u2};
  }

  // Lawson flips around the new vertex p (v[2] of every triangle on the stack).
  void legalize(std::uint32_t p) {
    while (!stack_.empty()) {
      const std::uint32_t t = stack_.back();
      stack_.pop_back();
      const Tri T = tris_[t];
      const std::uint32_t u = T.n[2];
      if (u == kNone) continue;
      const std::uint32_t x = T.v[0], y = T.v[1];
      const Tri U = tris_[u];
      std::size_t jq = 0;
      while (U.v[jq] == x || U.v[jq] == y) ++jq;
      const std::uint32_t q = U.v[jq];
      if (axis_rectangle(xy_[x], xy_[y], xy_[p], xy_[q])) continue;  // cocircular: no flip
      if (!(kernel::incircle(xy_[x], xy_[y], xy_[p], xy_[q]) > 0)) continue;
      // U = (y, x, q) rotated: the edge (x, q) is opposite y, (q, y) opposite x.
      std::size_t jy = 0, jx = 0;
      while (U.v[jy] != y) ++jy;
      while (U.v[jx] != x) ++jx;
      const std::uint32_t n_xq = U.n[jy], n_qy = U.n[jx];
      take(u);
      tris_[t] = {{x, q, p}, {u, T.n[1], n_xq}};
      tris_[u] = {{q, y, p}, {T.n[0], t, n_qy}};
      relink(T.n[0], t, u);
      relink(n_xq, u, t);
      stack_.push_back(t), stack_.push_back(u);
    }
  }

  // Files the gathered points into the star, each star triangle's bucket appended at the pool's
  // end, and re-ranks the star. A point goes under the first star triangle (in star_ order, or
  // for a big star the one of its angle and then that one's two neighbours) whose smallest
  // barycentric weight is ≥ 0, and when rounding puts it in none, under the one where that
  // weight is largest.
  // Relies on: every star triangle was taken (take()) or is new, so its count_ is 0 and its old
  // bucket is listed in taken_; the taken buckets stay readable in the pool until step 3.
  void refile() {
    std::size_t entries = 0;
    for (const auto& [b, c] : taken_) entries += c;
    if (entries == 0 && lattice_) {  // nothing filed (the usual case on a lattice): rank only
      for (std::uint32_t t : star_) rank_cells(t);
      taken_.clear();
      return;
    }
    // The new buckets take at most `entries` more (a reallocation would double the pool; indices
    // would survive it): compact first, the gathered buckets (taken_) moved along.
    if (pool_.size() + entries > pool_.capacity()) compact();
    prepare_star(entries);
    const std::uint32_t moved = fans_.empty() ? assign_to_star<false>() : assign_to_star<true>();
    const std::uint32_t end = place_star_buckets();
    move_into_star_buckets(end);
    // The taken buckets are garbage now, never read again: the next re-filings' buckets may go
    // there (place_star_buckets), and into the room left in up to 64 older ones.
    std::erase_if(free_, [](const auto& seg) { return seg.second == 0; });
    if (free_.size() > 64) free_.erase(free_.begin(), free_.end() - 64);
    free_.insert(free_.end(), taken_.begin(), taken_.end());
    taken_.clear();  // (garbage now: compact() must not move it)
    live_ += moved;
    for (std::size_t k = 0; k < star_.size(); ++k) {
      // (A fan's best was ranked by FanEdge::rank while its points were assigned, in the order
      // of its new bucket, as rank_fan would rank them: no second scan.)
      if (!lattice_ && star_fan_[k]) {
        set_best(star_[k], star_best_[k], star_error_[k]);
      } else {
        publish_best(star_[k], star_best_[k], star_error_[k]);
      }
    }
  }

  // refile(), step 0: the star's planes and empty per-star tallies; slot_ room for `entries`.
  void prepare_star(std::size_t entries) {
    const std::size_t n = star_.size();
    planes_.clear();
    for (std::uint32_t s : star_) planes_.push_back(plane(s));
    // The fans among them (is_fan) and their data edges: assign_to_star ranks their points by
    // FanEdge::rank (not on a lattice, where the candidates are scanned by cell).
    star_fan_.assign(n, 0);
    fans_.clear();
    if (!lattice_ && !nodata_kernel_.empty()) {
      for (std::size_t k = 0; k < n; ++k) {
        if (!is_fan(star_[k])) continue;
        star_fan_[k] = 1;
        if (fans_.empty()) fans_.resize(n);
        fans_[k] = fan_edge(star_[k]);
      }
    }
    star_best_.assign(n, kNone);  // the index in its new bucket, then in the pool
    star_error_.assign(n, -1.0);
    star_count_.assign(n, 0);
    if (slot_.size() < entries) slot_.resize(entries);
    if (n > kSmallStar) sort_star_by_angle();
  }

  // refile(), step 1: each gathered point's star triangle (slot_, by gathered entry; kNone for a
  // point that left), its place in that triangle's new bucket (in gather order), and each
  // bucket's best candidate (star_best_, star_error_). Returns the number of points that stay.
  // (The hot loop of the stage. It works on raw pointers: through the vectors, every store made
  // the compiler reload their bounds.) kFans: some star triangle is a fan (star_fan_), whose
  // candidates rank by FanEdge::rank (fans_), as rank_fan ranks them.
  template <bool kFans>
  std::uint32_t assign_to_star() {
    const std::size_t n = star_.size();
    const bool by_angle = n > kSmallStar;
    std::uint32_t* const slot = slot_.data();
    std::uint32_t* const star_count = star_count_.data();
    std::uint32_t* const star_best = star_best_.data();
    double* const star_error = star_error_.data();
    const Plane* const planes = planes_.data();
    const std::uint8_t* const fan = star_fan_.data();
    const FanEdge* const fans = fans_.data();
    std::uint32_t moved = 0, m = 0;
    for (const auto& [b, cnt] : taken_) {
      const Filed* const bucket = pool_.data() + b;
      for (std::uint32_t e = 0; e < cnt; ++e, ++m) {
        const Filed& f = bucket[e];
        if (f.kind != kCandidate && f.kind != kExtra) {
          slot[m] = kNone;
          continue;
        }
        double surface = 0.0;  // always set by the locate calls below (GCC -O3 cannot see it)
        std::uint32_t k = 0;
        if (by_angle) {
          k = locate_by_angle(f.x, f.y, &surface);
        } else {
          while (k < n && !planes[k].contains(f.x, f.y, &surface)) ++k;
          if (k == n) k = locate_in_order(f.x, f.y, &surface);
        }
        slot[m] = k;
        const std::uint32_t place = star_count[k]++;
        ++moved;
        if (f.kind != kCandidate) continue;
        double err = effective_error(f, surface);
        if constexpr (kFans) {
          if (fan[k]) err = fans[k].rank(f.x, f.y, err);
        }
        if (err > star_error[k]) star_error[k] = err, star_best[k] = place;
      }
    }
    return moved;
  }

  // refile(), step 2: the new buckets' places, in star order: each in the first of the earlier
  // re-filings' taken buckets (free_: garbage since, so neither live nor taken now) with room
  // left for it, else after everything in the pool (the taken buckets included). The places
  // change nothing but memory traffic: a bucket's points and their order are the same anywhere.
  // star_best_ becomes a pool index, star_count_ the next free entry of each bucket. Returns the
  // pool's new end. Positions are indices, valid across the pool's growth (which refile()'s
  // compaction keeps within its capacity). (Until 2026-11-28 every bucket went to the end: the pool
  // filled twice as fast, and the compactions moved 1.6 × the re-filed points on Big Tujunga.)
  std::uint32_t place_star_buckets() {
    auto end = static_cast<std::uint32_t>(pool_.size());
    for (std::size_t k = 0; k < star_.size(); ++k) {
      const std::uint32_t t = star_[k];
      const std::uint32_t n = star_count_[k];
      std::uint32_t at = end;
      for (auto& [b, room] : free_) {
        if (room >= n && n != 0) {
          at = b, b += n, room -= n;
          break;
        }
      }
      if (at == end) end += n;
      begin_[t] = at;
      count_[t] = n;
      if (star_best_[k] != kNone) star_best_[k] += at;
      star_count_[k] = at;  // from here: where the bucket's next point goes
    }
    return end;
  }

  // refile(), step 3: the points into their buckets, straight from the taken ones (no scratch
  // copy: the new buckets overlap no taken one).
  void move_into_star_buckets(std::uint32_t end) {
    pool_.resize(end);
    Filed* const pool = pool_.data();
    const std::uint32_t* const slot = slot_.data();
    std::uint32_t* const next = star_count_.data();
    std::uint32_t m = 0;
    for (const auto& [b, cnt] : taken_) {
      for (std::uint32_t e = 0; e < cnt; ++e, ++m) {
        const std::uint32_t k = slot[m];
        if (k != kNone) pool[next[k]++] = pool[b + e];
      }
    }
  }

  // The star index to file (x, y) under, *surface the star's height there: the first star
  // triangle that contains it up to rounding (Plane::contains: min_weight ≥ 0, evaluated only as
  // far as the first negative weight), else the first of largest min_weight after the ones
  // already tried (`best_w`, `k`: by locate_by_angle). (refile() runs the first loop inline.)
  std::uint32_t locate_in_order(double x, double y, double* surface,
                                double best_w = -std::numeric_limits<double>::infinity(),
                                std::uint32_t k = 0) const {
    const std::size_t n = planes_.size();
    const Plane* const planes = planes_.data();
    for (std::size_t s = 0; s < n; ++s) {
      if (planes[s].contains(x, y, surface)) return static_cast<std::uint32_t>(s);
    }
    for (std::size_t s = 0; s < n; ++s) {
      const double w = planes[s].min_weight(x, y);
      if (w > best_w) best_w = w, k = static_cast<std::uint32_t>(s);
    }
    double w;
    *surface = planes_[k].at(x, y, &w);
    return k;
  }

  // For a big star: the sector of the pseudo-angle of (x, y) around the new vertex, then its
  // neighbours if rounding put the point outside it, then locate_in_order.
  std::uint32_t locate_by_angle(double x, double y, double* surface) const {
    const std::size_t n = planes_.size();
    const XY& c = xy_.back();
    const double a = pseudo_angle(x - c.x, y - c.y);
    const std::size_t after = first_sector_after(a);
    const std::size_t at = after == 0 ? n - 1 : after - 1;
    double best_w = -std::numeric_limits<double>::infinity(), w;
    std::uint32_t k = 0;
    for (std::size_t d : {std::size_t{0}, std::size_t{1}, n - 1}) {
      const std::uint32_t s = sector_[(at + d) % n];
      // (at(): min_weight's arithmetic, and the height from the same weights; k is s on return)
      const double z = planes_[s].at(x, y, &w);
      if (w > best_w) best_w = w, k = s;
      if (w >= 0) {
        *surface = z;
        return k;
      }
    }
    return locate_in_order(x, y, surface, best_w, k);
  }

  // A number in [0, 4) increasing with the angle of (dx, dy) from the +x axis (no atan2).
  static double pseudo_angle(double dx, double dy) {
    const double r = dy / (std::abs(dx) + std::abs(dy));
    if (dx < 0) return 2.0 - r;
    return dy < 0 ? 4.0 + r : r;
  }

  // sector_: star indices ordered by the pseudo-angle of their first ring vertex around the new
  // vertex (the last one); sector_start_: those angles. Star triangle (v0, v1, p) spans the
  // angles from v0's to v1's, counter-clockwise.
  void sort_star_by_angle() {
    const XY& c = xy_.back();
    const std::size_t n = star_.size();
    angle_.resize(n);
    sector_.resize(n);
    for (std::size_t s = 0; s < n; ++s) {
      const XY& v0 = xy_[tris_[star_[s]].v[0]];
      angle_[s] = pseudo_angle(v0.x - c.x, v0.y - c.y);
      sector_[s] = static_cast<std::uint32_t>(s);
    }
    std::sort(sector_.begin(), sector_.end(),
              [&](std::uint32_t a, std::uint32_t b) { return angle_[a] < angle_[b]; });
    sector_start_.resize(n);
    for (std::size_t s = 0; s < n; ++s) sector_start_[s] = angle_[sector_[s]];
    // A guess table for first_sector_after: 2n cells over [0, 4), each with the number of
    // sector starts below its lower end.
    const std::size_t cells = 2 * n;
    sector_cells_per_unit_ = static_cast<double>(cells) / 4.0;
    sector_guess_.resize(cells + 1);
    std::size_t k = 0;
    for (std::size_t i = 0; i <= cells; ++i) {
      const double lo = static_cast<double>(i) / sector_cells_per_unit_;
      while (k < n && sector_start_[k] < lo) ++k;
      sector_guess_[i] = static_cast<std::uint32_t>(k);
    }
  }

  // std::upper_bound(sector_start_, a) as an index: a guess from the table, then corrected in
  // both directions, so the table's rounding only costs steps, never changes the answer.
  std::size_t first_sector_after(double a) const {
    const std::size_t n = sector_start_.size();
    const double* const start = sector_start_.data();
    if (!(a >= 0 && a < 4)) {  // (NaN: no guess; upper_bound's answer is n)
      return static_cast<std::size_t>(std::upper_bound(start, start + n, a) - start);
    }
    std::size_t i = sector_guess_[static_cast<std::size_t>(a * sector_cells_per_unit_)];
    while (i > 0 && a < start[i - 1]) --i;
    while (i < n && !(a < start[i])) ++i;
    return i;
  }

  // Drops the pool's abandoned buckets (a refile appends, it never reuses), in place: the live
  // buckets, and the buckets taken_ lists (refile() compacts between gathering and reading them),
  // move down in the order they lie in the pool, so none is overwritten before it moved, and
  // each keeps its points' order. (No second buffer: for a parent thinned from 64 sources the
  // pool holds about a million points.)
  void compact() {
    free_.clear();  // (moved over)
    order_.clear();
    const auto triangles = static_cast<std::uint32_t>(tris_.size());
    for (std::uint32_t t = 0; t < triangles; ++t) {
      if (count_[t] != 0) order_.emplace_back(begin_[t], t);
    }
    for (std::size_t k = 0; k < taken_.size(); ++k) {  // (numbered after the triangles)
      if (taken_[k].second != 0) {
        order_.emplace_back(taken_[k].first, triangles + static_cast<std::uint32_t>(k));
      }
    }
    std::sort(order_.begin(), order_.end());
    Filed* const pool = pool_.data();
    std::uint32_t at = 0;
    for (const auto& [b, t] : order_) {
      const bool taken = t >= triangles;
      const std::uint32_t n = taken ? taken_[t - triangles].second : count_[t];
      if (b != at) std::memmove(pool + at, pool + b, n * sizeof(Filed));
      if (taken) {
        taken_[t - triangles].first = at;
      } else {
        begin_[t] = at;
        if (best_[t] != kNone && !lattice_) best_[t] = at + (best_[t] - b);
      }
      at += n;
    }
    pool_.resize(at);
  }

  Triangulation& kernel_;
  PointList pts_;
  std::vector<std::uint8_t>& state_;
  const Lattice* lattice_;            // the candidates' lattice, or null (then they are filed too)
  std::vector<double>& candidate_z_;  // PointSet::candidate_z
  std::span<const VertexId> nodata_kernel_;  // PointSet::nodata_vertices
  double tolerance_;                         // PointSet::outline_tolerance
  std::vector<std::uint8_t> nodata_;         // by own vertex: a NODATA corner
  std::size_t filed_from_;  // points below this index are scanned on the lattice, not filed
  // By own triangle: its kernel slot, as copied in start(), then as found by matches_kernel().
  std::vector<TriangleId> kernel_slot_;
  std::vector<VertexId> kernel_vertex_;      // by own vertex copied from the kernel
  std::vector<std::uint32_t> vertex_point_;  // by own vertex inserted here (after the copied)
  // The own mesh.
  std::vector<XY> xy_;
  std::vector<double> z_;
  std::vector<Tri> tris_;
  // Buckets: triangle t's points are pool_[begin_[t], begin_[t] + count_[t]).
  std::vector<Filed, DefaultInit<Filed>> pool_;                 // (resize leaves new entries unset)
  std::vector<std::pair<std::uint32_t, std::uint32_t>> order_;  // compact(): (begin, triangle)
  std::vector<std::uint32_t> begin_, count_;                    // by triangle
  std::size_t live_ = 0;                                        // points in buckets
  // Garbage the next re-filing may fill (begin, room left): the last one's taken buckets and
  // what is left of up to 64 earlier ones; emptied by compact().
  std::vector<std::pair<std::uint32_t, std::uint32_t>> free_;
  // By triangle: its candidate of largest effective error, as a pool index (or on a lattice a
  // cell: Pick), kNone when it has none (then it is not in heap_).
  std::vector<std::uint32_t> best_;
  IndexedHeap heap_;  // triangles by −(largest effective error), then id
  // Scratch of one insertion.
  std::vector<std::uint32_t> star_, stack_, star_best_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> taken_;  // (begin, count) of taken buckets
  std::vector<std::uint32_t> slot_;        // by gathered entry: its star index, or kNone
  std::vector<std::uint32_t> star_count_;  // by star index: its new bucket's size, then its end
  std::vector<double> star_error_;
  std::vector<std::uint32_t> sector_;
  std::vector<double> angle_, sector_start_;
  std::vector<std::uint32_t> sector_guess_;  // by cell of the pseudo-angle (sort_star_by_angle)
  double sector_cells_per_unit_ = 0;
  std::vector<Plane> planes_;
  std::vector<std::uint8_t> star_fan_;  // by star index: a fan (is_fan), not on a lattice
  std::vector<FanEdge> fans_;           // by star index, when some star triangle is a fan
  // The distinct weights of the filed points (Filed::weight), and weight_index()'s last answer.
  std::vector<double> weights_;
  std::uint64_t last_weight_bits_ = 0;
  std::uint16_t last_weight_ = kWeightById;  // (none yet)
};

// The points of one greedy_insert call: candidates first (all kCandidate), then the extra
// points (kExtra).
PointSet make_point_set(std::span<const tile::Vertex> candidates,
                        std::span<const tile::Vertex> extra, const Lattice* lattice,
                        std::span<const VertexId> nodata_vertices, double outline_tolerance) {
  PointSet points;
  points.nodata_vertices = nodata_vertices;
  points.outline_tolerance = outline_tolerance;
  points.candidates = candidates.size();
  points.lattice = lattice;
  if (lattice) points.candidate_z = lattice->z;
  points.pts = {candidates, extra};
  points.state.assign(points.pts.size(), kExtra);
  std::fill(points.state.begin(),
            points.state.begin() + static_cast<std::ptrdiff_t>(candidates.size()), kCandidate);
  return points;
}

// Inserts the chosen points into the kernel's triangulation, in their order (`bulk`: in one
// insert_bulk call, which may order them otherwise), and records their vertices in out.vertex.
// Every chosen point must go in: it was a vertex of the own mesh, so it duplicates no vertex.
Status commit_to_kernel(Triangulation& tri, const PointList& pts,
                        const std::vector<std::uint32_t>& chosen, bool bulk, GreedyResult& out) {
  if (bulk) {
    std::vector<kernel::Point3> p3;
    p3.reserve(chosen.size());
    for (std::uint32_t i : chosen) {
      const tile::Vertex& p = pts[i];
      p3.push_back({p.x, p.y, p.z, p.weight});
    }
    const std::vector<kernel::InsertResult> ins = tri.insert_bulk(p3);
    for (std::size_t k = 0; k < chosen.size(); ++k) {
      if (ins[k].outcome == kernel::InsertOutcome::inserted) out.vertex[chosen[k]] = ins[k].vertex;
    }
  } else {
    for (const std::uint32_t c : chosen) {
      const tile::Vertex& p = pts[c];
      const kernel::InsertResult r = tri.insert({p.x, p.y, p.z, p.weight});
      if (r.outcome != kernel::InsertOutcome::inserted) break;
      out.vertex[c] = r.vertex;
    }
  }
  for (std::uint32_t i : chosen) {
    if (out.vertex[i] == kNone) {
      return Error(ErrorCode::internal, "interior point #" + std::to_string(i) +
                                            " chosen by greedy insertion was not inserted");
    }
  }
  out.inserted += chosen.size();
  return {};
}

// The last step of every way out: the points still filed (in `g`'s mesh, which is the kernel's
// triangle for triangle) and the largest error left.
void finish(const GreedyInserter& g, GreedyResult& out) {
  g.hand_over(out.orphans);
  out.max_error = g.top_error();
}

}  // namespace

Result<GreedyResult> greedy_insert(Triangulation& tri, std::span<const tile::Vertex> candidates,
                                   std::span<const tile::Vertex> extra, std::size_t max_vertices,
                                   double epsilon, const Lattice* lattice,
                                   std::span<const VertexId> nodata_vertices,
                                   double outline_tolerance) {
  PointSet points = make_point_set(candidates, extra, lattice, nodata_vertices, outline_tolerance);
  GreedyResult out;
  out.vertex.assign(candidates.size(), kNone);
  // Round 0 selects in the own mesh; the kernel's triangulation of the chosen points may
  // resolve cocircular ties (common on grids) with other diagonals than the own mesh did. When
  // it does, the next round copies the kernel's mesh back, re-files and re-ranks every point and
  // inserts, in the own mesh and then in the kernel in the same order, the candidates whose
  // error exceeds what round 0 stopped at. It ends when the meshes match or a round has nothing
  // to insert.
  double floor = 0;
  constexpr int kMaxRounds = 8;
  for (int round = 0;; ++round) {
    GreedyInserter g(tri, points);
    if (Status s = g.start(); !s.ok()) return s.error();
    const std::vector<std::uint32_t> chosen = g.select(
        tri.num_vertices(), round == 0 ? max_vertices : kNoLimit, epsilon, floor, &out.duplicates);
    // (Repairs are for errors the kernel's diagonals raised; the point that round 0 stopped at
    // comes out equal up to rounding, which must not decide whether it goes in.)
    if (round == 0) floor = g.top_error() * (1 + 1e-9);
    if (chosen.empty()) {  // g's mesh is the kernel's: copied by start(), nothing inserted since
      finish(g, out);
      break;
    }
    if (round == kMaxRounds) {
      // Give up repairing: re-file in the kernel's mesh as it is (the error stays honest).
      if (Status s = commit_to_kernel(tri, points.pts, chosen, false, out); !s.ok()) {
        return s.error();
      }
      GreedyInserter last(tri, points);
      if (Status s = last.start(); !s.ok()) return s.error();
      finish(last, out);
      break;
    }
    if (Status s = commit_to_kernel(tri, points.pts, chosen, round == 0, out); !s.ok()) {
      return s.error();
    }
    if (g.matches_kernel(out.vertex)) {
      finish(g, out);
      break;
    }
  }
  return out;
}

}  // namespace tinstream::lod::detail
