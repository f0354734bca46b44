// Private: the one kernel operation pass 3 needs — the Delaunay triangulation of distinct points.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::triangulate::detail {

using IndexTriangle = std::array<std::uint32_t, 3>;

// Counter-clockwise triangles (indices into `points`) covering the convex hull of `points`.
// Requires: points are pairwise distinct.
std::vector<IndexTriangle> delaunay(const std::vector<kernel::XY>& points);

}  // namespace tinstream::triangulate::detail
