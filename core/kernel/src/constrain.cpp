// Constraint segments: walk the triangles crossed by a segment, split it at vertices lying on it
// and at crossing constraints, remove the crossed edges by flips (Sloan 1993), then restore the
// constrained Delaunay property around the new edges by Lawson flips.
#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "tinstream/kernel/triangulation.hpp"
#include "triangulation_detail.hpp"

namespace tinstream::kernel {

namespace {
std::string seg_name(VertexId a, VertexId b) {
  return "constraint " + std::to_string(a) + "-" + std::to_string(b);
}
}  // namespace

Status Triangulation::insert_constraint(VertexId a, VertexId b) {
  ++revision_;
  if (cut_) return unsupported(seg_name(a, b) + ": the mesh was cut, it no longer accepts edits");
  if (!is_vertex(a) || !is_vertex(b))
    return invalid_argument(seg_name(a, b) + ": not a live vertex");
  if (a == b) return invalid_argument(seg_name(a, b) + ": both ends are the same vertex");
  if (dimension() < 2) {
    return unsupported(seg_name(a, b) +
                       ": needs a two-dimensional triangulation (three non-collinear points)");
  }
  const std::size_t budget = 16 + 4 * segments_.size();
  intersections_left_ = budget;
  segments_.push_back({a, b});
  has_constraints_ = true;
  randomize_walk_ = true;
  Status inserted = insert_segment(a, b);
  // Crossing constraints: each crossed one is re-routed through a rounded intersection vertex,
  // which can leave a flipped edge outside the ones restore_delaunay was given (kernel_fuzzer
  // found such non-Delaunay edges after segments of 1e9 units crossing unit ones). Rare in real
  // data (border chains and breaklines seldom cross), so then every edge is checked: O(n).
  if (inserted.ok()) {
    if (intersections_left_ != budget) restore_delaunay_everywhere();
    return inserted;
  }
  // The segment could not be made a chain (rounded intersection points of long, nearly parallel
  // crossing constraints can cascade; found by kernel_fuzzer). Its flips were all valid, so the
  // mesh is still a triangulation, but edges it flipped may not be Delaunay and a constraint it
  // crossed may be half re-routed. Leave a valid constrained Delaunay triangulation behind, and
  // forget every recorded segment that is no longer a chain of constrained edges, by name in the
  // error.
  restore_delaunay_everywhere();
  std::string dropped;
  std::erase_if(segments_, [&](const std::array<VertexId, 2>& s) {
    if (segment_chain_present(s[0], s[1])) return false;
    dropped += (dropped.empty() ? "" : ", ") + std::to_string(s[0]) + "-" + std::to_string(s[1]);
    return true;
  });
  hint_ = mesh_.vertex_triangle(a);
  return Error(inserted.error().code, inserted.error().message +
                                          " (the triangulation stays valid without segment(s) " +
                                          dropped + ")");
}

Result<std::array<VertexId, 2>> Triangulation::insert_constraint(const Point3& a, const Point3& b) {
  const InsertResult ra = insert(a);
  if (ra.vertex == kNone)
    return invalid_argument("constraint start point is outside the domain or not finite");
  const InsertResult rb = insert(b);
  if (rb.vertex == kNone)
    return invalid_argument("constraint end point is outside the domain or not finite");
  Status s = insert_constraint(ra.vertex, rb.vertex);
  if (!s.ok()) return s.error();
  return std::array<VertexId, 2>{ra.vertex, rb.vertex};
}

namespace {
double distance_to_segment(const XY& p, const XY& u, const XY& v) {
  const double ex = v.x - u.x, ey = v.y - u.y;
  const double len2 = ex * ex + ey * ey;
  double k = len2 > 0.0 ? ((p.x - u.x) * ex + (p.y - u.y) * ey) / len2 : 0.0;
  k = std::clamp(k, 0.0, 1.0);
  return std::hypot(p.x - (u.x + k * ex), p.y - (u.y + k * ey));
}

struct IntersectionChoice {
  XY xy;       // the point to insert (when at_end is 0)
  double s;    // its parameter along a-b, for the height
  int at_end;  // 1 or 2: c1 or c2 itself is the crossing
};

// Where segment a-b crosses segment c1-c2. The point is computed along a-b (parameter s): exact
// up to rounding when the two cross at a clear angle. When they are nearly collinear, s is
// ill-conditioned: clamped into [0, 1] it can land anywhere on a-b, far outside c1-c2
// (kernel_fuzzer found a-b's far end chosen, which re-routed c1-c2 through a vertex units away and
// bent its constraint). Then the point along c1-c2 or an end of c1-c2 is taken instead: whichever
// lies nearest both segments (each candidate's worse distance, no closer than rounding allows, so
// that the point along a-b is kept whenever it is as good as rounding can tell).
IntersectionChoice choose_intersection(const XY& pa, const XY& pb, const XY& p1, const XY& p2) {
  const double dx = pb.x - pa.x, dy = pb.y - pa.y;
  const double fx = p2.x - p1.x, fy = p2.y - p1.y;
  const double denom = dx * fy - dy * fx;
  auto along = [](double num, double den) {
    const double k = num / den;
    return !(k >= 0.0) ? 0.0 : k > 1.0 ? 1.0 : k;
  };
  const double s = along((p1.x - pa.x) * fy - (p1.y - pa.y) * fx, denom);
  const double u = along((p1.x - pa.x) * dy - (p1.y - pa.y) * dx, denom);
  const XY on_ab{pa.x + s * dx, pa.y + s * dy};
  const XY on_c{p1.x + u * fx, p1.y + u * fy};
  double scale = 0.0;
  for (const XY* p : {&pa, &pb, &p1, &p2})
    scale = std::max({scale, std::abs(p->x), std::abs(p->y)});
  const double floor = 8.0 * std::numeric_limits<double>::epsilon() * scale;
  auto score = [&](const XY& p) {
    return std::max({distance_to_segment(p, pa, pb), distance_to_segment(p, p1, p2), floor});
  };
  // An end of c1-c2 on a-b as far as rounding can tell: a-b goes through that vertex. A point
  // computed along a-b instead would be a new vertex an ulp or two beside it, splitting c1-c2 next
  // to its end (kernel_fuzzer: a constraint rounded through an earlier intersection point passes
  // ulps beside another constraint's end; the near-duplicate vertex later let the end's removal
  // merge two constraints into a segment that was no chain).
  if (score(p1) == floor) return {p1, 0.0, 1};
  if (score(p2) == floor) return {p2, 0.0, 2};
  IntersectionChoice best{on_ab, s, 0};
  double best_score = score(on_ab);
  if (best_score == floor) return best;
  auto consider = [&](const XY& p, int at_end) {
    const double sc = score(p);
    if (sc < best_score) {
      const double len2 = dx * dx + dy * dy;
      const double k = len2 > 0.0 ? ((p.x - pa.x) * dx + (p.y - pa.y) * dy) / len2 : 0.0;
      best = {p, std::clamp(k, 0.0, 1.0), at_end};
      best_score = sc;
    }
  };
  consider(p1, 1);
  consider(p2, 2);
  consider(on_c, 0);
  return best;
}
}  // namespace

// Inserts the intersection of segment a-b with the constrained edge opposite v[edge] of t; the
// constrained edge becomes the chain c1-X-c2. Returns X (an existing vertex when X rounds onto
// one), or kNone when it cannot be inserted or the cascade budget (intersections_left_) is spent.
VertexId Triangulation::insert_intersection(VertexId a, VertexId b, TriangleId t, int edge) {
  const VertexId c1 = mesh_.tri(t).v[next3(edge)], c2 = mesh_.tri(t).v[prev3(edge)];
  const XY &pa = mesh_.xy(a), &pb = mesh_.xy(b), &p1 = mesh_.xy(c1), &p2 = mesh_.xy(c2);
  const IntersectionChoice choice = choose_intersection(pa, pb, p1, p2);
  if (choice.at_end != 0) {
    // The two segments are nearly collinear and meet at an end of the constrained edge (within
    // rounding): a-b goes through that vertex, and c1-c2 stays as it is.
    return choice.at_end == 1 ? c1 : c2;
  }
  const double s = choice.s;
  Point3 x{choice.xy.x, choice.xy.y, mesh_.z(a) + s * (mesh_.z(b) - mesh_.z(a)),
           std::max(mesh_.weight(a), mesh_.weight(b))};
  if (intersections_left_ == 0) return kNone;
  --intersections_left_;
  hint_ = t;
  const InsertResult r = insert(x);
  if (r.vertex == kNone) return kNone;
  int i;
  const TriangleId e = find_edge(c1, c2, &i);
  if (e != kNone && mesh_.constrained(e, i)) {
    // X did not land exactly on c1-c2: route that constraint through X instead.
    mesh_.set_edge_constrained(e, i, false);
    if (r.vertex != c1 && r.vertex != c2) {
      Status s1 = insert_segment(c1, r.vertex);
      Status s2 = insert_segment(r.vertex, c2);
      if (!s1.ok() || !s2.ok()) return kNone;
    } else {
      mesh_.set_edge_constrained(e, i, true);
    }
    // c1-c2 was protected while X was inserted; now unconstrained it may not be Delaunay.
    std::vector<std::array<VertexId, 2>> edges{{c1, c2}};
    restore_delaunay(edges);
  }
  return r.vertex;
}

// Lawson flips from every finite edge: they converge to the constrained Delaunay triangulation
// from any triangulation with the same constrained edges.
void Triangulation::restore_delaunay_everywhere() {
  std::vector<std::array<VertexId, 2>> edges;
  for (TriangleId t = 0; t < mesh_.triangle_slots(); ++t) {
    if (!mesh_.is_live(t) || mesh_.is_ghost(t)) continue;
    const Triangle& T = mesh_.tri(t);
    for (int i = 0; i < 3; ++i) {
      if (T.v[next3(i)] < T.v[prev3(i)]) edges.push_back({T.v[next3(i)], T.v[prev3(i)]});
    }
  }
  restore_delaunay(edges);
}

// Lawson flips starting from the given edges (vertex pairs) until every unconstrained edge
// reachable through flips is locally Delaunay.
void Triangulation::restore_delaunay(std::vector<std::array<VertexId, 2>>& edges) {
  while (!edges.empty()) {
    const auto [x, y] = edges.back();
    edges.pop_back();
    int i;
    const TriangleId f = find_edge(x, y, &i);
    if (f == kNone || mesh_.constrained(f, i)) continue;
    const TriangleId u = mesh_.tri(f).n[i];
    if (u == kNone || mesh_.is_ghost(f) || mesh_.is_ghost(u)) continue;
    const Triangle& F = mesh_.tri(f);
    const VertexId q = mesh_.tri(u).v[mesh_.mirror(f, i)];
    if (incircle(mesh_.xy(F.v[0]), mesh_.xy(F.v[1]), mesh_.xy(F.v[2]), mesh_.xy(q)) <= 0.0)
      continue;
    const VertexId p = F.v[i], w = F.v[prev3(i)], uu = F.v[next3(i)];
    mesh_.flip(f, i);
    edges.push_back({p, uu});
    edges.push_back({uu, q});
    edges.push_back({q, w});
    edges.push_back({w, p});
  }
}

namespace detail {
// One sub-segment s-e of a constraint on its way into the mesh.
struct SegmentWalk {
  VertexId s = kNone;
  VertexId e = kNone;
  // Filled by walk_segment. Either `split` is a vertex that s-e must pass through (one lying on
  // it next to s, or the intersection point inserted on a crossed constraint): s-e becomes s-split
  // and split-e. Or `crossed` holds the edges that s-end crosses, as vertex pairs (right, left) in
  // walk order, where `end` is e or the first vertex found lying on s-e further along.
  VertexId split = kNone;
  VertexId end = kNone;
  std::deque<std::array<VertexId, 2>> crossed;
};
}  // namespace detail

Status Triangulation::insert_segment(VertexId a0, VertexId b0) {
  std::vector<std::array<VertexId, 2>> work{{a0, b0}};
  std::size_t budget = 16 * mesh_.vertex_slots() + 64;
  detail::SegmentWalk walk;
  std::vector<std::array<VertexId, 2>> fresh;
  while (!work.empty()) {
    if (--budget == 0) return Error(ErrorCode::internal, seg_name(a0, b0) + ": did not converge");
    const auto [s, e] = work.back();
    work.pop_back();
    if (s == e) continue;
    int idx;
    if (const TriangleId t = find_edge(s, e, &idx); t != kNone) {
      mesh_.set_edge_constrained(t, idx, true);
      continue;
    }
    walk.s = s;
    walk.e = e;
    if (Status walked = walk_segment(walk); !walked.ok()) return walked;
    if (walk.split != kNone) {
      work.push_back({walk.split, e});
      work.push_back({s, walk.split});
      continue;
    }
    if (walk.end != e) work.push_back({walk.end, e});
    if (Status flipped = flip_crossed_away(walk, fresh); !flipped.ok()) return flipped;
    restore_delaunay(fresh);
  }
  hint_ = mesh_.vertex_triangle(a0);
  return {};
}

// Walks from s along s-e through the triangles it crosses (see detail::SegmentWalk for what it
// leaves in `walk`).
Status Triangulation::walk_segment(detail::SegmentWalk& walk) {
  const VertexId s = walk.s, e = walk.e;
  walk.split = kNone;
  walk.end = e;
  walk.crossed.clear();
  const XY ps = mesh_.xy(s), pe = mesh_.xy(e);
  // The sector around s that the segment leaves through, or a vertex on the segment.
  TriangleId cur = kNone;
  int ci = 0;
  for (TriangleId r : incident_triangles(s, false)) {
    const int k = mesh_.index_of(r, s);
    const VertexId x = mesh_.tri(r).v[next3(k)], y = mesh_.tri(r).v[prev3(k)];
    if (x != kInfiniteVertex) {
      const XY& px = mesh_.xy(x);
      if (orient2d(ps, pe, px) == 0.0 &&
          (px.x - ps.x) * (pe.x - ps.x) + (px.y - ps.y) * (pe.y - ps.y) > 0.0) {
        walk.split = x;
        return {};
      }
    }
    if (x == kInfiniteVertex || y == kInfiniteVertex) continue;
    if (orient2d(ps, mesh_.xy(x), pe) > 0.0 && orient2d(ps, mesh_.xy(y), pe) < 0.0) {
      cur = r;
      ci = k;
    }
  }
  if (cur == kNone)
    return Error(ErrorCode::internal,
                 seg_name(s, e) + ": no triangle around the start vertex faces the end vertex");
  for (;;) {
    if (mesh_.constrained(cur, ci)) {
      walk.split = insert_intersection(s, e, cur, ci);
      if (walk.split != kNone) return {};
      return Error(ErrorCode::internal,
                   seg_name(s, e) + (intersections_left_ == 0
                                         ? ": its crossings with rounded intersection points "
                                           "cascade (too many intersection vertices)"
                                         : ": could not insert the intersection point"));
    }
    const Triangle& T = mesh_.tri(cur);
    walk.crossed.push_back({T.v[next3(ci)], T.v[prev3(ci)]});
    const TriangleId nb = T.n[ci];
    const int j = mesh_.mirror(cur, ci);
    const VertexId o = mesh_.tri(nb).v[j];
    if (o == e) return {};
    if (o == kInfiniteVertex)
      return Error(ErrorCode::internal, seg_name(s, e) + ": walked out of the hull");
    const double side = orient2d(ps, pe, mesh_.xy(o));
    if (side == 0.0) {  // o lies on the segment: finish s-o now, o-e later
      walk.end = o;
      return {};
    }
    cur = nb;
    ci = side < 0.0 ? prev3(j) : next3(j);
  }
}

// Sloan: flips the crossed edges whose quadrilateral is convex until none crosses s-end, then
// constrains s-end. The edges the flips made that do not cross s-end go to `fresh`, to be made
// Delaunay again.
Status Triangulation::flip_crossed_away(detail::SegmentWalk& walk,
                                        std::vector<std::array<VertexId, 2>>& fresh) {
  const VertexId s = walk.s, end = walk.end;
  const XY ps = mesh_.xy(s), pend = mesh_.xy(end);
  auto& crossed = walk.crossed;
  std::size_t stall = 0;
  while (!crossed.empty()) {
    const auto [x, y] = crossed.front();
    crossed.pop_front();
    int i;
    const TriangleId f = find_edge(x, y, &i);
    if (f == kNone) return Error(ErrorCode::internal, seg_name(s, end) + ": lost a crossed edge");
    const VertexId p = mesh_.tri(f).v[i];
    const VertexId q = mesh_.tri(mesh_.tri(f).n[i]).v[mesh_.mirror(f, i)];
    const XY &pp = mesh_.xy(p), &pq = mesh_.xy(q);
    const double ox = orient2d(pp, pq, mesh_.xy(x)), oy = orient2d(pp, pq, mesh_.xy(y));
    if (!((ox > 0.0 && oy < 0.0) || (ox < 0.0 && oy > 0.0))) {
      crossed.push_back({x, y});
      if (++stall > 4 * crossed.size() + 16) {
        return Error(ErrorCode::internal,
                     seg_name(s, end) + ": crossed edges cannot be flipped away");
      }
      continue;
    }
    stall = 0;
    mesh_.flip(f, i);
    const bool crossing = p != s && p != end && q != s && q != end &&
                          ((orient2d(ps, pend, pp) > 0.0 && orient2d(ps, pend, pq) < 0.0) ||
                           (orient2d(ps, pend, pp) < 0.0 && orient2d(ps, pend, pq) > 0.0));
    if (crossing) {
      crossed.push_back({p, q});
    } else {
      fresh.push_back({p, q});
    }
  }
  int idx;
  const TriangleId t = find_edge(s, end, &idx);
  if (t == kNone)
    return Error(ErrorCode::internal, seg_name(s, end) + ": edge missing after flips");
  mesh_.set_edge_constrained(t, idx, true);
  return {};
}

}  // namespace tinstream::kernel
