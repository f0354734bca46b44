#include "delaunay.hpp"

#include <algorithm>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::triangulate::detail {
namespace {

using kernel::XY;

bool lex_greater(const XY& p, const XY& q) { return p.x > q.x || (p.x == q.x && p.y > q.y); }

// The kernel's finite triangles are copied into a compact DelaunayMesh (neighbours[t][i] across
// the edge opposite triangles[t][i]; kNoTri on the hull), on which cocircular ties are flipped to
// the canonical diagonal by Lawson flips under the perturbed predicate. Only ties can flip (the
// kernel's result is already Delaunay), so the work is proportional to the number of ties.
constexpr std::uint32_t kNoTri = kNoNeighbour;

void canonicalize(const std::vector<XY>& p, DelaunayMesh& mesh,
                  std::vector<std::pair<std::uint32_t, int>>& stack) {
  auto& tv = mesh.triangles;
  auto& tn = mesh.neighbours;
  auto index_in = [&](std::uint32_t t, std::uint32_t of) {
    for (int i = 0; i < 3; ++i) {
      if (tn[t][static_cast<std::size_t>(i)] == of) return i;
    }
    return -1;
  };
  stack.clear();
  for (std::uint32_t t = 0; t < tv.size(); ++t) {
    for (int i = 0; i < 3; ++i) {
      if (tn[t][static_cast<std::size_t>(i)] != kNoTri && tn[t][static_cast<std::size_t>(i)] > t)
        stack.emplace_back(t, i);
    }
  }
  while (!stack.empty()) {
    const auto [t1, i1] = stack.back();
    stack.pop_back();
    const std::uint32_t t2 = tn[t1][static_cast<std::size_t>(i1)];
    if (t2 == kNoTri) continue;
    const int i2 = index_in(t2, t1);
    if (i2 < 0) continue;
    // (i ≤ 4 here: a subtraction, not the division i % 3 compiles to)
    const auto at = [](int i) { return static_cast<std::size_t>(i >= 3 ? i - 3 : i); };
    // t1 = (c, a, b) from position i1; t2 = (d, b, a) from position i2.
    const std::uint32_t c = tv[t1][at(i1)], a = tv[t1][at(i1 + 1)], b = tv[t1][at(i1 + 2)];
    const std::uint32_t d = tv[t2][at(i2)];
    if (kernel::incircle(p[c], p[a], p[b], p[d]) != 0.0) continue;  // not a tie: already right
    if (perturbed_incircle(p[c], p[a], p[b], p[d]) < 0) continue;
    const std::uint32_t x_bc = tn[t1][at(i1 + 1)], x_ca = tn[t1][at(i1 + 2)];
    const std::uint32_t x_ad = tn[t2][at(i2 + 1)], x_db = tn[t2][at(i2 + 2)];
    // (c, a, d) and (d, b, c): the diagonal c-d replaces a-b.
    tv[t1] = {c, a, d};
    tn[t1] = {x_ad, t2, x_ca};
    tv[t2] = {d, b, c};
    tn[t2] = {x_bc, t1, x_db};
    if (x_ad != kNoTri) tn[x_ad][static_cast<std::size_t>(index_in(x_ad, t2))] = t1;
    if (x_bc != kNoTri) tn[x_bc][static_cast<std::size_t>(index_in(x_bc, t1))] = t2;
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
  DelaunayBuilder builder;
  builder.extend(points);
  return builder.mesh();
}

void DelaunayBuilder::clear() {
  dt_.clear();
  index_of_.clear();
  added_ = 0;
  mesh_.triangles.clear();
  mesh_.neighbours.clear();
}

std::size_t DelaunayBuilder::memory_bytes() const {
  return dt_.memory_bytes() + batch_.capacity() * sizeof(kernel::Point3) +
         (index_of_.capacity() + compact_.capacity()) * sizeof(std::uint32_t) +
         flips_.capacity() * sizeof(flips_[0]) +
         mesh_.triangles.capacity() * sizeof(IndexTriangle) +
         mesh_.neighbours.capacity() * sizeof(mesh_.neighbours[0]);
}

void DelaunayBuilder::extend(const std::vector<XY>& points) {
  batch_.resize(points.size() - added_);
  for (std::size_t i = 0; i < batch_.size(); ++i) {
    batch_[i] = {points[added_ + i].x, points[added_ + i].y, 0.0, 0.0};
  }
  const auto results = dt_.insert_bulk(batch_);
  // Vertex id → input index (the kernel numbers vertices in its own insertion order).
  index_of_.resize(dt_.vertex_id_bound(), 0);
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (results[i].outcome == kernel::InsertOutcome::inserted) {
      index_of_[results[i].vertex] = static_cast<std::uint32_t>(added_ + i);
    }
  }
  added_ = points.size();
  // The compact copy of all finite triangles, in kernel slot order, then its ties made canonical.
  const kernel::Mesh& mesh = dt_.mesh();
  compact_.assign(mesh.triangle_slots(), kNoTri);
  auto& tv = mesh_.triangles;
  auto& tn = mesh_.neighbours;
  tv.clear();
  for (kernel::TriangleId t = 0; t < mesh.triangle_slots(); ++t) {
    if (!mesh.is_live(t) || mesh.is_ghost(t)) continue;
    compact_[t] = static_cast<std::uint32_t>(tv.size());
    const auto& tri = mesh.tri(t);
    tv.push_back({index_of_[tri.v[0]], index_of_[tri.v[1]], index_of_[tri.v[2]]});
  }
  tn.resize(tv.size());
  for (kernel::TriangleId t = 0; t < mesh.triangle_slots(); ++t) {
    if (compact_[t] == kNoTri) continue;
    const auto& tri = mesh.tri(t);
    for (std::size_t i = 0; i < 3; ++i) {
      tn[compact_[t]][i] = tri.n[i] < compact_.size() ? compact_[tri.n[i]] : kNoTri;
    }
  }
  canonicalize(points, mesh_, flips_);
}

}  // namespace tinstream::triangulate::detail
