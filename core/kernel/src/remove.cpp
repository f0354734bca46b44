// Vertex removal: the star of v is re-triangulated in a small local structure, the hole
// (removal_hole.hpp), which both removal_preview (read-only) and remove_vertex (writes it back)
// use. Expected O(degree) (the ear queue is O(degree^2), used up to degree 24).
//
// plan_removal: collect_star, find_constraint_to_rejoin, then one planner per case —
//   hull vertex                plan_hull_hole: open link chain, made convex (Graham-like scan)
//                              + ghost triangles
//   straight constraint a-v-b  plan_constraint_hole: the link splits at a and b into two open
//                              chains, each made convex against the segment a-b, which becomes
//                              one constrained edge
//   interior vertex            plan_interior_hole: closed link polygon: the Delaunay apexes
//                              (remove_vertex), degree 4 by one exact incircle test, up to degree
//                              24 ears in Devillers' order (flips only verify); larger stars, or
//                              when that order fails near a degeneracy, ears clipped in the
//                              star-shaped order
// — and flip_hole_to_delaunay (Lawson flips inside the hole only) where the planner did not
// decide the triangles exactly. write_hole / write_apex_hole / write_hole_general put the hole
// into the mesh.
#include <algorithm>
#include <array>
#include <limits>
#include <string>

#include "removal_hole.hpp"
#include "tinstream/kernel/triangulation.hpp"
#include "triangulation_detail.hpp"

namespace tinstream::kernel {

detail::RemovalScratch::RemovalScratch() noexcept = default;
detail::RemovalScratch::RemovalScratch(const RemovalScratch&) noexcept {}
detail::RemovalScratch& detail::RemovalScratch::operator=(const RemovalScratch& other) noexcept {
  if (this != &other) hole_.reset();
  return *this;
}
detail::RemovalScratch::RemovalScratch(RemovalScratch&&) noexcept = default;
detail::RemovalScratch& detail::RemovalScratch::operator=(RemovalScratch&&) noexcept = default;
detail::RemovalScratch::~RemovalScratch() = default;
detail::RemovalHole& detail::RemovalScratch::get() {
  if (!hole_) hole_ = std::make_unique<detail::RemovalHole>();
  return *hole_;
}

using detail::is_local;
using detail::kPendingTriangle;
using detail::kUnsetEdge;
using detail::local_edge;
using detail::local_index;
using detail::local_triangle;
using detail::RemovalHole;
using detail::ring_edge;
using detail::ring_index;

// The star buffers (ring, star, outer and their scratch) only grow; Hole::degree is in use.
void RemovalHole::clear() {
  degree = 0;
  ntri = 0;
  join_a = join_b = kNone;
  segment_ends.clear();
  degenerate = false;
  hull = false;
  ghost_pos = 0;
  apexes = false;
}

inline int RemovalHole::add(VertexId a, VertexId b, VertexId c, int oa, int ob, int oc) {
  if (ntri == tris.size()) grow();
  const int L = static_cast<int>(ntri++);
  tris[static_cast<std::size_t>(L)] = {a, b, c};
  adj[static_cast<std::size_t>(L)] = {oa, ob, oc};
  fixed[static_cast<std::size_t>(L)] = 0;
  auto back = [&](int o, int code) {
    if (is_local(o)) adj[local_triangle(o)][local_index(o)] = code;
  };
  back(oa, local_edge(L, 0));
  back(ob, local_edge(L, 1));
  back(oc, local_edge(L, 2));
  return L;
}

void RemovalHole::grow_star(std::size_t n) {
  n = std::max<std::size_t>(n, 2 * star.size());
  for (auto* b : {&ring, &star, &outer, &star_back, &ring_back, &outer_back}) b->resize(n);
}

void RemovalHole::grow() {
  const std::size_t n = std::max<std::size_t>(16, 2 * tris.size());
  tris.resize(n);
  adj.resize(n);
  fixed.resize(n);
}

namespace {

// Interior vertices of at most this degree are re-triangulated with the ear queue (quadratic in
// the degree); larger stars go to the plain ear clipping plus flips.
constexpr std::size_t kEarQueueMax = 24;

}  // namespace

void RemovalHole::convexify(const Mesh& mesh) {
  RemovalHole& hole = *this;
  auto& st = hole.stack;
  st.clear();
  for (int i = 0; i < static_cast<int>(chain.size()); ++i) {
    while (st.size() >= 2) {
      const auto a = static_cast<std::size_t>(st[st.size() - 2]);
      const auto b = static_cast<std::size_t>(st.back());
      const auto c = static_cast<std::size_t>(i);
      if (orient2d(mesh.xy(chain[a]), mesh.xy(chain[b]), mesh.xy(chain[c])) <= 0.0) break;
      // Ear (a, b, i): edges opposite a = (b, i), opposite b = (i, a) new, opposite i = (a, b).
      const int L = hole.add(chain[a], chain[b], chain[c], owner[b], kUnsetEdge, owner[a]);
      owner[a] = local_edge(L, 1);
      st.pop_back();
    }
    st.push_back(i);
  }
}

void RemovalHole::start_ring() {
  const std::size_t k = degree;
  nxt.resize(k);
  prv.resize(k);
  owner.resize(k);
  for (std::size_t i = 0; i < k; ++i) {
    nxt[i] = static_cast<int>(i + 1 == k ? 0 : i + 1);
    prv[i] = static_cast<int>(i == 0 ? k - 1 : i - 1);
    owner[i] = ring_edge(i);
  }
}

void RemovalHole::clip_ear(int c) {
  const auto uc = static_cast<std::size_t>(c);
  const auto p = static_cast<std::size_t>(prv[uc]), n = static_cast<std::size_t>(nxt[uc]);
  // Edges opposite p = (c, n): ring owner of c; opposite c = (n, p): new; opposite n = (p, c).
  const int L = add(ring[p], ring[uc], ring[n], owner[uc], kUnsetEdge, owner[p]);
  owner[p] = local_edge(L, 1);
  nxt[p] = static_cast<int>(n);
  prv[n] = static_cast<int>(p);
}

void RemovalHole::close_ring(int c) {
  const auto uc = static_cast<std::size_t>(c);
  const auto p = static_cast<std::size_t>(prv[uc]), n = static_cast<std::size_t>(nxt[uc]);
  add(ring[p], ring[uc], ring[n], owner[uc], owner[n], owner[p]);
}

// Degree 4 (a quadrilateral hole r0 r1 r2 r3): the diagonal r0-r2 lies inside when the corners
// at r1 and r3 are strictly convex, r1-r3 when those at r2 and r0 are; when both do, one exact
// incircle test picks the Delaunay one (on a tie either is). Returns false, leaving the hole
// untouched, only when neither diagonal is valid (cannot happen for a valid star).
bool RemovalHole::triangulate_quad(const Mesh& mesh) {
  const XY &r0 = mesh.xy(ring[0]), &r1 = mesh.xy(ring[1]), &r2 = mesh.xy(ring[2]),
           &r3 = mesh.xy(ring[3]);
  const bool d02 = orient2d(r0, r1, r2) > 0.0 && orient2d(r2, r3, r0) > 0.0;
  const bool d13 = orient2d(r1, r2, r3) > 0.0 && orient2d(r3, r0, r1) > 0.0;
  if (!d02 && !d13) return false;
  if (d02 && !(d13 && incircle(r0, r1, r2, r3) > 0.0)) {
    clip_ear(1);  // (r0, r1, r2), then (r0, r2, r3)
    close_ring(2);
  } else {
    clip_ear(2);  // (r1, r2, r3), then (r1, r3, r0)
    close_ring(3);
  }
  return true;
}

// Devillers' ear queue ("On deletion in Delaunay triangulations", 2002): of all ears of the link
// polygon, the one whose circumcircle has the largest power with respect to v is a Delaunay
// triangle of the hole, so clipping ears in that order needs no flips afterwards. The powers are
// compared in plain floating point (power = -incircle(ear, v) / orient(ear)); every chosen ear is
// then checked with the exact predicates like any ear, and the Lawson pass of plan_removal still
// verifies every new diagonal exactly, so a wrong choice near a tie costs a flip, never
// correctness. Returns false (hole to be rebuilt by the plain ear clipping) when the chosen ear is
// not a valid ear, which happens only near degeneracies.
//
// The ring is copied once into small arrays relative to v (coordinates, lifts x^2 + y^2, and the
// cross product of each current polygon edge, which the incircle determinant of an ear shares
// with its neighbours), so an ear key is a handful of flops and no division; clipped corners get
// a key that never wins, and the argmin scans all k slots (no list chasing, no shifting).
bool RemovalHole::clip_delaunay_ears(const Mesh& mesh, const XY& pv) {
  const std::size_t k = degree;
  if (k < 3 || k > kEarQueueMax) return false;
  std::array<double, kEarQueueMax> x, y, lift, edge, num, den;
  std::array<int, kEarQueueMax> nx, pr, own;
  // nx[m] = m + 1, pr[m] = m - 1 (cyclic), own[m] = ring edge m: copied whole, then closed.
  static constexpr auto kTables = [] {
    std::array<std::array<int, kEarQueueMax>, 3> t{};
    for (std::size_t m = 0; m < kEarQueueMax; ++m) {
      t[0][m] = static_cast<int>(m) + 1;
      t[1][m] = static_cast<int>(m) - 1;
      t[2][m] = ring_edge(m);
    }
    return t;
  }();
  nx = kTables[0];
  pr = kTables[1];
  own = kTables[2];
  nx[k - 1] = 0;
  pr[0] = static_cast<int>(k - 1);
  for (std::size_t m = 0; m < k; ++m) {
    const XY& p = mesh.xy(ring[m]);
    x[m] = p.x - pv.x;
    y[m] = p.y - pv.y;
    lift[m] = x[m] * x[m] + y[m] * y[m];
  }
  auto cross = [&](std::size_t a, std::size_t b) { return x[a] * y[b] - x[b] * y[a]; };
  for (std::size_t m = 0; m < k; ++m) edge[m] = cross(m, static_cast<std::size_t>(nx[m]));
  // Ear (p, m, n): key inc / orient with incircle(p, m, n, v) expanded along the lifts
  // (edge[p] = cross(p, m), edge[m] = cross(m, n)), kept as a fraction: orient > 0 for an ear,
  // 0 for a reflex or flat corner (approximately) or a clipped one, which never compares smaller.
  auto evaluate = [&](std::size_t m) {
    const auto p = static_cast<std::size_t>(pr[m]), n = static_cast<std::size_t>(nx[m]);
    const double orient = (x[p] - x[n]) * (y[m] - y[n]) - (y[p] - y[n]) * (x[m] - x[n]);
    const double inc = lift[p] * edge[m] - lift[m] * cross(p, n) + lift[n] * edge[p];
    const bool ear = orient > 0.0;  // false for NaN too
    num[m] = ear ? inc : 1.0;
    den[m] = ear ? orient : 0.0;
  };
  for (std::size_t m = 0; m < k; ++m) evaluate(m);
  std::size_t c = 0;
  for (std::size_t left = k; left > 3; --left) {
    double best_num = num[0], best_den = den[0];
    c = 0;
    for (std::size_t m = 1; m < k; ++m) {  // num[m] / den[m] < best_num / best_den
      const bool better = num[m] * best_den < best_num * den[m];
      c = better ? m : c;
      best_num = better ? num[m] : best_num;
      best_den = better ? den[m] : best_den;
    }
    if (!(best_den > 0.0)) return false;
    const auto p = static_cast<std::size_t>(pr[c]), n = static_cast<std::size_t>(nx[c]);
    const XY &a = mesh.xy(ring[p]), &b = mesh.xy(ring[c]), &d = mesh.xy(ring[n]);
    if (orient2d(a, b, d) <= 0.0 || orient2d(a, d, pv) <= 0.0) return false;
    // Edges opposite p = (c, n): owner of c; opposite c = (n, p): new; opposite n = (p, c).
    const int L = add(ring[p], ring[c], ring[n], own[c], kUnsetEdge, own[p]);
    own[p] = local_edge(L, 1);
    nx[p] = static_cast<int>(n);
    pr[n] = static_cast<int>(p);
    edge[p] = cross(p, n);
    num[c] = 1.0;
    den[c] = 0.0;
    evaluate(p);  // the ears at p and n changed
    evaluate(n);
    c = p;
  }
  const auto p = static_cast<std::size_t>(pr[c]), n = static_cast<std::size_t>(nx[c]);
  add(ring[p], ring[c], ring[n], own[c], own[n], own[p]);
  return true;
}

// The hole's Delaunay triangulation built from ring edge 0 inwards: the triangle on the inner
// side of a known edge a->b (a ring edge or a diagonal found before) is a Delaunay triangle of
// the ring's points, so its apex is the candidate c strictly left of a->b whose circle through a
// and b contains no other such candidate (every triangle of the hole has an empty circle among
// S \ {v}, which includes the ring). The candidates are the polygon vertices between b and a;
// each is compared with the best so far by one exact incircle test. When no test is a tie
// (incircle == 0), every apex is the unique minimum, so this hole is the only constrained
// Delaunay triangulation of the star polygon, the one any other exact method finds; on a tie
// the hole is left for the ear queue, which decides ties as before. Returns false then.
bool RemovalHole::delaunay_apexes(const Mesh& mesh) {
  const std::size_t k = degree;
  constexpr std::size_t kMax = kApexMax;
  if (k > kMax) return false;
  while (tris.size() < k) grow();
  // Ring positions 0..k, position k being ring[0] again: a sub-polygon is a range b..a of
  // positions with 1 <= b < a <= k, closed by the edge a -> b.
  std::array<XY, kMax + 1> P;
  for (std::size_t m = 0; m < k; ++m) P[m] = mesh.xy(ring[m]);
  P[k] = P[0];
  struct Item {
    int a, b, owner;  // base edge a -> b (ring positions), the code of its other side
  };
  std::array<Item, kMax> todo;
  std::size_t ntodo = 0;
  todo[ntodo++] = {static_cast<int>(k), 1, ring_edge(0)};
  auto id = [&](int pos) {
    return ring[static_cast<std::size_t>(pos) == k ? 0 : static_cast<std::size_t>(pos)];
  };
  while (ntodo > 0) {
    const Item it = todo[--ntodo];
    const XY &pa = P[static_cast<std::size_t>(it.a)], &pb = P[static_cast<std::size_t>(it.b)];
    int best = it.b + 1;
    if (best + 1 < it.a) {  // more than one candidate
      // The first candidate strictly left of a -> b, then incircle tests alone: a candidate on
      // the right or on the line never enters the circle through a, b and a left candidate
      // whose circle is at least the apex's, and the apex's circle is empty.
      while (best < it.a && orient2d(pa, pb, P[static_cast<std::size_t>(best)]) <= 0.0) ++best;
      if (best == it.a) return false;
      for (int c = best + 1; c < it.a; ++c) {
        const double s =
            incircle(pa, pb, P[static_cast<std::size_t>(best)], P[static_cast<std::size_t>(c)]);
        if (s == 0.0) return false;
        if (s > 0.0) best = c;
      }
    }
    // Triangle (a, b, best): edge 0 = (b, best), edge 1 = (best, a), edge 2 = the base.
    const auto L = static_cast<int>(ntri++);
    const auto uL = static_cast<std::size_t>(L);
    tris[uL] = {id(it.a), id(it.b), id(best)};
    adj[uL] = {best == it.b + 1 ? ring_edge(static_cast<std::size_t>(it.b)) : kUnsetEdge,
               best + 1 == it.a ? ring_edge(static_cast<std::size_t>(best)) : kUnsetEdge, it.owner};
    fixed[uL] = 0;
    if (is_local(it.owner)) adj[local_triangle(it.owner)][local_index(it.owner)] = local_edge(L, 2);
    if (best != it.b + 1) {
      todo[ntodo++] = {best, it.b, local_edge(L, 0)};
    } else {
      ring_tri[static_cast<std::size_t>(it.b)] = local_edge(L, 0);
    }
    if (best + 1 != it.a) {
      todo[ntodo++] = {it.a, best, local_edge(L, 1)};
    } else {
      ring_tri[static_cast<std::size_t>(best)] = local_edge(L, 1);
    }
  }
  ring_tri[0] = local_edge(0, 2);  // the first triangle's base
  apexes = true;
  return true;
}

// The Lawson flip of the diagonal across edge i of new triangle L: T = (p, u, w) and across it
// S = (q, w, u) become T = (p, u, q), S = (q, w, p), as Mesh::flip does; the links and the
// constrained flags of the four outer edges follow.
int RemovalHole::flip(int L, int i) {
  const auto uL = static_cast<std::size_t>(L);
  const int o = adj[uL][static_cast<std::size_t>(i)];
  const int U = static_cast<int>(local_triangle(o)), j = static_cast<int>(local_index(o));
  const auto uU = static_cast<std::size_t>(U);
  const VertexTriple T = tris[uL], S = tris[uU];
  const VertexId p = T[static_cast<std::size_t>(i)], u = T[static_cast<std::size_t>(next3(i))],
                 w = T[static_cast<std::size_t>(prev3(i))], q = S[static_cast<std::size_t>(j)];
  const int A = adj[uL][static_cast<std::size_t>(next3(i))],
            B = adj[uL][static_cast<std::size_t>(prev3(i))];
  const int C = adj[uU][static_cast<std::size_t>(next3(j))],
            D = adj[uU][static_cast<std::size_t>(prev3(j))];
  const bool fA = (fixed[uL] >> next3(i)) & 1u, fB = (fixed[uL] >> prev3(i)) & 1u;
  const bool fC = (fixed[uU] >> next3(j)) & 1u, fD = (fixed[uU] >> prev3(j)) & 1u;
  tris[uL] = {p, u, q};
  tris[uU] = {q, w, p};
  adj[uL] = {C, local_edge(U, 1), B};
  adj[uU] = {A, local_edge(L, 1), D};
  fixed[uL] = static_cast<std::uint8_t>((fC ? 1u : 0u) | (fB ? 4u : 0u));
  fixed[uU] = static_cast<std::uint8_t>((fA ? 1u : 0u) | (fD ? 4u : 0u));
  auto relink = [&](int code, int target) {
    if (is_local(code)) adj[local_triangle(code)][local_index(code)] = target;
  };
  relink(C, local_edge(L, 0));
  relink(B, local_edge(L, 2));
  relink(A, local_edge(U, 0));
  relink(D, local_edge(U, 2));
  return U;
}

namespace {

std::string vertex_name(VertexId v) { return "vertex " + std::to_string(v); }

// Collects the star of v into hole (degree, ring, star, outer, hull, ghost_pos), walking around v
// in both directions at once: each step is a dependent load, usually a cache miss when removals
// come in random order; two independent chains let the misses of one overlap with the other's.
// Each star triangle is read once: its ring vertex and outer neighbour are recorded on the way.
// Requires: v a live vertex of a two-dimensional, uncut mesh; hole cleared.
void collect_star(const Mesh& mesh, VertexId v, RemovalHole& hole) {
  if (hole.star.size() < 16) hole.grow_star(16);
  TriangleId* star = hole.star.data();
  VertexId* ring = hole.ring.data();
  TriangleId* outer = hole.outer.data();
  TriangleId* back = hole.star_back.data();  // clockwise from t0's predecessor
  VertexId* ring_back = hole.ring_back.data();
  TriangleId* outer_back = hole.outer_back.data();
  std::size_t nf = 0, nb = 0;
  const TriangleId t0 = mesh.vertex_triangle(v);
  TriangleId fwd = t0;
  int jf = mesh.index_of(t0, v);
  TriangleId bwd = mesh.tri(t0).n[prev3(jf)];
  for (;;) {
    if (nf + nb + 2 > hole.star.size()) {
      hole.grow_star(nf + nb + 2);
      star = hole.star.data();
      ring = hole.ring.data();
      outer = hole.outer.data();
      back = hole.star_back.data();
      ring_back = hole.ring_back.data();
      outer_back = hole.outer_back.data();
    }
    const Triangle& F = mesh.tri(fwd);
    star[nf] = fwd;
    ring[nf] = F.v[next3(jf)];
    outer[nf] = F.n[jf];
    ++nf;
    if (fwd == bwd) break;
    const int jb = mesh.index_of(bwd, v);
    const Triangle& B = mesh.tri(bwd);
    back[nb] = bwd;
    ring_back[nb] = B.v[next3(jb)];
    outer_back[nb] = B.n[jb];
    ++nb;
    const TriangleId fnext = F.n[next3(jf)];
    const TriangleId bnext = B.n[prev3(jb)];
    if (fnext == bwd) break;
    fwd = fnext;
    bwd = bnext;
    jf = mesh.index_of(fwd, v);
  }
  for (std::size_t i = 0; i < nb; ++i) {
    star[nf + i] = back[nb - 1 - i];
    ring[nf + i] = ring_back[nb - 1 - i];
    outer[nf + i] = outer_back[nb - 1 - i];
  }
  const std::size_t k = nf + nb;
  hole.degree = k;
  for (std::size_t pos = 0; pos < k; ++pos) {
    // The outer triangles are written only by remove_vertex and the ring coordinates are read
    // by the planners: start all their (independent) cache misses now. (Issued during the walk
    // instead, they delayed the walk's own misses: uniform 1e6 removal 700 -> 860 ms.)
    if (outer[pos] != kNone) mesh.prefetch_triangle(outer[pos]);
    mesh.prefetch_vertex(ring[pos]);
    if (ring[pos] == kInfiniteVertex) {
      hole.hull = true;  // the ghost vertex is at most once in the link
      hole.ghost_pos = pos;
    }
  }
}

// A segment record ending at v is re-ended at a join vertex (remove_vertex), which keeps it a
// chain only when its other end lies on the line join_a - join_b. A constraint may end at v and
// still leave it along one of the spokes, routed through a vertex within rounding of its line
// (kernel_fuzzer, 2026-11-28: constraint 9-8 routed 9-7-8, then 6-7 through 9; removing 9 made
// the record 6-8, no chain): then v is the end of a bent constraint, and cannot go.
// The one scan of the records also lists their ends at v in hole.segment_ends, for remove_vertex.
Status collect_segment_ends(const Mesh& mesh, const std::vector<std::array<VertexId, 2>>& segments,
                            VertexId v, RemovalHole& hole) {
  if (hole.join_a == kNone) return {};
  const XY& a = mesh.xy(hole.join_a);
  const XY& b = mesh.xy(hole.join_b);
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const auto& seg = segments[i];
    if (seg[0] != v && seg[1] != v) continue;
    const std::size_t end = seg[0] == v ? 0 : 1;
    hole.segment_ends.push_back(2 * i + end);
    const VertexId other = seg[1 - end];
    if (orient2d(a, b, mesh.xy(other)) != 0.0) {
      return invalid_argument(vertex_name(v) + " ends constraint segment " +
                              std::to_string(seg[0]) + "-" + std::to_string(seg[1]) +
                              ", which is not on the line of the constraint through it");
    }
  }
  return {};
}

// The constrained edges at v: none, or exactly two exactly collinear through v (v splits a
// straight constraint), whose far ends become hole.join_a and hole.join_b. Anything else is an
// error naming v.
Status find_constraint_to_rejoin(const Mesh& mesh, VertexId v, RemovalHole& hole) {
  VertexId spokes[2] = {kNone, kNone};
  std::size_t constrained = 0;
  for (std::size_t pos = 0; pos < hole.degree; ++pos) {
    const TriangleId t = hole.star[pos];
    if (mesh.constrained(t, prev3(mesh.index_of(t, v)))) {
      if (constrained < 2) spokes[constrained] = hole.ring[pos];
      ++constrained;
    }
  }
  if (constrained == 0) return {};
  if (constrained != 2 || orient2d(mesh.xy(spokes[0]), mesh.xy(v), mesh.xy(spokes[1])) != 0.0) {
    return invalid_argument(
        vertex_name(v) + " is an end or a corner of constrained edges (" +
        std::to_string(constrained) +
        " incident); only a vertex splitting a straight constraint can be removed");
  }
  hole.join_a = spokes[0];
  hole.join_b = spokes[1];
  return {};
}

// Requires: hole.hull, and every finite triangle in v's star. True when the link's finite
// vertices are collinear: v was the only vertex off their line, nothing two-dimensional remains.
bool link_is_collinear(const Mesh& mesh, const RemovalHole& hole) {
  const std::size_t k = hole.degree;
  const XY& first = mesh.xy(hole.ring[(hole.ghost_pos + 1) % k]);
  const XY& last = mesh.xy(hole.ring[(hole.ghost_pos + k - 1) % k]);
  for (std::size_t r = 0; r < k; ++r) {
    if (hole.ring[r] != kInfiniteVertex && orient2d(first, last, mesh.xy(hole.ring[r])) != 0.0) {
      return false;
    }
  }
  return true;
}

// Planner for a hull vertex: the link is an open chain from ring[ghost_pos + 1] around to
// ring[ghost_pos - 1], made convex (Graham-like scan), with ghost triangles (c_j, c_j+1, 0)
// along the new hull. A straight constraint through a hull vertex lies on the hull line; the
// new hull edge join_a-join_b is marked constrained by remove_vertex.
void plan_hull_hole(const Mesh& mesh, RemovalHole& hole) {
  const std::size_t k = hole.degree, ghost = hole.ghost_pos;
  auto& chain = hole.chain;
  auto& owner = hole.owner;
  chain.clear();
  owner.clear();
  for (std::size_t s = 1; s < k; ++s) {
    const std::size_t r = (ghost + s) % k;
    chain.push_back(hole.ring[r]);
    owner.push_back(ring_edge(r));
  }
  hole.convexify(mesh);
  const auto& hull = hole.stack;
  int prev_ghost = ring_edge(ghost);  // edge (0, chain[0])
  for (std::size_t j = 0; j + 1 < hull.size(); ++j) {
    const auto a = static_cast<std::size_t>(hull[j]), b = static_cast<std::size_t>(hull[j + 1]);
    const int L = hole.add(chain[a], chain[b], kInfiniteVertex, kUnsetEdge, prev_ghost, owner[a]);
    prev_ghost = local_edge(L, 0);
  }
  // The last ghost's edge (c_r, 0) is the ring edge ending at the ghost vertex.
  hole.adj[local_triangle(prev_ghost)][0] = ring_edge((ghost + k - 1) % k);
}

// Planner for a vertex splitting a straight constraint join_a - v - join_b: the link splits at
// join_a and join_b into two open chains, each made convex against the segment, which becomes
// one constrained edge shared by the two sides.
Status plan_constraint_hole(const Mesh& mesh, VertexId v, RemovalHole& hole) {
  const std::size_t k = hole.degree;
  const VertexId* ring = hole.ring.data();
  const auto ia = static_cast<std::size_t>(std::find(ring, ring + k, hole.join_a) - ring);
  const auto ib = static_cast<std::size_t>(std::find(ring, ring + k, hole.join_b) - ring);
  int segment_side[2];  // the edge code of the segment on each side
  for (int side = 0; side < 2; ++side) {
    const std::size_t from = side == 0 ? ia : ib, to = side == 0 ? ib : ia;
    auto& chain = hole.chain;
    auto& owner = hole.owner;
    chain.clear();
    owner.clear();
    for (std::size_t r = from;; r = (r + 1) % k) {
      chain.push_back(ring[r]);
      owner.push_back(ring_edge(r));
      if (r == to) break;
    }
    hole.convexify(mesh);
    const auto& rest = hole.stack;
    if (rest.size() != 2) {
      return Error(ErrorCode::internal, vertex_name(v) + ": re-joining the constraint failed");
    }
    segment_side[side] = owner[static_cast<std::size_t>(rest[0])];
  }
  if (!is_local(segment_side[0]) || !is_local(segment_side[1])) {
    return Error(ErrorCode::internal, vertex_name(v) + ": degenerate star around a constraint");
  }
  for (int side = 0; side < 2; ++side) {
    const int code = segment_side[side];
    hole.adj[local_triangle(code)][local_index(code)] = segment_side[1 - side];
    hole.fixed[local_triangle(code)] |= static_cast<std::uint8_t>(1u << local_index(code));
  }
  return {};
}

// What an interior hole still needs after its planner.
enum class InteriorFill : std::uint8_t {
  final,             // chosen exactly (degree 4, or the Delaunay apexes): nothing to flip
  verify_diagonals,  // from Devillers' ear queue: the diagonals are checked, flipped if needed
  flip_all,          // from the plain ear clipping: Lawson flips over every diagonal
};

// Plain ear clipping of the closed, star-shaped link polygon: an ear (p, c, n) with a convex
// corner at c and v strictly left of p->n lies inside the two star triangles at c, so it
// contains no other vertex and the rest stays star-shaped around v. Only when v lies on every
// candidate diagonal (k = 4, a "square") is an ear with v on it taken.
Status clip_ears_in_star_order(const Mesh& mesh, VertexId v, const XY& pv, RemovalHole& hole) {
  hole.ntri = 0;
  hole.start_ring();
  const auto& nxt = hole.nxt;
  const auto& prv = hole.prv;
  std::size_t left = hole.degree;
  int c = 0;
  int misses = 0;
  bool relaxed = false;
  while (left > 3) {
    const int p = prv[static_cast<std::size_t>(c)], n = nxt[static_cast<std::size_t>(c)];
    const XY &a = mesh.xy(hole.ring[static_cast<std::size_t>(p)]),
             &b = mesh.xy(hole.ring[static_cast<std::size_t>(c)]),
             &d = mesh.xy(hole.ring[static_cast<std::size_t>(n)]);
    const double side = orient2d(a, d, pv);
    if (orient2d(a, b, d) > 0.0 && (side > 0.0 || (relaxed && side == 0.0))) {
      hole.clip_ear(c);
      --left;
      c = p;
      misses = 0;
      relaxed = false;
      continue;
    }
    c = n;
    if (++misses > static_cast<int>(left)) {
      if (relaxed)
        return Error(ErrorCode::internal, vertex_name(v) + ": no ear in its star polygon");
      relaxed = true;
      misses = 0;
    }
  }
  hole.close_ring(c);
  return {};
}

// Planner for an interior vertex (closed link polygon), cheapest exact method first: with
// any_order (remove_vertex; a preview must decide ties as the ear queue does) the Delaunay
// apexes; degree 4 by one exact incircle test; up to degree kEarQueueMax ears in Devillers'
// order; otherwise, or when that order fails near a degeneracy, ears in the star-shaped order.
Result<InteriorFill> plan_interior_hole(const Mesh& mesh, VertexId v, RemovalHole& hole,
                                        bool any_order) {
  const std::size_t k = hole.degree;
  const XY pv = mesh.xy(v);
  if (any_order && k > 4) {
    if (hole.delaunay_apexes(mesh)) return InteriorFill::final;
    hole.ntri = 0;
  }
  if (k == 4) {
    hole.start_ring();
    if (hole.triangulate_quad(mesh)) return InteriorFill::final;
  }
  if (k <= kEarQueueMax && hole.clip_delaunay_ears(mesh, pv)) {
    return InteriorFill::verify_diagonals;  // every ear was checked exactly
  }
  if (Status s = clip_ears_in_star_order(mesh, v, pv, hole); !s) return s.error();
  return InteriorFill::flip_all;
}

// True when every diagonal of an ear-queue hole passes the exact empty-circle test. Ear L's new
// edge (index 1) is the diagonal shared with a later triangle; the last triangle adds none. The
// hole is interior, so no diagonal is fixed or touches the ghost vertex.
bool ear_diagonals_delaunay(const Mesh& mesh, const RemovalHole& hole) {
  for (std::size_t L = 0; L + 1 < hole.ntri; ++L) {
    const int o = hole.adj[L][1];
    const VertexTriple& T = hole.tris[L];
    const VertexId q = hole.tris[local_triangle(o)][local_index(o)];
    if (incircle(mesh.xy(T[0]), mesh.xy(T[1]), mesh.xy(T[2]), mesh.xy(q)) > 0.0) return false;
  }
  return true;
}

// Lawson flips inside the hole until every unfixed diagonal between two finite new triangles is
// Delaunay (exact incircle); edges to the outer triangles are never flipped. only_ear_diagonals:
// start from the ear queue's diagonals (one per ear), else from every diagonal once.
Status flip_hole_to_delaunay(const Mesh& mesh, VertexId v, RemovalHole& hole,
                             bool only_ear_diagonals) {
  auto& st = hole.flips;
  st.clear();
  if (only_ear_diagonals) {
    for (std::size_t L = 0; L + 1 < hole.ntri; ++L) st.emplace_back(static_cast<int>(L), 1);
  } else {
    for (std::size_t L = 0; L < hole.ntri; ++L) {
      for (int i = 0; i < 3; ++i) {  // each diagonal once, from its lower-numbered side
        const int o = hole.adj[L][static_cast<std::size_t>(i)];
        if (is_local(o) && local_triangle(o) > L) st.emplace_back(static_cast<int>(L), i);
      }
    }
  }
  auto finite = [&](std::size_t L) {
    if (!hole.hull) return true;
    const auto& tr = hole.tris[L];
    return tr[0] != kInfiniteVertex && tr[1] != kInfiniteVertex && tr[2] != kInfiniteVertex;
  };
  std::size_t guard = 0;
  while (!st.empty()) {
    const auto [L, i] = st.back();
    st.pop_back();
    const auto uL = static_cast<std::size_t>(L);
    const int o = hole.adj[uL][static_cast<std::size_t>(i)];
    if (!is_local(o) || ((hole.fixed[uL] >> i) & 1u) || !finite(uL) || !finite(local_triangle(o)))
      continue;
    const VertexTriple& T = hole.tris[uL];
    if (incircle(mesh.xy(T[0]), mesh.xy(T[1]), mesh.xy(T[2]),
                 mesh.xy(hole.tris[local_triangle(o)][local_index(o)])) <= 0.0)
      continue;
    if (++guard > 64 * hole.ntri * hole.ntri + 64)
      return Error(ErrorCode::internal, vertex_name(v) + ": flips do not converge");
    const int U = hole.flip(L, i);
    st.emplace_back(L, 0);
    st.emplace_back(L, 2);
    st.emplace_back(U, 0);
    st.emplace_back(U, 2);
  }
  return {};
}

}  // namespace

// Plans the removal of v into hole: collects the star, checks the constraints at v, and lets the
// planner of its case fill the hole (hull vertex, straight constraint, interior vertex), then
// restores the Delaunay property inside the hole where the planner has not decided it exactly.
// Errors: a cut mesh, v not live, v an end or corner of constraints (all invalid input), or an
// internal failure (named, never expected).
Status Triangulation::plan_removal(VertexId v, RemovalHole& hole, bool any_order) const {
  if (cut_) return unsupported(vertex_name(v) + ": the mesh was cut, it no longer accepts edits");
  // v's coordinates are read only after the star walk (a chain of misses): load them meanwhile.
  if (v < mesh_.vertex_slots()) __builtin_prefetch(&mesh_.xy(v));
  if (!is_vertex(v) || mesh_.vertex_triangle(v) == kPendingTriangle) {
    return invalid_argument(vertex_name(v) + ": not a live vertex of the triangulation");
  }
  hole.clear();
  collect_star(mesh_, v, hole);
  if (has_constraints_) {
    if (Status s = find_constraint_to_rejoin(mesh_, v, hole); !s) return s;
    if (Status s = collect_segment_ends(mesh_, segments_, v, hole); !s) return s;
  }
  // Every finite triangle touches v: the others may all lie on one line.
  if (hole.hull && hole.degree - 2 == num_finite_triangles() && link_is_collinear(mesh_, hole)) {
    hole.degenerate = true;
    return {};
  }
  if (hole.hull) {
    plan_hull_hole(mesh_, hole);
    return flip_hole_to_delaunay(mesh_, v, hole, false);
  }
  if (hole.join_a != kNone) {
    if (Status s = plan_constraint_hole(mesh_, v, hole); !s) return s;
    return flip_hole_to_delaunay(mesh_, v, hole, false);
  }
  auto fill = plan_interior_hole(mesh_, v, hole, any_order);
  if (!fill) return fill.error();
  switch (*fill) {
    case InteriorFill::final:
      return {};
    case InteriorFill::verify_diagonals:
      if (ear_diagonals_delaunay(mesh_, hole)) return {};  // the usual outcome
      return flip_hole_to_delaunay(mesh_, v, hole, true);
    case InteriorFill::flip_all:
      break;
  }
  return flip_hole_to_delaunay(mesh_, v, hole, false);
}

Result<std::vector<VertexTriple>> Triangulation::removal_preview(VertexId v) const {
  RemovalHole& hole = removal_.get();
  hole.planned_vertex = kNone;  // the hole is overwritten below, even when planning fails
  // A vertex kept while the set is not yet triangulated (dimension < 2): remove_vertex drops it,
  // and no triangle replaces it (found by kernel_fuzzer: the preview refused what removal did).
  if (!cut_ && v != kInfiniteVertex && v < mesh_.vertex_slots() &&
      mesh_.vertex_triangle(v) == kPendingTriangle) {
    return std::vector<VertexTriple>{};
  }
  if (Status s = plan_removal(v, hole); !s) return s.error();
  hole.planned_vertex = v;  // remove_vertex(v) right after this preview reuses the plan
  hole.planned_revision = revision_;
  std::vector<VertexTriple> out;
  if (hole.degenerate) return out;
  for (std::size_t L = 0; L < hole.ntri; ++L) {
    const VertexTriple& t = hole.tris[L];
    if (t[0] != kInfiniteVertex && t[1] != kInfiniteVertex && t[2] != kInfiniteVertex)
      out.push_back(t);
  }
  return out;
}

void Triangulation::demote_to_collinear(VertexId removed) {
  std::vector<VertexId> keep;
  for (VertexId v = 1; v < mesh_.vertex_slots(); ++v) {
    if (v != removed && mesh_.vertex_triangle(v) != kNone) keep.push_back(v);
  }
  mesh_.clear_triangles();
  pending_ = keep;
  for (VertexId v : keep) mesh_.set_vertex_triangle(v, kPendingTriangle);
  segments_.clear();
  hint_ = kNone;
}

// Writes the planned hole into the mesh, constrained edges included: the new triangles take the
// star's slots in order (the two left over are freed) and every outer triangle is re-linked.
// Returns the id of the first new triangle.
TriangleId Triangulation::write_hole_general(RemovalHole& hole) {
  // Where each outer triangle refers back to the star, read before anything is rewritten (an
  // outer triangle may border two ring edges, and the star's slots are reused below).
  hole.outer_index.resize(hole.degree);
  for (std::size_t r = 0; r < hole.degree; ++r) {
    const TriangleId out = hole.outer[r];
    hole.outer_index[r] = out == kNone ? 0 : mesh_.index_of_neighbour(out, hole.star[r]);
  }
  // Re-use the star's triangle slots for the new triangles and free the two left over.
  const std::size_t nnew = hole.ntri;
  const std::vector<TriangleId>& id = hole.star;
  for (std::size_t L = nnew; L < hole.degree; ++L) mesh_.free_triangle(hole.star[L]);
  for (std::size_t L = 0; L < nnew; ++L) {
    const auto& t = hole.tris[L];
    mesh_.set_vertices(id[L], t[0], t[1], t[2]);
  }
  for (std::size_t L = 0; L < nnew; ++L) {
    const auto& t = hole.tris[L];
    for (int i = 0; i < 3; ++i) {
      const int o = hole.adj[L][static_cast<std::size_t>(i)];
      if (is_local(o)) {
        mesh_.set_neighbour(id[L], i, id[local_triangle(o)]);
        if (has_constraints_) mesh_.set_constrained(id[L], i, (hole.fixed[L] >> i) & 1u);
      } else {
        const std::size_t r = ring_index(o);
        const TriangleId out = hole.outer[r];
        mesh_.link(id[L], i, out, hole.outer_index[r]);
        // Ring edge r starts at ring[r] = t[next3(i)]; every ring vertex starts one ring edge.
        mesh_.set_vertex_triangle(t[static_cast<std::size_t>(next3(i))], id[L]);
        if (has_constraints_) {
          mesh_.set_constrained(id[L], i,
                                out != kNone && mesh_.constrained(out, hole.outer_index[r]));
        }
      }
    }
  }
  return hole.star[0];
}

// Same without constraints, with fewer writes: each new triangle that has a ring edge takes the
// slot of the star triangle across that edge, so the outer triangle there still points at the
// right id and is neither read nor written; only the other ring edges (two per hole, plus one
// per new triangle without a ring edge) re-link their outer triangle. Stars of more than 64
// triangles take the general path.
TriangleId Triangulation::write_hole(RemovalHole& hole) {
  const std::size_t nnew = hole.ntri, k = hole.degree;
  constexpr std::size_t kMax = 64;
  if (k > kMax || nnew > k) return write_hole_general(hole);
  const TriangleId* star = hole.star.data();
  const TriangleId* outer = hole.outer.data();
  const std::array<int, 3>* adj = hole.adj.data();
  const VertexTriple* tris = hole.tris.data();
  std::array<TriangleId, kMax> slot;  // mesh id of new triangle L
  std::array<int, kMax> kept;         // its edge whose outer link stays, or -1
  std::array<int, kMax> at;           // by ring edge: where its outer triangle points back
  std::uint64_t taken = 0;            // bit r: star slot r reused
  // Where the outer triangles to re-link point back is read here, before anything is rewritten
  // (an outer triangle may border two ring edges, and the star's slots are reused).
  for (std::size_t L = 0; L < nnew; ++L) {
    const auto& a = adj[L];
    int keep = -1;
    for (int i = 0; i < 3; ++i) {
      const int o = a[static_cast<std::size_t>(i)];
      if (is_local(o)) continue;
      const std::size_t r = ring_index(o);
      if (keep < 0) {
        keep = i;
        slot[L] = star[r];
        taken |= std::uint64_t{1} << r;
      } else if (outer[r] != kNone) {
        at[r] = mesh_.index_of_neighbour(outer[r], star[r]);
      }
    }
    kept[L] = keep;
  }
  for (std::size_t L = 0; L < nnew; ++L) {
    if (kept[L] >= 0) continue;
    const auto r = static_cast<unsigned>(__builtin_ctzll(~taken));
    slot[L] = star[r];
    taken |= std::uint64_t{1} << r;
  }
  const std::uint64_t all = k == kMax ? ~std::uint64_t{0} : (std::uint64_t{1} << k) - 1;
  for (std::uint64_t left = all & ~taken; left != 0; left &= left - 1) {
    mesh_.free_triangle(star[__builtin_ctzll(left)]);
  }
  for (std::size_t L = 0; L < nnew; ++L) {
    const TriangleId id = slot[L];
    Triangle T{tris[L], {}};
    for (int i = 0; i < 3; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const int o = adj[L][ui];
      if (is_local(o)) {
        T.n[ui] = slot[local_triangle(o)];
        continue;
      }
      const std::size_t r = ring_index(o);
      T.n[ui] = outer[r];
      if (i != kept[L] && outer[r] != kNone) mesh_.set_neighbour(outer[r], at[r], id);
      // Ring edge r starts at ring[r] = T.v[next3(i)]; every ring vertex starts one ring edge.
      mesh_.set_vertex_triangle(T.v[static_cast<std::size_t>(next3(i))], id);
    }
    if (hole.hull) {
      mesh_.set_triangle(id, T);
    } else {
      mesh_.set_finite_triangle(id, T);
    }
  }
  return slot[0];
}

// Writes a hole from delaunay_apexes (interior, no constraints): each new triangle takes the slot
// of the star triangle across one of its ring edges, so that outer triangle keeps its link; the
// triangles without a ring edge take the slots left over, and the last two are freed.
TriangleId Triangulation::write_apex_hole(RemovalHole& hole) {
  constexpr std::size_t kMax = RemovalHole::kApexMax;
  const std::size_t k = hole.degree, nnew = hole.ntri;
  const TriangleId* star = hole.star.data();
  const TriangleId* outer = hole.outer.data();
  const VertexId* ring = hole.ring.data();
  std::array<TriangleId, kMax> slot;  // mesh id of new triangle L
  std::array<TriangleId, kMax> spare;
  std::array<int, kMax> at;  // by ring edge: where its outer triangle points back, or -1 (kept)
  std::size_t nspare = 0;
  for (std::size_t L = 0; L < nnew; ++L) slot[L] = kNone;
  for (std::size_t r = 0; r < k; ++r) {
    const std::size_t L = local_triangle(hole.ring_tri[r]);
    if (slot[L] == kNone) {
      slot[L] = star[r];
      at[r] = -1;
    } else {
      spare[nspare++] = star[r];
      at[r] = outer[r] == kNone ? -1 : mesh_.index_of_neighbour(outer[r], star[r]);
    }
  }
  for (std::size_t L = 0; L < nnew; ++L) {
    if (slot[L] == kNone) slot[L] = spare[--nspare];
  }
  for (std::size_t i = 0; i < nspare; ++i) mesh_.free_triangle(spare[i]);
  for (std::size_t L = 0; L < nnew; ++L) {
    Triangle T{hole.tris[L], {}};
    for (std::size_t e = 0; e < 3; ++e) {
      const int o = hole.adj[L][e];
      T.n[e] = is_local(o) ? slot[local_triangle(o)] : outer[ring_index(o)];
    }
    mesh_.set_finite_triangle(slot[L], T);
  }
  for (std::size_t r = 0; r < k; ++r) {
    const TriangleId id = slot[local_triangle(hole.ring_tri[r])];
    if (at[r] >= 0) mesh_.set_neighbour(outer[r], at[r], id);
    mesh_.set_vertex_triangle(ring[r], id);
  }
  return slot[0];
}

Status Triangulation::remove_vertex(VertexId v) {
  if (!cut_ && v != kInfiniteVertex && v < mesh_.vertex_slots() &&
      mesh_.vertex_triangle(v) == kPendingTriangle) {
    std::erase(pending_, v);
    mesh_.set_vertex_triangle(v, kNone);
    --live_vertices_;
    ++revision_;
    return {};
  }
  RemovalHole& hole = removal_.get();
  const bool planned_already = hole.planned_vertex == v && hole.planned_revision == revision_;
  hole.planned_vertex = kNone;
  if (!planned_already) {
    if (Status s = plan_removal(v, hole, true); !s) return s;
  }
  ++revision_;
  if (hole.degenerate) {
    demote_to_collinear(v);
    --live_vertices_;
    return {};
  }
  const TriangleId first = has_constraints_ ? write_hole_general(hole)
                           : hole.apexes    ? write_apex_hole(hole)
                                            : write_hole(hole);
  mesh_.set_vertex_triangle(v, kNone);
  --live_vertices_;
  hint_ = first;
  if (hole.join_a != kNone) {
    int i;
    const TriangleId t = find_edge(hole.join_a, hole.join_b, &i);
    if (t != kNone) mesh_.set_edge_constrained(t, i, true);
    // Segment records ending at v (listed by the plan) now end at the re-join vertex on the far
    // side of v.
    const XY pv = mesh_.xy(v);
    const XY& pa = mesh_.xy(hole.join_a);
    bool collapsed = false;
    for (const std::size_t at : hole.segment_ends) {
      auto& s = segments_[at / 2];
      const std::size_t e = at % 2;
      const XY& other = mesh_.xy(s[1 - e]);
      const bool a_same_side =
          (pa.x - pv.x) * (other.x - pv.x) + (pa.y - pv.y) * (other.y - pv.y) > 0.0;
      s[e] = a_same_side ? hole.join_b : hole.join_a;
      collapsed = collapsed || s[0] == s[1];
    }
    if (collapsed) std::erase_if(segments_, [](const auto& s) { return s[0] == s[1]; });
  }
  return {};
}

}  // namespace tinstream::kernel
