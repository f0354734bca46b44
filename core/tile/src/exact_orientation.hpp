// exact_orientation.hpp — exact sign of the 2D orientation determinant, private to core/tile.
//
// check_structure() needs an exact counter-clockwise test; the project's exact adaptive predicate
// lives in the kernel (tinstream/kernel/predicates.hpp, Shewchuk-style filter + expansion
// arithmetic). This wrapper is the one place the tile module calls it.
#pragma once

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::tile::detail {

// Returns +1 if c lies to the left of the directed line a→b (counter-clockwise triangle),
// -1 if to the right, 0 if the three points are collinear. Exact for normalised Mercator input.
inline int orient2d_sign(double ax, double ay, double bx, double by, double cx, double cy) {
  const double det = kernel::orient2d({ax, ay}, {bx, by}, {cx, cy});
  return det > 0 ? 1 : (det < 0 ? -1 : 0);
}

}  // namespace tinstream::tile::detail
