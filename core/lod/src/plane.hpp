// The linear interpolant of one triangle, set up once and evaluated at many points (the greedy
// stage's re-filing, the drop stage's orphans). Internal to core/lod.
#pragma once

#include <algorithm>

#include "tinstream/kernel/mesh.hpp"

namespace tinstream::lod::detail {

// The linear interpolant of one triangle, set up once for many points: barycentric weights
// relative to its first corner (for accuracy far from the origin).
struct Plane {
  double ax, ay, az, bx, by, cx, cy, dzb, dzc, inv_det;

  Plane(const kernel::XY& a, const kernel::XY& b, const kernel::XY& c, double za, double zb,
        double zc) {
    ax = a.x, ay = a.y, az = za;
    bx = b.x - ax, by = b.y - ay, cx = c.x - ax, cy = c.y - ay;
    dzb = zb - za, dzc = zc - za;
    inv_det = 1.0 / (bx * cy - by * cx);
  }
  // The smallest barycentric weight at (x, y): ≥ 0 inside (up to rounding).
  double min_weight(double x, double y) const {
    const double qx = x - ax, qy = y - ay;
    const double wb = (qx * cy - qy * cx) * inv_det;
    const double wc = (bx * qy - by * qx) * inv_det;
    return std::min(std::min(wb, wc), 1.0 - wb - wc);
  }
  // Whether min_weight(x, y) ≥ 0 (the same arithmetic, stopping at the first negative weight);
  // if so, *z = the height at (x, y), as at() gives it.
  bool contains(double x, double y, double* z) const {
    const double qx = x - ax, qy = y - ay;
    const double wb = (qx * cy - qy * cx) * inv_det;
    if (!(wb >= 0)) return false;  // then min(min(wb, wc), …) < 0 or NaN
    const double wc = (bx * qy - by * qx) * inv_det;
    const double m = std::min(wb, wc);
    if (!(m >= 0)) return false;
    if (!(std::min(m, 1.0 - wb - wc) >= 0)) return false;
    *z = az + wb * dzb + wc * dzc;
    return true;
  }
  // Height at (x, y); *min_weight (≥ 0 inside up to rounding) the smallest barycentric weight.
  double at(double x, double y, double* min_weight) const {
    const double qx = x - ax, qy = y - ay;
    const double wb = (qx * cy - qy * cx) * inv_det;
    const double wc = (bx * qy - by * qx) * inv_det;
    *min_weight = std::min(std::min(wb, wc), 1.0 - wb - wc);
    return az + wb * dzb + wc * dzc;
  }
};

}  // namespace tinstream::lod::detail
