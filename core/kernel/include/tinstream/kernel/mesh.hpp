// tinstream/kernel/mesh.hpp — the triangle-based data structure (layer 2 of the kernel).
//
// Contract: Mesh stores vertices and triangles by 32-bit index and performs purely topological
// edits (split a triangle, split an edge, flip an edge, free a triangle). It knows nothing about
// geometry beyond storing coordinates; whether an edit is *geometrically* valid is decided by the
// algorithms layer (triangulation.hpp). The Mesh owns all its storage (plain std::vectors);
// indices stay valid until the element is removed. Not thread-safe: one owner thread.
//
// Numbering convention (paper Listings 2-3, CGAL's): a triangle lists its vertices
// counter-clockwise, v[0] v[1] v[2]; neighbour n[i] lies across the edge *opposite* v[i], i.e.
// the edge v[i+1] -> v[i+2] (indices mod 3). constrained(t, i) flags that same edge.
//
//                  v[2]
//                  /  \       .
//        n[1]     /    \      n[0]
//   (across      /  t   \     (across v[1]-v[2])
//   v[2]-v[0])  /        \    .
//             v[0] ------ v[1]
//                 n[2] (across v[0]-v[1])
//
// The infinite ("ghost") vertex kInfiniteVertex = 0 closes the triangulation into a sphere as in
// CGAL: every hull edge a->b (interior on its left) has a ghost triangle (b, a, 0) on its right,
// so every live triangle has three live neighbours. A triangle is finite when none of its
// vertices is 0. After triangles were cut away (islands, see Triangulation::remove_triangles_if)
// a neighbour may be kNone.
#pragma once

#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::kernel {

using VertexId = std::uint32_t;
using TriangleId = std::uint32_t;
inline constexpr std::uint32_t kNone = 0xFFFFFFFFu;
inline constexpr VertexId kInfiniteVertex = 0;

namespace detail {
// Asks the OS to back the 2 MiB-aligned part of [p, p + bytes) with transparent huge pages
// (Linux madvise(MADV_HUGEPAGE); a no-op elsewhere, when refused, or for blocks under 4 MiB).
// Point location and vertex removal touch the big arrays at random; with 4 KiB pages nearly every
// such access is also a TLB miss, which costs more than the cache miss itself under
// virtualisation. Only pages not yet touched are affected, so it is given right after a reserve.
void advise_huge_pages(const void* p, std::size_t bytes);
}  // namespace detail

inline constexpr int next3(int i) { return i == 2 ? 0 : i + 1; }
inline constexpr int prev3(int i) { return i == 0 ? 2 : i - 1; }

struct Triangle {
  std::array<VertexId, 3> v;    // counter-clockwise; v[0] == kNone marks a freed slot
  std::array<TriangleId, 3> n;  // n[i] across the edge opposite v[i]
};

class Mesh {
 public:
  Mesh() { add_vertex(0.0, 0.0, 0.0, 0.0); }  // slot 0: the infinite vertex

  // ---- vertices -------------------------------------------------------------------------------
  VertexId add_vertex(double x, double y, double z, double weight) {
    xy_.push_back({x, y});
    z_.push_back(z);
    weight_.push_back(weight);
    vtri_.push_back(kNone);
    return static_cast<VertexId>(xy_.size() - 1);
  }
  // Reserves room for n vertices; the arrays reached at random get the huge-page hint (only a
  // bulk reserve does: growth one element at a time keeps ordinary pages, whose faults are
  // cheaper than huge-page compaction when only a few elements are added).
  void reserve_vertices(std::size_t n) {
    xy_.reserve(n + 1);
    z_.reserve(n + 1);
    weight_.reserve(n + 1);
    vtri_.reserve(n + 1);
    detail::advise_huge_pages(xy_.data(), xy_.capacity() * sizeof(XY));
    detail::advise_huge_pages(vtri_.data(), vtri_.capacity() * sizeof(TriangleId));
  }
  std::size_t vertex_slots() const { return xy_.size(); }  // including slot 0 and removed ones
  const XY& xy(VertexId v) const { return xy_[v]; }
  double z(VertexId v) const { return z_[v]; }
  double weight(VertexId v) const { return weight_[v]; }
  void set_z(VertexId v, double z) { z_[v] = z; }
  void set_weight(VertexId v, double w) { weight_[v] = w; }
  // One live triangle incident to v, or kNone (removed vertex, or not yet triangulated).
  TriangleId vertex_triangle(VertexId v) const { return vtri_[v]; }
  void set_vertex_triangle(VertexId v, TriangleId t) { vtri_[v] = t; }

  // Cache hints (no effect on the contents): start loading what an edit will read or write.
  void prefetch_vertex(VertexId v) const {
    __builtin_prefetch(&xy_[v]);
    __builtin_prefetch(&vtri_[v], 1);
  }
  void prefetch_triangle(TriangleId t) const { __builtin_prefetch(&tris_[t], 1); }

  // ---- triangles ------------------------------------------------------------------------------
  std::size_t triangle_slots() const { return tris_.size(); }
  std::size_t live_triangles() const { return tris_.size() - free_.size(); }
  std::size_t ghost_triangles() const { return ghosts_; }
  const Triangle& tri(TriangleId t) const { return tris_[t]; }
  bool is_live(TriangleId t) const { return tris_[t].v[0] != kNone; }
  bool is_ghost(TriangleId t) const {
    const auto& v = tris_[t].v;
    return v[0] == kInfiniteVertex || v[1] == kInfiniteVertex || v[2] == kInfiniteVertex;
  }
  bool constrained(TriangleId t, int i) const {
    return any_constrained_ && ((flags_[t] >> i) & 1u);
  }
  void set_constrained(TriangleId t, int i, bool on) {
    if (!any_constrained_) {
      if (!on) return;
      any_constrained_ = true;  // the flag array exists from the first constrained edge on
      flags_.assign(tris_.size(), 0);
    }
    if (on) {
      flags_[t] = static_cast<std::uint8_t>(flags_[t] | (1u << i));
    } else {
      flags_[t] = static_cast<std::uint8_t>(flags_[t] & ~(1u << i));
    }
  }
  // Sets both sides of the edge opposite v[i] of t.
  void set_edge_constrained(TriangleId t, int i, bool on) {
    set_constrained(t, i, on);
    const TriangleId u = tris_[t].n[i];
    if (u != kNone) set_constrained(u, mirror(t, i), on);
  }
  // Index of vertex v in t, or -1. Branch-free: which corner holds v is unpredictable, and a
  // mispredicted compare chain cost more than the arithmetic in the star walks of removal.
  int index_of(TriangleId t, VertexId v) const {
    const auto& tv = tris_[t].v;
    const int at12 = static_cast<int>(tv[1] == v) | (static_cast<int>(tv[2] == v) << 1);
    return at12 - 1 + static_cast<int>(tv[0] == v) + static_cast<int>(at12 != 0);
  }
  // Index j such that tri(n[i]).n[j] == t. Requires: n[i] != kNone.
  int mirror(TriangleId t, int i) const { return index_of_neighbour(tris_[t].n[i], t); }
  // Index j such that tri(u).n[j] == t. Requires: t is a neighbour of u.
  int index_of_neighbour(TriangleId u, TriangleId t) const {
    const auto& un = tris_[u].n;
    return static_cast<int>(un[1] == t) | (static_cast<int>(un[2] == t) << 1);  // branch-free
  }

  TriangleId new_triangle(VertexId a, VertexId b, VertexId c) {
    TriangleId t;
    if (!free_.empty()) {
      t = free_.back();
      free_.pop_back();
      tris_[t] = Triangle{{a, b, c}, {kNone, kNone, kNone}};
      if (any_constrained_) flags_[t] = 0;
    } else {
      t = static_cast<TriangleId>(tris_.size());
      tris_.push_back(Triangle{{a, b, c}, {kNone, kNone, kNone}});
      if (any_constrained_) flags_.push_back(0);
    }
    if (a == kInfiniteVertex || b == kInfiniteVertex || c == kInfiniteVertex) ++ghosts_;
    return t;
  }
  // A slot for a new triangle, taken as new_triangle takes it (last freed first); the caller
  // writes all of it and keeps the ghost count.
  [[gnu::always_inline]] TriangleId take_slot() {
    if (!free_.empty()) {
      const TriangleId t = free_.back();
      free_.pop_back();
      if (any_constrained_) flags_[t] = 0;
      return t;
    }
    const auto t = static_cast<TriangleId>(tris_.size());
    tris_.emplace_back();
    if (any_constrained_) flags_.push_back(0);
    return t;
  }
  void free_triangle(TriangleId t) {
    if (is_ghost(t)) --ghosts_;
    tris_[t].v = {kNone, kNone, kNone};
    tris_[t].n = {kNone, kNone, kNone};
    if (any_constrained_) flags_[t] = 0;
    free_.push_back(t);
  }
  // Rewrites the vertices of a live triangle (keeps the ghost count right).
  void set_vertices(TriangleId t, VertexId a, VertexId b, VertexId c) {
    if (is_ghost(t)) --ghosts_;
    tris_[t].v = {a, b, c};
    if (a == kInfiniteVertex || b == kInfiniteVertex || c == kInfiniteVertex) ++ghosts_;
  }
  // Rewrites a live triangle's vertices and neighbours at once (keeps the ghost count right).
  void set_triangle(TriangleId t, const Triangle& tri) {
    ghosts_ -= static_cast<std::size_t>(is_ghost(t));
    tris_[t] = tri;
    ghosts_ += static_cast<std::size_t>(is_ghost(t));
  }
  // Same for a finite triangle replacing a finite one (no ghost count to keep).
  void set_finite_triangle(TriangleId t, const Triangle& tri) {
    assert(!is_ghost(t) && tri.v[0] != kInfiniteVertex && tri.v[1] != kInfiniteVertex &&
           tri.v[2] != kInfiniteVertex);
    tris_[t] = tri;
  }
  void set_neighbour(TriangleId t, int i, TriangleId u) { tris_[t].n[i] = u; }
  // Makes t (edge i) and u (edge j) neighbours of each other.
  void link(TriangleId t, int i, TriangleId u, int j) {
    tris_[t].n[i] = u;
    if (u != kNone) tris_[u].n[j] = t;
  }
  // In the triangle `of` (possibly kNone), replaces the neighbour reference old_t by new_t.
  void replace_neighbour(TriangleId of, TriangleId old_t, TriangleId new_t) {
    if (of == kNone) return;
    const int k = index_of_neighbour(of, old_t);  // branch-free: the slot is unpredictable
    assert(tris_[of].n[k] == old_t);
    tris_[of].n[k] = new_t;
  }

  // ---- topological edits ----------------------------------------------------------------------
  // Splits t = (a, b, c) at new vertex p into (a, b, p), (b, c, p), (c, a, p); p is v[2] of all
  // three, so the old edges are at index 2. Returns the three triangles (t is reused first).
  std::array<TriangleId, 3> split_triangle(TriangleId t, VertexId p) {
    const Triangle old = tris_[t];
    const VertexId a = old.v[0], b = old.v[1], c = old.v[2];
    const TriangleId t1 = take_slot();
    const TriangleId t2 = take_slot();  // the same slots, in the same order, as new_triangle
    tris_[t] = Triangle{{a, b, p}, {t1, t2, old.n[2]}};
    tris_[t1] = Triangle{{b, c, p}, {t2, t, old.n[0]}};
    tris_[t2] = Triangle{{c, a, p}, {t, t1, old.n[1]}};
    // At most one of a, b, c is the infinite vertex; if one is, two of the three are ghosts.
    ghosts_ += static_cast<std::size_t>((a == kInfiniteVertex) | (b == kInfiniteVertex) |
                                        (c == kInfiniteVertex));
    if (any_constrained_) {
      const std::uint8_t f = flags_[t];
      flags_[t] = static_cast<std::uint8_t>(((f >> 2) & 1u) << 2);
      flags_[t1] = static_cast<std::uint8_t>((f & 1u) << 2);
      flags_[t2] = static_cast<std::uint8_t>(((f >> 1) & 1u) << 2);
    }
    replace_neighbour(old.n[0], t, t1);
    replace_neighbour(old.n[1], t, t2);
    vtri_[c] = t1;  // a and b stay in t
    vtri_[p] = t;
    return {t, t1, t2};
  }

  // Splits the edge opposite v[i] of t (shared with u = n[i]) at new vertex p. Returns the four
  // triangles, in each of which the edge opposite p is one of the four old outer edges; the
  // second of each pair is the index of p. A constrained edge stays constrained in both halves.
  struct EdgeSplit {
    std::array<TriangleId, 4> t;
    std::array<int, 4> p_index;
  };
  EdgeSplit split_edge(TriangleId t, int i, VertexId p) {
    const TriangleId u = tris_[t].n[i];
    const int j = mirror(t, i);
    const Triangle ot = tris_[t], ou = tris_[u];
    const std::uint8_t ft = any_constrained_ ? flags_[t] : 0, fu = any_constrained_ ? flags_[u] : 0;
    const VertexId a = ot.v[i], uu = ot.v[next3(i)], w = ot.v[prev3(i)], q = ou.v[j];
    const TriangleId A = ot.n[next3(i)], B = ot.n[prev3(i)];
    const TriangleId C = ou.n[next3(j)], D = ou.n[prev3(j)];
    const bool fA = (ft >> next3(i)) & 1u, fB = (ft >> prev3(i)) & 1u;
    const bool fC = (fu >> next3(j)) & 1u, fD = (fu >> prev3(j)) & 1u;
    const bool fe = (ft >> i) & 1u;
    const TriangleId t1 = new_triangle(a, p, w);
    const TriangleId u1 = new_triangle(q, p, uu);
    set_vertices(t, a, uu, p);
    set_vertices(u, q, w, p);
    // t = (a, u, p): n = [(u,p)->u1, (p,a)->t1, (a,u)->B]
    tris_[t].n = {u1, t1, B};
    if (any_constrained_) flags_[t] = static_cast<std::uint8_t>((fe ? 1u : 0u) | (fB ? 4u : 0u));
    // t1 = (a, p, w): n = [(p,w)->u, (w,a)->A, (a,p)->t]
    tris_[t1].n = {u, A, t};
    if (any_constrained_) flags_[t1] = static_cast<std::uint8_t>((fe ? 1u : 0u) | (fA ? 2u : 0u));
    // u = (q, w, p): n = [(w,p)->t1, (p,q)->u1, (q,w)->D]
    tris_[u].n = {t1, u1, D};
    if (any_constrained_) flags_[u] = static_cast<std::uint8_t>((fe ? 1u : 0u) | (fD ? 4u : 0u));
    // u1 = (q, p, u): n = [(p,u)->t, (u,q)->C, (q,p)->u]
    tris_[u1].n = {t, C, u};
    if (any_constrained_) flags_[u1] = static_cast<std::uint8_t>((fe ? 1u : 0u) | (fC ? 2u : 0u));
    replace_neighbour(A, t, t1);
    replace_neighbour(C, u, u1);
    vtri_[uu] = t;  // a stays in t, q in u
    vtri_[w] = t1;
    vtri_[p] = t;
    return {{t, t1, u, u1}, {2, 1, 2, 1}};
  }

  // Flips the edge opposite v[i] of t. With t = (p, u, w) (p = v[i]) and its neighbour
  // (q, w, u), the result is t = (p, u, q) and neighbour = (q, w, p). Returns the neighbour id.
  // The new edge p-q is unconstrained. Requires: the quadrilateral is strictly convex (checked
  // by the caller with exact predicates).
  TriangleId flip(TriangleId t, int i) { return flip(t, i, mirror(t, i)); }
  // Same, with j = mirror(t, i) already known. Always inlined: the Lawson loop flips ~3 times per
  // insertion, and the call (register saves, reloads of what the loop had loaded) was ~10 % of it.
  [[gnu::always_inline]] TriangleId flip(TriangleId t, int i, int j) {
    Triangle& T = tris_[t];
    const TriangleId u = T.n[i];
    Triangle& U = tris_[u];
    const int i1 = next3(i), i2 = prev3(i), j1 = next3(j), j2 = prev3(j);
    const VertexId p = T.v[i], uu = T.v[i1], w = T.v[i2], q = U.v[j];
    const TriangleId A = T.n[i1], B = T.n[i2], C = U.n[j1], D = U.n[j2];
    if (any_constrained_) {
      const unsigned ft = flags_[t], fu = flags_[u];
      flags_[t] = static_cast<std::uint8_t>(((fu >> j1) & 1u) | (((ft >> i2) & 1u) << 2));
      flags_[u] = static_cast<std::uint8_t>(((ft >> i1) & 1u) | (((fu >> j2) & 1u) << 2));
    }
    T.v = {p, uu, q};
    T.n = {C, u, B};
    U.v = {q, w, p};
    U.n = {A, t, D};
    // Ghost count: an edge (x, 0) flipped away loses one ghost, a new edge (p, 0) adds one.
    ghosts_ += static_cast<std::size_t>((p == kInfiniteVertex) | (q == kInfiniteVertex));
    ghosts_ -= static_cast<std::size_t>((uu == kInfiniteVertex) | (w == kInfiniteVertex));
    replace_neighbour(C, u, t);
    replace_neighbour(A, t, u);
    vtri_[uu] = t;  // p and q stay in both; u-vertex only in t, w only in u
    vtri_[w] = u;
    return u;
  }

  // Drops every triangle and vertex-to-triangle reference (vertices stay).
  void clear_triangles() {
    tris_.clear();
    flags_.clear();
    any_constrained_ = false;
    free_.clear();
    ghosts_ = 0;
    for (auto& t : vtri_) t = kNone;
  }
  // Drops every vertex and triangle but keeps the arrays' memory: the mesh is then as a new one
  // (only the infinite vertex), and what is built next reuses the capacity.
  void clear() {
    xy_.clear();
    z_.clear();
    weight_.clear();
    vtri_.clear();
    clear_triangles();
    add_vertex(0.0, 0.0, 0.0, 0.0);
  }
  void reserve_triangles(std::size_t n) {
    tris_.reserve(n);
    if (any_constrained_) flags_.reserve(n);
    detail::advise_huge_pages(tris_.data(), tris_.capacity() * sizeof(Triangle));
  }
  std::size_t memory_bytes() const {
    return xy_.capacity() * sizeof(XY) + (z_.capacity() + weight_.capacity()) * sizeof(double) +
           vtri_.capacity() * sizeof(TriangleId) + tris_.capacity() * sizeof(Triangle) +
           flags_.capacity() + free_.capacity() * sizeof(TriangleId);
  }

 private:
  std::vector<XY> xy_;
  std::vector<double> z_;
  std::vector<double> weight_;
  std::vector<TriangleId> vtri_;
  std::vector<Triangle> tris_;
  std::vector<std::uint8_t> flags_;  // bit i: edge opposite v[i] constrained
  std::vector<TriangleId> free_;
  std::size_t ghosts_ = 0;
  bool any_constrained_ = false;  // while false every flag is 0 and edits skip the flag array
};

}  // namespace tinstream::kernel
