// Private: the kernel operations pass 3 needs — the *canonical* Delaunay triangulation of
// distinct points, and the perturbed in-circle test that defines it.
//
// Cocircular points (every rectangle of a DEM lattice in Mercator!) have several Delaunay
// triangulations. Two tiles triangulating different subsets must agree on the triangles near
// their shared border, so ties are broken by the kernel's perturbed_incircle (predicates.hpp),
// a symbolic perturbation that depends on the points alone: the kernel flips by it as the points
// go in (Triangulation::set_perturbed_ties), so its triangulation is the perturbed point set's,
// which is unique.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "tinstream/kernel/predicates.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::triangulate::detail {

using IndexTriangle = std::array<std::uint32_t, 3>;

// The kernel's perturbed_incircle (predicates.hpp) defines the perturbation.
using kernel::perturbed_incircle;

// The canonical (perturbed) Delaunay triangulation: counter-clockwise triangles (indices into
// `points`) covering the convex hull of `points`. Requires: points are pairwise distinct.
std::vector<IndexTriangle> delaunay(const std::vector<kernel::XY>& points);

// The same triangulation with neighbour links: neighbours[t][i] is the triangle across the edge
// opposite triangles[t][i] (from triangles[t][i+1] to triangles[t][i+2]), kNoNeighbour on the
// convex hull — so the hull edges are found in one pass, without sorting the edges.
constexpr std::uint32_t kNoNeighbour = 0xFFFFFFFFu;
struct DelaunayMesh {
  std::vector<IndexTriangle> triangles;
  std::vector<std::array<std::uint32_t, 3>> neighbours;
};
DelaunayMesh delaunay_mesh(const std::vector<kernel::XY>& points);

// The canonical triangulation of a growing point set, kept in one kernel triangulation: each
// extend() inserts only the points appended since the previous call (a halo round's new cells)
// instead of triangulating all of them again. mesh() holds the same triangles as
// delaunay_mesh(points) — the canonical triangulation is unique — but not in the same order.
// After clear() the next extend() gives exactly delaunay_mesh(points), triangle order included.
// The buffers (kernel mesh included) keep their capacity across clear(): one builder per thread,
// reused from tile to tile.
class DelaunayBuilder {
 public:
  void clear();
  // Inserts points[added(), points.size()). Requires: points[0, added()) are the points of the
  // previous calls, unchanged; all points pairwise distinct.
  void extend(const std::vector<kernel::XY>& points);
  std::size_t added() const { return added_; }
  const DelaunayMesh& mesh() const { return mesh_; }
  std::size_t memory_bytes() const;

 private:
  kernel::Triangulation dt_;
  std::vector<kernel::Point3> batch_;
  std::vector<std::uint32_t> index_of_;  // kernel vertex id → index into the points
  std::vector<std::uint32_t> compact_;  // kernel triangle id → index into mesh_ (or kNoNeighbour)
  std::size_t added_ = 0;
  DelaunayMesh mesh_;
};

}  // namespace tinstream::triangulate::detail
