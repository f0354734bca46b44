#include "delaunay.hpp"

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::triangulate::detail {

using kernel::XY;

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
         mesh_.triangles.capacity() * sizeof(IndexTriangle) +
         mesh_.neighbours.capacity() * sizeof(mesh_.neighbours[0]);
}

void DelaunayBuilder::extend(const std::vector<XY>& points) {
  batch_.resize(points.size() - added_);
  for (std::size_t i = 0; i < batch_.size(); ++i) {
    batch_[i] = {points[added_ + i].x, points[added_ + i].y, 0.0, 0.0};
  }
  // Ties are flipped by perturbed_incircle as the points go in, so the kernel's triangulation is
  // the canonical one (the triangles are copied below, nothing is flipped after).
  dt_.set_perturbed_ties(true);
  const auto results = dt_.insert_bulk(batch_);
  // Vertex id → input index (the kernel numbers vertices in its own insertion order).
  index_of_.resize(dt_.vertex_id_bound(), 0);
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (results[i].outcome == kernel::InsertOutcome::inserted) {
      index_of_[results[i].vertex] = static_cast<std::uint32_t>(added_ + i);
    }
  }
  added_ = points.size();
  // The compact copy of all finite triangles (neighbours[t][i] across the edge opposite
  // triangles[t][i]; kNoNeighbour on the hull), in kernel slot order.
  const kernel::Mesh& mesh = dt_.mesh();
  compact_.assign(mesh.triangle_slots(), kNoNeighbour);
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
    if (compact_[t] == kNoNeighbour) continue;
    const auto& tri = mesh.tri(t);
    for (std::size_t i = 0; i < 3; ++i) {
      tn[compact_[t]][i] = tri.n[i] < compact_.size() ? compact_[tri.n[i]] : kNoNeighbour;
    }
  }
}

}  // namespace tinstream::triangulate::detail
