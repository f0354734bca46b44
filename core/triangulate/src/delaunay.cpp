#include "delaunay.hpp"

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::triangulate::detail {

std::vector<IndexTriangle> delaunay(const std::vector<kernel::XY>& points) {
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
  return out;
}

}  // namespace tinstream::triangulate::detail
