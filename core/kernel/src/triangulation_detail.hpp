// Private helpers shared by the algorithm translation units.
#pragma once

#include "tinstream/kernel/mesh.hpp"

namespace tinstream::kernel::detail {

// vertex_triangle() of a vertex that waits for the triangulation to become two-dimensional.
inline constexpr TriangleId kPendingTriangle = 0xFFFFFFFEu;

}  // namespace tinstream::kernel::detail
