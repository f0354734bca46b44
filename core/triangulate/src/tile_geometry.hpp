// Private: the small geometric tests pass 3 shares between gathering a tile's halo (halo.cpp)
// and cutting the tile at its border (border_cut.cpp). Rectangles are closed; "conservative"
// tests may answer true when the exact answer is false, never the other way.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "tinstream/geo/tile_id.hpp"
#include "tinstream/kernel/predicates.hpp"
#include "tinstream/subdivide/sorted_run.hpp"

namespace tinstream::triangulate::detail {

using kernel::XY;
using subdivide::SortedPoint;

// No edge point closer than this to a corner, and no two vertices of a tile closer than this
// (normalised units; `tinstream verify` rejects a tile with such a pair).
constexpr double kMinVertexDistance = 1e-12;

// A sub-cell's or tile's key in the hash maps: (x << 32) | y.
inline std::uint64_t pack(std::uint32_t x, std::uint32_t y) {
  return (static_cast<std::uint64_t>(x) << 32) | y;
}

struct Circle {
  double cx = 0, cy = 0, r2 = 0;
  bool unbounded = false;  // degenerate or enormous: reaches everything on one side
};

// The circumcircle of abc in floating point; unbounded when it is not finite or has r² > 16.
inline Circle circumcircle(const XY& a, const XY& b, const XY& c) {
  const double bx = b.x - a.x, by = b.y - a.y;
  const double qx = c.x - a.x, qy = c.y - a.y;
  const double d = 2.0 * (bx * qy - by * qx);
  const double b2 = bx * bx + by * by, q2 = qx * qx + qy * qy;
  const double ux = (qy * b2 - by * q2) / d;
  const double uy = (bx * q2 - qx * b2) / d;
  Circle circle{a.x + ux, a.y + uy, ux * ux + uy * uy, false};
  if (!std::isfinite(circle.cx) || !std::isfinite(circle.cy) || !std::isfinite(circle.r2) ||
      circle.r2 > 16.0) {
    circle.unbounded = true;
  }
  return circle;
}

// The radius with the relative margin every halo test of a circle uses.
inline double padded_radius(const Circle& c) { return std::sqrt(c.r2) * (1.0 + 1e-9); }

// Conservative: true whenever the circle may meet the rectangle.
inline bool circle_meets(const Circle& c, const geo::MercatorRect& r) {
  if (c.unbounded) return true;
  const double dx = std::max({r.min_x - c.cx, 0.0, c.cx - r.max_x});
  const double dy = std::max({r.min_y - c.cy, 0.0, c.cy - r.max_y});
  return dx * dx + dy * dy <= c.r2 * (1.0 + 1e-9) + 1e-300;
}

// Whether the bounding box of abc meets the rectangle.
inline bool bbox_meets(const XY& a, const XY& b, const XY& c, const geo::MercatorRect& r) {
  return std::max({a.x, b.x, c.x}) >= r.min_x && std::min({a.x, b.x, c.x}) <= r.max_x &&
         std::max({a.y, b.y, c.y}) >= r.min_y && std::min({a.y, b.y, c.y}) <= r.max_y;
}

// Conservative: true whenever triangle abc may meet the border ∂R of the rectangle — its bounding
// box meets R and does not lie in R's open interior. (A triangle meeting R with a vertex on or
// outside ∂R meets ∂R, since it is convex; one with all vertices strictly inside R does not.)
inline bool bbox_meets_border(const XY& a, const XY& b, const XY& c, const geo::MercatorRect& r) {
  if (!bbox_meets(a, b, c, r)) return false;
  const bool strictly_inside =
      std::min({a.x, b.x, c.x}) > r.min_x && std::max({a.x, b.x, c.x}) < r.max_x &&
      std::min({a.y, b.y, c.y}) > r.min_y && std::max({a.y, b.y, c.y}) < r.max_y;
  return !strictly_inside;
}

inline geo::MercatorRect cell_rect(std::uint32_t level, std::uint32_t cx, std::uint32_t cy) {
  return geo::TileId{level, cx, cy}.bounds();
}

// The canonical (lexicographic) order of points: both tiles beside a border order an edge's
// endpoints alike, so they compute the same bits from it.
inline bool lex_less(const SortedPoint& a, const SortedPoint& b) {
  return a.x < b.x || (a.x == b.x && a.y < b.y);
}

}  // namespace tinstream::triangulate::detail
