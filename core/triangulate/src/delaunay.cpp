#include "delaunay.hpp"

#include <algorithm>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::triangulate::detail {
namespace {

using kernel::XY;

bool lex_greater(const XY& p, const XY& q) { return p.x > q.x || (p.x == q.x && p.y > q.y); }

// A compact copy of the kernel's finite triangles with neighbour links (n[i] across the edge
// opposite v[i]; kNoTri on the hull), on which cocircular ties are flipped to the canonical
// diagonal by Lawson flips under the perturbed predicate. Only ties can flip (the kernel's result
// is already Delaunay), so the work is proportional to the number of ties.
constexpr std::uint32_t kNoTri = kNoNeighbour;

struct FlipMesh {
  std::vector<IndexTriangle> v;  // input indices
  std::vector<std::array<std::uint32_t, 3>> n;
};

void canonicalize(const std::vector<XY>& p, FlipMesh& m) {
  auto index_in = [&](std::uint32_t t, std::uint32_t of) {
    for (int i = 0; i < 3; ++i) {
      if (m.n[t][static_cast<std::size_t>(i)] == of) return i;
    }
    return -1;
  };
  std::vector<std::pair<std::uint32_t, int>> stack;
  stack.reserve(m.v.size() * 3);
  for (std::uint32_t t = 0; t < m.v.size(); ++t) {
    for (int i = 0; i < 3; ++i) {
      if (m.n[t][static_cast<std::size_t>(i)] != kNoTri && m.n[t][static_cast<std::size_t>(i)] > t)
        stack.emplace_back(t, i);
    }
  }
  while (!stack.empty()) {
    const auto [t1, i1] = stack.back();
    stack.pop_back();
    const std::uint32_t t2 = m.n[t1][static_cast<std::size_t>(i1)];
    if (t2 == kNoTri) continue;
    const int i2 = index_in(t2, t1);
    if (i2 < 0) continue;
    const auto at = [](int i) { return static_cast<std::size_t>(i % 3); };
    // t1 = (c, a, b) from position i1; t2 = (d, b, a) from position i2.
    const std::uint32_t c = m.v[t1][at(i1)], a = m.v[t1][at(i1 + 1)], b = m.v[t1][at(i1 + 2)];
    const std::uint32_t d = m.v[t2][at(i2)];
    if (kernel::incircle(p[c], p[a], p[b], p[d]) != 0.0) continue;  // not a tie: already right
    if (perturbed_incircle(p[c], p[a], p[b], p[d]) < 0) continue;
    const std::uint32_t x_bc = m.n[t1][at(i1 + 1)], x_ca = m.n[t1][at(i1 + 2)];
    const std::uint32_t x_ad = m.n[t2][at(i2 + 1)], x_db = m.n[t2][at(i2 + 2)];
    // (c, a, d) and (d, b, c): the diagonal c-d replaces a-b.
    m.v[t1] = {c, a, d};
    m.n[t1] = {x_ad, t2, x_ca};
    m.v[t2] = {d, b, c};
    m.n[t2] = {x_bc, t1, x_db};
    if (x_ad != kNoTri) m.n[x_ad][static_cast<std::size_t>(index_in(x_ad, t2))] = t1;
    if (x_bc != kNoTri) m.n[x_bc][static_cast<std::size_t>(index_in(x_bc, t1))] = t2;
    stack.emplace_back(t1, 0);
    stack.emplace_back(t1, 2);
    stack.emplace_back(t2, 0);
    stack.emplace_back(t2, 2);
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
  return delaunay_mesh(points).triangles;
}

DelaunayMesh delaunay_mesh(const std::vector<XY>& points) {
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
  const kernel::Mesh& mesh = dt.mesh();
  std::vector<std::uint32_t> compact(mesh.triangle_slots(), kNoTri);
  FlipMesh m;
  m.v.reserve(2 * points.size());
  for (kernel::TriangleId t = 0; t < mesh.triangle_slots(); ++t) {
    if (!mesh.is_live(t) || mesh.is_ghost(t)) continue;
    compact[t] = static_cast<std::uint32_t>(m.v.size());
    const auto& tri = mesh.tri(t);
    m.v.push_back({index_of[tri.v[0]], index_of[tri.v[1]], index_of[tri.v[2]]});
  }
  m.n.resize(m.v.size());
  for (kernel::TriangleId t = 0; t < mesh.triangle_slots(); ++t) {
    if (compact[t] == kNoTri) continue;
    const auto& tri = mesh.tri(t);
    for (std::size_t i = 0; i < 3; ++i) {
      m.n[compact[t]][i] = tri.n[i] < compact.size() ? compact[tri.n[i]] : kNoTri;
    }
  }
  canonicalize(points, m);
  return {std::move(m.v), std::move(m.n)};
}

}  // namespace tinstream::triangulate::detail
