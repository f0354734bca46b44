// tinstream/kernel/predicates.hpp — exact adaptive geometric predicates (layer 1 of the kernel).
//
// Contract: orient2d and incircle return a value whose *sign* is exactly the sign of the
// determinant computed in exact real arithmetic from the double inputs (the magnitude is only an
// approximation). The method is Shewchuk's (1996): a cheap floating-point evaluation with a
// forward error bound; only when the bound cannot certify the sign is the determinant evaluated
// again with floating-point expansion arithmetic (src/predicates.cpp), first assuming the
// coordinate differences are exact, then fully exactly.
//
// Range: exactness assumes no overflow or underflow in the intermediate products, i.e. all
// coordinate magnitudes and differences within about [1e-60, 1e60] for incircle (degree 4) and
// [1e-140, 1e140] for orient2d (degree 2). Normalised Mercator coordinates are far inside.
// Pure functions, no state: safe to call from any thread.
#pragma once

namespace tinstream::kernel {

struct XY {
  double x;
  double y;
};

namespace detail {
// Machine epsilon as Shewchuk defines it: half an ulp of 1 (2^-53).
inline constexpr double kEpsilon = 0x1p-53;
inline constexpr double kOrientBoundA = (3.0 + 16.0 * kEpsilon) * kEpsilon;
inline constexpr double kIncircleBoundA = (10.0 + 96.0 * kEpsilon) * kEpsilon;

// Slow paths: exact sign (returned as a double of that sign).
double orient2d_exact(const XY& a, const XY& b, const XY& c);
double incircle_exact(const XY& a, const XY& b, const XY& c, const XY& d);
// perturbed_incircle's tie case (a, b, c, d exactly cocircular).
int perturbed_tie(const XY& a, const XY& b, const XY& c, const XY& d);
}  // namespace detail

// > 0 when a, b, c turn counter-clockwise, < 0 clockwise, 0 when collinear.
inline double orient2d(const XY& a, const XY& b, const XY& c) {
  const double left = (a.x - c.x) * (b.y - c.y);
  const double right = (a.y - c.y) * (b.x - c.x);
  const double det = left - right;
  // Shewchuk's bound on |left + right| when the two products have the same sign, written without
  // branching on their signs (those branches were mispredicted about as often as not). With
  // opposite signs or a zero product there is no cancellation, |det| >= (|left| + |right|)(1 - eps)
  // passes the test and its sign is right; with left = right = 0, det = 0 is exact.
  const double bound = detail::kOrientBoundA * (__builtin_fabs(left) + __builtin_fabs(right));
  if (__builtin_fabs(det) >= bound) return det;
  return detail::orient2d_exact(a, b, c);
}

// > 0 when d lies strictly inside the circle through a, b, c (which must be counter-clockwise;
// for clockwise a, b, c the sign flips), < 0 outside, 0 on the circle.
inline double incircle(const XY& a, const XY& b, const XY& c, const XY& d) {
  const double adx = a.x - d.x, ady = a.y - d.y;
  const double bdx = b.x - d.x, bdy = b.y - d.y;
  const double cdx = c.x - d.x, cdy = c.y - d.y;
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double alift = adx * adx + ady * ady;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double blift = bdx * bdx + bdy * bdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double clift = cdx * cdx + cdy * cdy;
  const double det =
      alift * (bdxcdy - cdxbdy) + blift * (cdxady - adxcdy) + clift * (adxbdy - bdxady);
  const double permanent = (__builtin_fabs(bdxcdy) + __builtin_fabs(cdxbdy)) * alift +
                           (__builtin_fabs(cdxady) + __builtin_fabs(adxcdy)) * blift +
                           (__builtin_fabs(adxbdy) + __builtin_fabs(bdxady)) * clift;
  const double bound = detail::kIncircleBoundA * permanent;
  if (det > bound || -det > bound) return det;
  return detail::incircle_exact(a, b, c, d);
}

// incircle under a symbolic perturbation that breaks ties (cocircular points) by the points
// alone: each point is lifted onto the paraboloid and then raised by δ(p), where δ grows with
// the lexicographic rank of p (x, then y) and each rank's δ dominates all lower ones. For four
// cocircular points the sign is then the sign of the cofactor of the highest-ranked point
// (never zero: no three points of a circle are collinear). The perturbed point set is in
// general position, so its Delaunay triangulation is unique — the *canonical* one, the same
// whatever the insertion order, which lets two triangulations of overlapping point sets agree.
// +1 when d is inside the circle through the counter-clockwise a, b, c under the perturbation,
// -1 outside (never 0 for distinct points with a, b, c not collinear).
inline int perturbed_incircle(const XY& a, const XY& b, const XY& c, const XY& d) {
  const double exact = incircle(a, b, c, d);
  if (exact > 0.0) return 1;
  if (exact < 0.0) return -1;
  return detail::perturbed_tie(a, b, c, d);
}

inline int sign(double v) { return (v > 0.0) - (v < 0.0); }

}  // namespace tinstream::kernel
