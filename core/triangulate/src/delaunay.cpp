#include "delaunay.hpp"

#include <algorithm>
#include <unordered_map>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::triangulate::detail {
namespace {

using kernel::XY;

bool lex_greater(const XY& p, const XY& q) { return p.x > q.x || (p.x == q.x && p.y > q.y); }

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t{a} << 32) | b; }

// Lawson flips under the perturbed predicate, starting from a Delaunay triangulation: only
// cocircular ties can be flipped, so the work is proportional to the number of ties.
void canonicalize(const std::vector<XY>& p, std::vector<IndexTriangle>& tris) {
  // Most inputs have no ties at all: find out cheaply (sorted half-edges) before building maps.
  {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> half(tris.size() * 3);
    for (std::uint32_t t = 0; t < tris.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) {
        half[t * 3 + k] = {edge_key(tris[t][k], tris[t][(k + 1) % 3]), tris[t][(k + 2) % 3]};
      }
    }
    std::sort(half.begin(), half.end());
    bool tie = false;
    for (const auto& [key, c] : half) {
      const auto a = static_cast<std::uint32_t>(key >> 32), b = static_cast<std::uint32_t>(key);
      if (a > b) continue;
      const auto twin = std::lower_bound(half.begin(), half.end(),
                                         std::make_pair(edge_key(b, a), std::uint32_t{0}));
      if (twin == half.end() || twin->first != edge_key(b, a)) continue;
      if (kernel::incircle(p[a], p[b], p[c], p[twin->second]) == 0.0) {
        tie = true;
        break;
      }
    }
    if (!tie) return;
  }
  // Directed edge (u → v) → triangle index and the position of u in it.
  std::unordered_map<std::uint64_t, std::uint32_t> owner;
  owner.reserve(tris.size() * 3);
  for (std::uint32_t t = 0; t < tris.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) owner[edge_key(tris[t][k], tris[t][(k + 1) % 3])] = t;
  }
  std::vector<std::uint64_t> stack;
  for (std::uint32_t t = 0; t < tris.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t u = tris[t][k], v = tris[t][(k + 1) % 3];
      if (u < v) stack.push_back(edge_key(u, v));
    }
  }
  auto third = [](const IndexTriangle& t, std::uint32_t u, std::uint32_t v) {
    for (std::uint32_t w : t) {
      if (w != u && w != v) return w;
    }
    return t[0];
  };
  while (!stack.empty()) {
    const std::uint64_t key = stack.back();
    stack.pop_back();
    const auto a = static_cast<std::uint32_t>(key >> 32), b = static_cast<std::uint32_t>(key);
    const auto left = owner.find(edge_key(a, b));   // triangle (a, b, c)
    const auto right = owner.find(edge_key(b, a));  // triangle (b, a, d)
    if (left == owner.end() || right == owner.end()) continue;  // hull edge
    const std::uint32_t t1 = left->second, t2 = right->second;
    const std::uint32_t c = third(tris[t1], a, b), d = third(tris[t2], a, b);
    if (kernel::incircle(p[a], p[b], p[c], p[d]) != 0.0) continue;  // not a tie: already right
    if (perturbed_incircle(p[a], p[b], p[c], p[d]) < 0) continue;
    // Flip a-b to c-d: (a, b, c) + (b, a, d) → (a, d, c) + (d, b, c).
    for (std::size_t k = 0; k < 3; ++k) {
      owner.erase(edge_key(tris[t1][k], tris[t1][(k + 1) % 3]));
      owner.erase(edge_key(tris[t2][k], tris[t2][(k + 1) % 3]));
    }
    tris[t1] = {a, d, c};
    tris[t2] = {d, b, c};
    for (std::uint32_t t : {t1, t2}) {
      for (std::size_t k = 0; k < 3; ++k) owner[edge_key(tris[t][k], tris[t][(k + 1) % 3])] = t;
    }
    for (auto [u, v] : {std::pair{a, d}, std::pair{d, b}, std::pair{b, c}, std::pair{c, a}}) {
      stack.push_back(u < v ? edge_key(u, v) : edge_key(v, u));
    }
  }
}

}  // namespace

int perturbed_incircle(const XY& a, const XY& b, const XY& c, const XY& d) {
  const double exact = kernel::incircle(a, b, c, d);
  if (exact > 0.0) return 1;
  if (exact < 0.0) return -1;
  // Cofactor of each point's lift (see the header), highest lexicographic rank first.
  const XY* order[4] = {&a, &b, &c, &d};
  std::sort(std::begin(order), std::end(order),
            [](const XY* l, const XY* r) { return lex_greater(*l, *r); });
  for (const XY* t : order) {
    double s;
    if (t == &d) {
      s = -kernel::orient2d(a, b, c);
    } else if (t == &a) {
      s = kernel::orient2d(d, b, c);
    } else if (t == &b) {
      s = kernel::orient2d(a, d, c);
    } else {
      s = kernel::orient2d(a, b, d);
    }
    if (s > 0.0) return 1;
    if (s < 0.0) return -1;
  }
  return -1;  // degenerate (a, b, c collinear): treat as outside
}

std::vector<IndexTriangle> delaunay(const std::vector<XY>& points) {
  std::vector<kernel::Point3> in(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) in[i] = {points[i].x, points[i].y, 0.0, 0.0};
  kernel::Triangulation dt;
  const auto results = dt.insert_bulk(in);
  // Vertex id → input index (the kernel numbers vertices in its own insertion order).
  std::vector<std::uint32_t> index_of(dt.vertex_id_bound(), 0);
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (results[i].outcome == kernel::InsertOutcome::inserted) {
      index_of[results[i].vertex] = static_cast<std::uint32_t>(i);
    }
  }
  std::vector<IndexTriangle> out;
  out.reserve(2 * points.size());
  dt.for_each_finite_triangle([&](kernel::TriangleId, const auto& t) {
    out.push_back({index_of[t.v[0]], index_of[t.v[1]], index_of[t.v[2]]});
  });
  canonicalize(points, out);
  return out;
}

}  // namespace tinstream::triangulate::detail
