// Incremental insertion: point location by walking, the four insertion cases, Lawson flips with
// an explicit stack, dimension raising for collinear starts, and bulk insertion in BRIO/Hilbert
// order.
#include <algorithm>
#include <array>
#include <cmath>

#include "spatial_sort.hpp"
#include "tinstream/kernel/triangulation.hpp"
#include "triangulation_detail.hpp"

namespace tinstream::kernel {

using detail::kPendingTriangle;

TriangleId Triangulation::start_triangle(TriangleId hint) const {
  TriangleId t = hint;
  if (t == kNone || t >= mesh_.triangle_slots() || !mesh_.is_live(t)) {
    t = kNone;
    for (TriangleId s = 0; s < mesh_.triangle_slots(); ++s) {
      if (mesh_.is_live(s) && !mesh_.is_ghost(s)) {
        t = s;
        break;
      }
    }
    return t;
  }
  if (mesh_.is_ghost(t)) {
    const int g = mesh_.index_of(t, kInfiniteVertex);
    const TriangleId f = mesh_.tri(t).n[g];
    if (f != kNone && !mesh_.is_ghost(f)) return f;
    return start_triangle(kNone);
  }
  return t;
}

// Remembering stochastic visibility walk (Devillers, Pion, Teillaud 2002): from the current
// triangle cross an edge that separates it from p, trying the edges from a random start so that
// the walk cannot cycle even in non-Delaunay (constrained) triangulations.
Triangulation::Location Triangulation::locate(const XY& p, TriangleId hint) const {
  TriangleId t = start_triangle(hint);
  if (t == kNone) return {Where::outside_hull, kNone, 0};
  TriangleId prev = kNone;
  int start = 0;
  double o[3];
  for (;;) {
    const Triangle& T = mesh_.tri(t);
    if (T.v[0] == kInfiniteVertex || T.v[1] == kInfiniteVertex || T.v[2] == kInfiniteVertex) {
      return {Where::outside_hull, t, 0};  // crossed a hull edge that p sees from outside
    }
    const XY* P[3] = {&mesh_.xy(T.v[0]), &mesh_.xy(T.v[1]), &mesh_.xy(T.v[2])};
    if (randomize_walk_) {
      rng_ ^= rng_ << 13;
      rng_ ^= rng_ >> 17;
      rng_ ^= rng_ << 5;
      start = static_cast<int>(rng_ % 3u);
    } else {
      start = next3(start);
    }
    TriangleId next = kNone;
    int i = start;
    for (int k = 0; k < 3; ++k, i = next3(i)) {
      const TriangleId nb = T.n[i];
      if (nb == prev && prev != kNone) {
        o[i] = 1.0;  // p is strictly on this side: we just crossed that edge towards it
        continue;
      }
      o[i] = orient2d(*P[next3(i)], *P[prev3(i)], p);
      if (o[i] < 0.0) {
        if (nb == kNone) return {Where::outside_hull, kNone, 0};  // cut mesh: blocked
        next = nb;
        break;
      }
    }
    if (next == kNone) break;
    prev = t;
    t = next;
  }
  // p lies in the closed triangle t; o[] holds its (non-negative) edge orientations.
  const int zeros = (o[0] == 0.0) + (o[1] == 0.0) + (o[2] == 0.0);
  if (zeros == 0) return {Where::inside, t, 0};
  if (zeros == 1) return {Where::on_edge, t, o[0] == 0.0 ? 0 : o[1] == 0.0 ? 1 : 2};
  // On two edge lines: p is the vertex they share, the one opposite the non-zero edge.
  return {Where::on_vertex, t, o[0] != 0.0 ? 0 : o[1] != 0.0 ? 1 : 2};
}

// Lawson flips from the new vertex p: every edge opposite p is tested against the triangle on
// its other side and flipped when p lies in its circle. Stack entries (t, i) have p == v[i] of t.
// A flip of (t, i) would push (t, 0) and then (v2, 2), which is popped at once: the inner loop
// goes on with (v2, 2) directly, so the order of the tests is that of the plain stack.
void Triangulation::legalize(VertexId p, std::size_t top) {
  const XY pp = mesh_.xy(p);
  // A local pointer (refreshed only when the buffer grows) and size keep the vector's own
  // bookkeeping out of the loop.
  std::pair<TriangleId, int>* stack = stack_.data();
  while (top != 0) {
    auto [t, i] = stack[--top];
    for (;;) {
      if (has_constraints_ && mesh_.constrained(t, i)) break;
      const TriangleId nb = mesh_.tri(t).n[i];
      if (nb == kNone) break;
      const Triangle& N = mesh_.tri(nb);
      const int j = mesh_.index_of_neighbour(nb, t);
      const VertexId q = N.v[j];
      if (q == kInfiniteVertex) break;  // across a hull edge from inside: never in conflict
      const VertexId w = N.v[next3(j)], u = N.v[prev3(j)];  // N = (q, w, u)
      bool conflict;
      if (w == kInfiniteVertex) {
        conflict = orient2d(mesh_.xy(u), mesh_.xy(q), pp) > 0.0;  // ghost (u, q, 0)
      } else if (u == kInfiniteVertex) {
        conflict = orient2d(mesh_.xy(q), mesh_.xy(w), pp) > 0.0;  // ghost (q, w, 0)
      } else {
        const XY &xq = mesh_.xy(q), &xw = mesh_.xy(w), &xu = mesh_.xy(u);
        const double in = incircle(xq, xw, xu, pp);
        conflict =
            in > 0.0 || (in == 0.0 && perturbed_ties_ && detail::perturbed_tie(xq, xw, xu, pp) > 0);
      }
      if (!conflict) break;
      const TriangleId v2 = mesh_.flip(t, i, j);
      if (top == stack_.size()) {
        stack_.resize(2 * top);
        stack = stack_.data();
      }
      stack[top++] = {t, 0};
      t = v2;
      i = 2;
    }
  }
}

InsertResult Triangulation::insert_vertex(VertexId v, TriangleId hint) {
  return insert_at(v, locate(mesh_.xy(v), hint));
}

InsertResult Triangulation::insert_at(VertexId v, const Location& loc) {
  switch (loc.where) {
    case Where::on_vertex:
      return {InsertOutcome::duplicate, mesh_.tri(loc.t).v[loc.index]};
    case Where::inside:
    case Where::outside_hull: {
      if (loc.t == kNone) return {InsertOutcome::rejected, kNone};
      const auto ts = mesh_.split_triangle(loc.t, v);
      stack_[0] = {ts[0], 2};
      stack_[1] = {ts[1], 2};
      stack_[2] = {ts[2], 2};
      legalize(v, 3);
      break;
    }
    case Where::on_edge: {
      const auto s = mesh_.split_edge(loc.t, loc.index, v);
      for (int k = 0; k < 4; ++k) stack_[k] = {s.t[k], s.p_index[k]};
      legalize(v, 4);
      break;
    }
  }
  hint_ = mesh_.vertex_triangle(v);
  return {InsertOutcome::inserted, v};
}

bool Triangulation::pending_contains(const XY& p, VertexId* found) const {
  for (VertexId v : pending_) {
    const XY& q = mesh_.xy(v);
    if (q.x == p.x && q.y == p.y) {
      *found = v;
      return true;
    }
  }
  return false;
}

void Triangulation::clear() {
  mesh_.clear();
  pending_.clear();
  segments_.clear();
  ++revision_;  // no removal plan survives
  hint_ = kNone;
  randomize_walk_ = false;
  has_constraints_ = false;
  rng_ = kRngSeed;
  live_vertices_ = 0;
  cut_ = false;
}

InsertResult Triangulation::insert(const Point3& p) {
  ++revision_;
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || cut_) return {InsertOutcome::rejected, kNone};
  if (domain_ && !domain_->contains(p.x, p.y)) return {InsertOutcome::outside_domain, kNone};
  const XY xy{p.x, p.y};
  if (mesh_.live_triangles() == 0) {
    VertexId existing;
    if (pending_contains(xy, &existing)) return {InsertOutcome::duplicate, existing};
    const VertexId v = mesh_.add_vertex(p.x, p.y, p.z, p.weight);
    ++live_vertices_;
    if (pending_.size() >= 2 && orient2d(mesh_.xy(pending_[0]), mesh_.xy(pending_[1]), xy) != 0.0) {
      raise_dimension(v);
    } else {
      mesh_.set_vertex_triangle(v, kPendingTriangle);
      pending_.push_back(v);
    }
    return {InsertOutcome::inserted, v};
  }
  const Location loc = locate(xy, hint_);
  if (loc.where == Where::on_vertex) {
    hint_ = loc.t;
    return {InsertOutcome::duplicate, mesh_.tri(loc.t).v[loc.index]};
  }
  if (loc.t == kNone) return {InsertOutcome::rejected, kNone};
  const VertexId v = mesh_.add_vertex(p.x, p.y, p.z, p.weight);
  ++live_vertices_;
  return insert_at(v, loc);
}

// The pending vertices are distinct and collinear; `off_line` is not on their line. Builds the
// first triangle and inserts the rest of the line from one end so that every insertion is a
// plain outside-the-hull case.
void Triangulation::raise_dimension(VertexId off_line) {
  std::vector<VertexId> line = std::move(pending_);
  pending_.clear();
  std::sort(line.begin(), line.end(), [&](VertexId a, VertexId b) {
    const XY &p = mesh_.xy(a), &q = mesh_.xy(b);
    return p.x < q.x || (p.x == q.x && p.y < q.y);
  });
  VertexId a = line[0], b = line[1];
  const VertexId c = off_line;
  if (orient2d(mesh_.xy(a), mesh_.xy(b), mesh_.xy(c)) < 0.0) std::swap(a, b);
  const TriangleId f = mesh_.new_triangle(a, b, c);
  const TriangleId ga = mesh_.new_triangle(c, b, kInfiniteVertex);
  const TriangleId gb = mesh_.new_triangle(a, c, kInfiniteVertex);
  const TriangleId gc = mesh_.new_triangle(b, a, kInfiniteVertex);
  mesh_.link(f, 0, ga, 2);
  mesh_.link(f, 1, gb, 2);
  mesh_.link(f, 2, gc, 2);
  mesh_.link(gc, 0, gb, 1);
  mesh_.link(gc, 1, ga, 0);
  mesh_.link(ga, 1, gb, 0);
  mesh_.set_vertex_triangle(a, f);
  mesh_.set_vertex_triangle(b, f);
  mesh_.set_vertex_triangle(c, f);
  mesh_.set_vertex_triangle(kInfiniteVertex, ga);
  hint_ = f;
  for (std::size_t k = 2; k < line.size(); ++k) {
    mesh_.set_vertex_triangle(line[k], kNone);
    insert_vertex(line[k], hint_);
  }
}

std::vector<InsertResult> Triangulation::insert_bulk(std::span<const Point3> points) {
  std::vector<InsertResult> out(points.size(), InsertResult{InsertOutcome::rejected, kNone});
  std::vector<std::uint32_t> valid;
  valid.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point3& p = points[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || cut_) continue;
    if (domain_ && !domain_->contains(p.x, p.y)) {
      out[i] = {InsertOutcome::outside_domain, kNone};
      continue;
    }
    valid.push_back(static_cast<std::uint32_t>(i));
  }
  const std::vector<std::uint32_t> order = detail::brio_hilbert_order(points, valid);
  mesh_.reserve_vertices(mesh_.vertex_slots() + order.size());
  mesh_.reserve_triangles(mesh_.triangle_slots() + 2 * order.size() + 8);
  const std::size_t first_new = mesh_.vertex_slots();
  // The input is read in a scattered order. Each chunk of it is gathered first in a tight loop
  // of independent loads (their cache and TLB misses overlap) and its results are scattered back
  // after it was inserted, so no insertion waits for a miss on the input or on `out`.
  constexpr std::size_t kChunk = 512;
  std::array<Point3, kChunk> gathered;
  std::array<InsertResult, kChunk> results;
  std::vector<std::uint32_t> origin(order.size(), kNone);  // new vertex - first_new -> input
  for (std::size_t k0 = 0; k0 < order.size(); k0 += kChunk) {
    const std::size_t m = std::min(kChunk, order.size() - k0);
    for (std::size_t k = 0; k < m; ++k) gathered[k] = points[order[k0 + k]];
    for (std::size_t k = 0; k < m; ++k) results[k] = insert(gathered[k]);
    for (std::size_t k = 0; k < m; ++k) {
      const std::uint32_t i = order[k0 + k];
      out[i] = results[k];
      if (results[k].outcome == InsertOutcome::inserted) origin[results[k].vertex - first_new] = i;
    }
  }
  // Among exact duplicates the first in input order wins, whatever the insertion order was.
  for (std::uint32_t i : valid) {
    if (out[i].outcome != InsertOutcome::duplicate) continue;
    const VertexId v = out[i].vertex;
    if (v < first_new) continue;  // a duplicate of a vertex inserted before this call
    std::uint32_t& first = origin[v - first_new];
    if (first < i) continue;
    out[first].outcome = InsertOutcome::duplicate;
    out[i].outcome = InsertOutcome::inserted;
    first = i;
    mesh_.set_z(v, points[i].z);
    mesh_.set_weight(v, points[i].weight);
  }
  return out;
}

}  // namespace tinstream::kernel
