// tinstream/client/bounds.hpp — bounding volumes of tiles in ECEF and the ellipsoid's horizon.
//
// Two volumes per tile (../shared/DESIGN.md §6, the client; docs/DESIGN.md has no client section):
//  * before a tile is loaded, rectangle_aabb(): the exact axis-aligned ECEF box of its geodetic
//    rectangle between two heights. Exact because each ECEF coordinate is monotone in latitude
//    and height and a cosine/sine in longitude, so its extremes lie at rectangle corners, at the
//    latitude nearest the equator, or at longitudes 0, ±90, 180 (see bounds.cpp);
//  * once loaded, the tile mesh's Obb: a box in the tile's local east/north/up frame fitted to
//    every vertex it will draw (skirts included), hence tight and containing them by construction.
// HorizonOccluder hides what lies behind the WGS84 ellipsoid (shrunk to the lowest terrain).
// Pure value types and functions; thread-safe.
#pragma once

#include <array>
#include <span>

#include "tinstream/client/vec.hpp"
#include "tinstream/geo/tile_id.hpp"

namespace tinstream::client {

struct Aabb {
  Vec3 min, max;
  bool contains(Vec3 p) const {
    return p.x >= min.x && p.x <= max.x && p.y >= min.y && p.y <= max.y && p.z >= min.z &&
           p.z <= max.z;
  }
};

// An oriented box: centre + Σ t_i·axis_i with t_i ∈ [-half_i, half_i]; axes orthonormal.
struct Obb {
  Vec3 centre;
  std::array<Vec3, 3> axis{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
  std::array<double, 3> half{0, 0, 0};

  static Obb from_aabb(const Aabb& box);
  std::array<Vec3, 8> corners() const;
  // Euclidean distance from p to the box (0 inside).
  double distance_to(Vec3 p) const;
  // p's coordinates in the box frame lie within the half extents.
  bool contains(Vec3 p) const;
};

// The exact ECEF box of the geodetic rectangle `r` (degrees, south < north, west < east, within
// [-180, 180] × (-90, 90)) between ellipsoidal heights min_h ≤ max_h (|h| ≪ the Earth's radius),
// widened by 1 mm plus a relative 1e-12 so that rounding in the ECEF conversion can never leave a
// point of the rectangle outside it.
Aabb rectangle_aabb(const geo::LonLatRect& r, double min_h, double max_h);

// A box in the local east/north/up frame of the rectangle's centre that contains
// rectangle × [min_h, max_h]: fitted to a 5 × 5 grid of samples at both heights and widened by the
// sagitta of the longest sample cell (what the curved surface can bulge out between samples).
// Much tighter than rectangle_aabb for small tiles, whose ECEF-aligned box is tilted against the
// ground; rectangles wider than 30° get rectangle_aabb's box.
Obb rectangle_obb(const geo::LonLatRect& r, double min_h, double max_h);

// The local frame of the ellipsoid at (lon, lat) (degrees): east, north, up (the ellipsoid normal).
std::array<Vec3, 3> enu_frame(double lon_deg, double lat_deg);

// The box in the frame `axes` (orthonormal) around `origin` that holds every point, padded by
// 1 mm plus 1e-9 of its size against rounding. Requires: points is not empty.
Obb fit_obb(std::span<const Vec3> points, Vec3 origin, const std::array<Vec3, 3>& axes);

// The WGS84 ellipsoid lowered by `depth` metres (≥ 0: its semi-axes minus depth, which lies
// inside the surface at height −depth): everything behind it, seen from the camera, is hidden.
// Exact region test in the ellipsoid's unit-sphere space, where the hidden region (the tangent
// cone's part beyond the horizon circle, with the ellipsoid's inside) is convex: a box is hidden
// when its eight corners are.
class HorizonOccluder {
 public:
  explicit HorizonOccluder(double depth = 0);
  // True when the segment from `camera` to p meets the occluding ellipsoid before p (or p is
  // inside it). A camera inside the ellipsoid occludes nothing.
  bool hides(Vec3 camera, Vec3 p) const;
  bool hides_all(Vec3 camera, std::span<const Vec3> points) const;

 private:
  double inv_a_, inv_b_;  // 1 / semi-axes
};

}  // namespace tinstream::client
