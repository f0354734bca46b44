// Queries, accessors, the validity checker and cutting triangles away (islands).
#include <algorithm>
#include <cmath>
#include <string>

#include "tinstream/kernel/triangulation.hpp"
#include "triangulation_detail.hpp"

namespace tinstream::kernel {

using detail::kPendingTriangle;

namespace {
std::string tri_name(const Mesh& m, TriangleId t) {
  const Triangle& T = m.tri(t);
  return "triangle " + std::to_string(t) + " (" + std::to_string(T.v[0]) + ", " +
         std::to_string(T.v[1]) + ", " + std::to_string(T.v[2]) + ")";
}

// Walks v's fan in the order of incident_triangles(v, false) without collecting it: counter-
// clockwise from the vertex's triangle, or, on an open fan (`may_be_open`: only a cut mesh has
// one), from its clockwise end to its counter-clockwise end. Stops at the first triangle `stop`
// accepts and returns it; kNone when none does (or v has no triangle).
template <class Stop>
TriangleId walk_fan(const Mesh& m, VertexId v, bool may_be_open, Stop&& stop) {
  if (v >= m.vertex_slots()) return kNone;
  const TriangleId t0 = m.vertex_triangle(v);
  if (t0 == kNone || t0 == kPendingTriangle) return kNone;
  auto ccw = [&](TriangleId t) { return m.tri(t).n[next3(m.index_of(t, v))]; };
  auto cw = [&](TriangleId t) { return m.tri(t).n[prev3(m.index_of(t, v))]; };
  TriangleId start = t0;
  if (may_be_open) {
    TriangleId t = cw(t0);
    while (t != kNone && t != t0) {
      start = t;
      t = cw(t);
    }
    if (t == t0) start = t0;  // closed after all
  }
  TriangleId t = start;
  do {
    if (stop(t)) return t;
    t = ccw(t);
  } while (t != kNone && t != start);
  return kNone;
}
}  // namespace

bool Triangulation::is_vertex(VertexId v) const {
  return v != kInfiniteVertex && v < mesh_.vertex_slots() && mesh_.vertex_triangle(v) != kNone;
}

int Triangulation::dimension() const {
  if (mesh_.live_triangles() > 0) return 2;
  if (live_vertices_ == 0) return -1;
  return live_vertices_ == 1 ? 0 : 1;
}

std::size_t Triangulation::num_finite_triangles() const {
  return mesh_.live_triangles() - mesh_.ghost_triangles();
}

std::vector<VertexTriple> Triangulation::finite_triangles() const {
  std::vector<VertexTriple> out;
  out.reserve(num_finite_triangles());
  for_each_finite_triangle([&](TriangleId, const Triangle& t) { out.push_back(t.v); });
  return out;
}

std::vector<TriangleId> Triangulation::incident_triangles(VertexId v, bool finite_only) const {
  std::vector<TriangleId> ring;
  walk_fan(mesh_, v, cut_, [&](TriangleId t) {
    if (!finite_only || !mesh_.is_ghost(t)) ring.push_back(t);
    return false;
  });
  return ring;
}

std::vector<VertexId> Triangulation::adjacent_vertices(VertexId v, bool include_infinite) const {
  std::vector<VertexId> out;
  TriangleId last = kNone;
  walk_fan(mesh_, v, cut_, [&](TriangleId t) {
    const VertexId a = mesh_.tri(t).v[next3(mesh_.index_of(t, v))];
    if (a != kInfiniteVertex || include_infinite) out.push_back(a);
    last = t;
    return false;
  });
  if (last != kNone) {  // open fan (cut mesh): the last triangle's far vertex closes the list
    const int k = mesh_.index_of(last, v);
    if (mesh_.tri(last).n[next3(k)] == kNone) out.push_back(mesh_.tri(last).v[prev3(k)]);
  }
  return out;
}

// A live triangle having the directed edge a->b (a at v[next3(i)], b at v[prev3(i)]), or kNone:
// the first such triangle in a's fan (walk_fan: no allocation, the constraint code and the checker
// call this per edge). On an open fan's clockwise end the edge may be b->a only.
TriangleId Triangulation::find_edge(VertexId a, VertexId b, int* index) const {
  return walk_fan(mesh_, a, cut_, [&](TriangleId t) {
    const int k = mesh_.index_of(t, a);
    if (mesh_.tri(t).v[next3(k)] == b) {
      *index = prev3(k);
      return true;
    }
    if (mesh_.tri(t).v[prev3(k)] == b && mesh_.tri(t).n[next3(k)] == kNone) {
      *index = next3(k);
      return true;
    }
    return false;
  });
}

bool Triangulation::is_edge(VertexId a, VertexId b) const {
  int i;
  return a != b && find_edge(a, b, &i) != kNone;
}

bool Triangulation::is_constrained_edge(VertexId a, VertexId b) const {
  int i;
  if (a == b) return false;
  const TriangleId t = find_edge(a, b, &i);
  return t != kNone && mesh_.constrained(t, i);
}

bool Triangulation::is_on_hull(VertexId v) const {
  for (TriangleId t : incident_triangles(v, false)) {
    if (mesh_.is_ghost(t)) return true;
  }
  return false;
}

TriangleId Triangulation::locate_triangle(double x, double y) const {
  if (mesh_.live_triangles() == 0) return kNone;
  const XY p{x, y};
  const Location loc = locate(p, hint_);
  if (loc.t != kNone && loc.where != Where::outside_hull) {
    hint_ = loc.t;
    return loc.t;
  }
  if (loc.where == Where::outside_hull && !cut_) return kNone;
  // Cut mesh: the walk was blocked by a cut; islands need a scan.
  for (TriangleId t = 0; t < mesh_.triangle_slots(); ++t) {
    if (!mesh_.is_live(t) || mesh_.is_ghost(t)) continue;
    const Triangle& T = mesh_.tri(t);
    if (orient2d(mesh_.xy(T.v[0]), mesh_.xy(T.v[1]), p) >= 0.0 &&
        orient2d(mesh_.xy(T.v[1]), mesh_.xy(T.v[2]), p) >= 0.0 &&
        orient2d(mesh_.xy(T.v[2]), mesh_.xy(T.v[0]), p) >= 0.0) {
      hint_ = t;
      return t;
    }
  }
  return kNone;
}

std::optional<double> Triangulation::interpolate(double x, double y) const {
  const TriangleId t = locate_triangle(x, y);
  if (t == kNone) return std::nullopt;
  const Triangle& T = mesh_.tri(t);
  const XY &a = mesh_.xy(T.v[0]), &b = mesh_.xy(T.v[1]), &c = mesh_.xy(T.v[2]);
  if (a.x == x && a.y == y) return mesh_.z(T.v[0]);
  if (b.x == x && b.y == y) return mesh_.z(T.v[1]);
  if (c.x == x && c.y == y) return mesh_.z(T.v[2]);
  const double det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
  const double l1 = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
  const double l2 = ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) / det;
  const double l0 = 1.0 - l1 - l2;
  return l0 * mesh_.z(T.v[0]) + l1 * mesh_.z(T.v[1]) + l2 * mesh_.z(T.v[2]);
}

std::optional<VertexId> Triangulation::find_vertex(double x, double y) const {
  if (mesh_.live_triangles() == 0) {
    VertexId v;
    if (pending_contains(XY{x, y}, &v)) return v;
    return std::nullopt;
  }
  const TriangleId t = locate_triangle(x, y);
  if (t == kNone) return std::nullopt;
  for (VertexId v : mesh_.tri(t).v) {
    if (mesh_.xy(v).x == x && mesh_.xy(v).y == y) return v;
  }
  return std::nullopt;
}

// Follows constrained edges from a towards b, always taking the constrained edge that turns least
// away from the direction to b (intersection vertices make chains slightly bent).
bool Triangulation::segment_chain_present(VertexId a, VertexId b) const {
  // Depth-first from a along constrained edges whose far vertex lies on the segment a-b (within
  // rounding: intersection vertices are rounded; see the tolerance below) and not behind the
  // vertex before. Not a greedy walk by edge direction: rounding can put two intersection vertices
  // a few ulps apart (their short edge points anywhere, in either order along a-b), and two long
  // constraints from one far vertex can point the same way to within rounding; the greedy walk
  // reported both as missing chains (found by kernel_fuzzer).
  const XY& pa = mesh_.xy(a);
  const XY& pb = mesh_.xy(b);
  const double dx = pb.x - pa.x, dy = pb.y - pa.y;
  const double len2 = dx * dx + dy * dy;
  // An intersection vertex is computed along the crossing segment, to within ~1e-16 of *its*
  // length: a short constraint crossed by a much longer one can be bent by that much (a 8-unit
  // one by 4e-8 when crossed by a 1e9-unit one). The tolerance is relative to the mesh's extent.
  double extent = std::sqrt(len2);
  for (VertexId v = 1; v < mesh_.vertex_slots(); ++v) {
    if (!is_vertex(v)) continue;
    extent = std::max({extent, std::abs(mesh_.xy(v).x - pa.x), std::abs(mesh_.xy(v).y - pa.y)});
  }
  const double tolerance = 1e-9 * extent;
  auto along = [&](const XY& p) { return ((p.x - pa.x) * dx + (p.y - pa.y) * dy) / len2; };
  auto off = [&](const XY& p) {
    return std::abs((p.x - pa.x) * dy - (p.y - pa.y) * dx) / std::sqrt(len2);
  };
  std::vector<VertexId> stack{a};
  std::vector<VertexId> seen{a};
  while (!stack.empty()) {
    const VertexId cur = stack.back();
    stack.pop_back();
    if (cur == b) return true;
    const double t_cur = along(mesh_.xy(cur));
    auto follow = [&](VertexId w) {
      if (std::find(seen.begin(), seen.end(), w) != seen.end()) return;
      const XY& q = mesh_.xy(w);
      // Not backwards beyond rounding: two intersection vertices a few ulps apart can come in
      // either order along the segment (the visited list stops any cycle).
      const double t = along(q);
      const double slack = tolerance / std::sqrt(len2);  // the tolerance along a-b, in t
      if (w != b && (off(q) > tolerance || !(t > t_cur - slack) || t > 1.0 + slack)) return;
      seen.push_back(w);
      stack.push_back(w);
    };
    // The constrained edges at cur, read off its fan in the order of adjacent_vertices(cur):
    // cur -> w is the edge prev3(k) of the triangle holding cur at k and w at next3(k); an open
    // fan's (cut mesh) closing vertex is at prev3(k) of its last triangle, edge next3(k). The
    // same flags as is_constrained_edge(cur, w), without a fan walk per neighbour (that made
    // this check quadratic in the vertex degree: most of kernel_fuzzer's time).
    TriangleId last = kNone;
    walk_fan(mesh_, cur, cut_, [&](TriangleId t) {
      const int k = mesh_.index_of(t, cur);
      const VertexId w = mesh_.tri(t).v[next3(k)];
      if (w != kInfiniteVertex && mesh_.constrained(t, prev3(k))) follow(w);
      last = t;
      return false;
    });
    if (last != kNone) {
      const int k = mesh_.index_of(last, cur);
      if (mesh_.tri(last).n[next3(k)] == kNone && mesh_.constrained(last, next3(k))) {
        follow(mesh_.tri(last).v[prev3(k)]);
      }
    }
  }
  return false;
}

Status Triangulation::check_valid(CheckLevel level) const {
  const std::size_t nt = mesh_.triangle_slots();
  std::size_t ghosts = 0;
  for (TriangleId t = 0; t < nt; ++t) {
    if (!mesh_.is_live(t)) continue;
    const Triangle& T = mesh_.tri(t);
    int g = 0;
    for (int i = 0; i < 3; ++i) {
      if (T.v[i] >= mesh_.vertex_slots())
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": vertex id out of range");
      if (T.v[i] == kInfiniteVertex) {
        ++g;
      } else if (!is_vertex(T.v[i])) {
        return Error(ErrorCode::internal,
                     tri_name(mesh_, t) + ": references removed vertex " + std::to_string(T.v[i]));
      }
    }
    if (T.v[0] == T.v[1] || T.v[1] == T.v[2] || T.v[0] == T.v[2]) {
      return Error(ErrorCode::internal, tri_name(mesh_, t) + ": repeated vertex");
    }
    if (g > 1) return Error(ErrorCode::internal, tri_name(mesh_, t) + ": two infinite vertices");
    if (g == 1) {
      ++ghosts;
      if (cut_)
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": ghost triangle in a cut mesh");
    } else if (orient2d(mesh_.xy(T.v[0]), mesh_.xy(T.v[1]), mesh_.xy(T.v[2])) <= 0.0) {
      return Error(ErrorCode::internal, tri_name(mesh_, t) + ": not counter-clockwise");
    }
    for (int i = 0; i < 3; ++i) {
      const TriangleId u = T.n[i];
      if (u == kNone) {
        if (!cut_)
          return Error(ErrorCode::internal,
                       tri_name(mesh_, t) + ": missing neighbour " + std::to_string(i));
        continue;
      }
      if (u >= nt || !mesh_.is_live(u)) {
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": neighbour " + std::to_string(i) +
                                              " is not a live triangle");
      }
      const Triangle& U = mesh_.tri(u);
      const int j = U.n[0] == t ? 0 : U.n[1] == t ? 1 : U.n[2] == t ? 2 : -1;
      if (j < 0)
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": neighbour " + std::to_string(u) +
                                              " does not point back");
      if (U.v[next3(j)] != T.v[prev3(i)] || U.v[prev3(j)] != T.v[next3(i)]) {
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": shared edge with " +
                                              std::to_string(u) + " does not match");
      }
      if (mesh_.constrained(t, i) != mesh_.constrained(u, j)) {
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": constraint flag not symmetric");
      }
    }
  }
  if (ghosts != mesh_.ghost_triangles())
    return Error(ErrorCode::internal, "ghost triangle count is wrong");
  std::size_t live = 0;
  for (VertexId v = 1; v < mesh_.vertex_slots(); ++v) {
    const TriangleId t = mesh_.vertex_triangle(v);
    if (t == kNone) continue;
    ++live;
    if (t == kPendingTriangle) {
      if (mesh_.live_triangles() != 0)
        return Error(ErrorCode::internal, "vertex " + std::to_string(v) + " still pending in 2D");
      continue;
    }
    if (t >= nt || !mesh_.is_live(t) || mesh_.index_of(t, v) < 0) {
      return Error(ErrorCode::internal,
                   "vertex " + std::to_string(v) + ": its triangle does not contain it");
    }
  }
  if (live != live_vertices_) return Error(ErrorCode::internal, "live vertex count is wrong");
  if (level == CheckLevel::cheap) return {};

  for (TriangleId t = 0; t < nt; ++t) {
    if (!mesh_.is_live(t)) continue;
    const Triangle& T = mesh_.tri(t);
    if (mesh_.is_ghost(t)) {
      const int g = mesh_.index_of(t, kInfiniteVertex);
      const TriangleId u = T.n[next3(g)];  // next ghost along the hull, across edge (y, 0)
      if (!mesh_.is_ghost(u))
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": ghost neighbour is finite");
      const Triangle& U = mesh_.tri(u);
      const int gu = mesh_.index_of(u, kInfiniteVertex);
      const VertexId x = T.v[next3(g)], y = T.v[prev3(g)], z = U.v[prev3(gu)];
      if (U.v[next3(gu)] != y)
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": hull chain broken");
      if (z != x && orient2d(mesh_.xy(x), mesh_.xy(y), mesh_.xy(z)) > 0.0) {
        return Error(ErrorCode::internal,
                     tri_name(mesh_, t) + ": hull not convex at vertex " + std::to_string(y));
      }
      continue;
    }
    for (int i = 0; i < 3; ++i) {
      const TriangleId u = T.n[i];
      if (u == kNone || mesh_.constrained(t, i) || mesh_.is_ghost(u)) continue;
      const int j = mesh_.mirror(t, i);
      const VertexId q = mesh_.tri(u).v[j];
      if (incircle(mesh_.xy(T.v[0]), mesh_.xy(T.v[1]), mesh_.xy(T.v[2]), mesh_.xy(q)) > 0.0) {
        return Error(ErrorCode::internal, tri_name(mesh_, t) + ": vertex " + std::to_string(q) +
                                              " lies inside its circumcircle (edge not Delaunay)");
      }
    }
  }
  for (const auto& s : segments_) {
    if (!segment_chain_present(s[0], s[1])) {
      return Error(ErrorCode::internal, "constraint segment " + std::to_string(s[0]) + "-" +
                                            std::to_string(s[1]) +
                                            " is not a chain of constrained edges");
    }
  }
  return {};
}

std::size_t Triangulation::remove_triangles_if(
    const std::function<bool(const VertexTriple&)>& drop) {
  ++revision_;
  std::size_t dropped = 0;
  std::vector<TriangleId> doomed;
  for (TriangleId t = 0; t < mesh_.triangle_slots(); ++t) {
    if (!mesh_.is_live(t)) continue;
    if (mesh_.is_ghost(t)) {
      doomed.push_back(t);
    } else if (drop(mesh_.tri(t).v)) {
      doomed.push_back(t);
      ++dropped;
    }
  }
  for (TriangleId t : doomed) {
    for (int i = 0; i < 3; ++i) {
      const TriangleId u = mesh_.tri(t).n[i];
      if (u != kNone) mesh_.replace_neighbour(u, t, kNone);
    }
    mesh_.free_triangle(t);
  }
  for (VertexId v = 0; v < mesh_.vertex_slots(); ++v) mesh_.set_vertex_triangle(v, kNone);
  for (TriangleId t = 0; t < mesh_.triangle_slots(); ++t) {
    if (!mesh_.is_live(t)) continue;
    for (VertexId v : mesh_.tri(t).v) mesh_.set_vertex_triangle(v, t);
  }
  live_vertices_ = 0;
  for (VertexId v = 1; v < mesh_.vertex_slots(); ++v) {
    if (mesh_.vertex_triangle(v) != kNone) ++live_vertices_;
  }
  std::erase_if(segments_, [&](const auto& s) { return !is_vertex(s[0]) || !is_vertex(s[1]); });
  pending_.clear();
  cut_ = true;
  hint_ = kNone;
  return dropped;
}

std::size_t Triangulation::remove_triangles_outside(const Rect& r) {
  return remove_triangles_if([&](const VertexTriple& t) {
    const XY &a = mesh_.xy(t[0]), &b = mesh_.xy(t[1]), &c = mesh_.xy(t[2]);
    return !r.contains((a.x + b.x + c.x) / 3.0, (a.y + b.y + c.y) / 3.0);
  });
}

}  // namespace tinstream::kernel
