// exact_orientation.hpp — exact sign of the 2D orientation determinant, private to core/tile.
//
// check_structure() needs an exact counter-clockwise test. The triangulation kernel (core/kernel)
// will own the adaptive predicates of the project; until it is available this is a small,
// always-exact implementation: the six products of
//
//   orient(a, b, c) = ax·by − ay·bx + bx·cy − by·cx + cx·ay − cy·ax
//
// are split into exact (product, error) pairs with std::fma and summed into a non-overlapping
// floating-point expansion (Shewchuk 1996, Grow-Expansion with zero elimination); the sign of the
// expansion is the sign of its largest component. Exact for all finite inputs whose products
// neither overflow nor underflow (every coordinate in [-1, 1] with magnitude ≥ 2^-500 or 0 —
// normalised Mercator always is). Swap `orient2d_sign` for the kernel's orient2d once it exists.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>

namespace tinstream::tile::detail {

// a + b = sum + err exactly (Knuth's TwoSum).
inline void two_sum(double a, double b, double& sum, double& err) {
  sum = a + b;
  const double bv = sum - a;
  const double av = sum - bv;
  err = (a - av) + (b - bv);
}

// Returns +1 if c lies to the left of the directed line a→b (counter-clockwise triangle),
// -1 if to the right, 0 if the three points are collinear. Exact.
inline int orient2d_sign(double ax, double ay, double bx, double by, double cx, double cy) {
  // Six products, each as an exact pair (p, e) with p + e = the real product.
  const std::array<double, 6> lhs{ax, -ay, bx, -by, cx, -cy};
  const std::array<double, 6> rhs{by, bx, cy, cx, ay, ax};
  std::array<double, 12> terms{};
  for (std::size_t i = 0; i < 6; ++i) {
    const double p = lhs[i] * rhs[i];
    terms[2 * i] = p;
    terms[2 * i + 1] = std::fma(lhs[i], rhs[i], -p);
  }
  // Grow a non-overlapping expansion (increasing magnitude) one term at a time.
  std::array<double, 13> expansion{};
  std::size_t length = 0;
  for (const double term : terms) {
    double q = term;
    std::size_t out = 0;
    for (std::size_t i = 0; i < length; ++i) {
      double sum = 0, err = 0;
      two_sum(q, expansion[i], sum, err);
      q = sum;
      if (err != 0) expansion[out++] = err;
    }
    if (q != 0) expansion[out++] = q;
    length = out;
  }
  if (length == 0) return 0;
  const double top = expansion[length - 1];
  return top > 0 ? 1 : (top < 0 ? -1 : 0);
}

}  // namespace tinstream::tile::detail
