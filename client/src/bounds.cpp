#include "tinstream/client/bounds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "tinstream/geo/ecef.hpp"

namespace tinstream::client {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Distance from the polar axis and height above the equatorial plane of (lat, h) on WGS84:
// r = (N + h)·cos φ and z = (N(1 − e²) + h)·sin φ, through the same conversion as the vertices.
struct Meridian {
  double r, z;
};
Meridian meridian_point(double lat_deg, double h) {
  const geo::Ecef e = geo::to_ecef({0.0, lat_deg, h});
  return {e.x, e.z};
}

double pad(double v) { return 1e-3 + 1e-12 * std::abs(v); }

}  // namespace

// Why the box is exact. With M(φ) the meridian radius of curvature, dr/dφ = −(M + h)·sin φ and
// dz/dφ = (M + h)·cos φ, both with M + h > 0 for |h| ≪ a: r falls as |φ| grows and z rises with
// φ; ∂r/∂h = cos φ ≥ 0 and ∂z/∂h = sin φ. So r spans [r(φ_far, h_min), r(φ_near, h_max)] (φ_near
// the latitude closest to the equator, φ_far the farthest) and z's extremes are at the north and
// south edges with the height that sin φ favours. x = r·cos λ and y = r·sin λ with r > 0: the
// cosine and sine of the longitude interval take their extremes at its ends or at 0, ±90, ±180.
Aabb rectangle_aabb(const geo::LonLatRect& rect, double min_h, double max_h) {
  const double near_lat = std::clamp(0.0, rect.south, rect.north);
  const double far_lat = std::abs(rect.south) > std::abs(rect.north) ? rect.south : rect.north;
  const double r_max = meridian_point(near_lat, max_h).r;
  const double r_min = meridian_point(far_lat, min_h).r;
  const double z_max = meridian_point(rect.north, rect.north > 0 ? max_h : min_h).z;
  const double z_min = meridian_point(rect.south, rect.south < 0 ? max_h : min_h).z;

  const double w = rect.west * kDeg, e = rect.east * kDeg;
  const auto contains = [&](double deg) { return rect.west <= deg && deg <= rect.east; };
  const double cos_max = contains(0) ? 1.0 : std::max(std::cos(w), std::cos(e));
  const double cos_min =
      contains(180) || contains(-180) ? -1.0 : std::min(std::cos(w), std::cos(e));
  const double sin_max = contains(90) ? 1.0 : std::max(std::sin(w), std::sin(e));
  const double sin_min = contains(-90) ? -1.0 : std::min(std::sin(w), std::sin(e));
  // r·c over r ∈ [r_min, r_max]: the larger r where c pushes outward, the smaller where inward.
  const auto low = [&](double c) { return c >= 0 ? r_min * c : r_max * c; };
  const auto high = [&](double c) { return c >= 0 ? r_max * c : r_min * c; };

  Aabb box{{low(cos_min), low(sin_min), z_min}, {high(cos_max), high(sin_max), z_max}};
  box.min = {box.min.x - pad(box.min.x), box.min.y - pad(box.min.y), box.min.z - pad(box.min.z)};
  box.max = {box.max.x + pad(box.max.x), box.max.y + pad(box.max.y), box.max.z + pad(box.max.z)};
  return box;
}

// The surface of a cell between samples bulges out of their hull by at most its sagitta,
// d²/(8R) for a chord d on a sphere of radius R; the ellipsoid's smallest radius of curvature is
// b²/a (at the equator, along the meridian), lowered by the depth of the lowest height.
Obb rectangle_obb(const geo::LonLatRect& rect, double min_h, double max_h) {
  constexpr std::size_t kSteps = 4;
  if (rect.east - rect.west > 30 || rect.north - rect.south > 30)
    return Obb::from_aabb(rectangle_aabb(rect, min_h, max_h));
  const double lon0 = (rect.west + rect.east) / 2, lat0 = (rect.south + rect.north) / 2;
  const geo::Ecef c = geo::to_ecef({lon0, lat0, (min_h + max_h) / 2});
  std::vector<Vec3> samples;
  samples.reserve(2 * (kSteps + 1) * (kSteps + 1));
  double diagonal = 0;
  for (std::size_t j = 0; j <= kSteps; ++j) {
    const double lat = rect.south + (rect.north - rect.south) * static_cast<double>(j) /
                                        static_cast<double>(kSteps);
    for (std::size_t i = 0; i <= kSteps; ++i) {
      const double lon = rect.west + (rect.east - rect.west) * static_cast<double>(i) /
                                         static_cast<double>(kSteps);
      for (const double h : {min_h, max_h}) {
        const geo::Ecef e = geo::to_ecef({lon, lat, h});
        samples.push_back({e.x, e.y, e.z});
      }
      if (i > 0 && j > 0) {  // the cell ending here, at its top height (the longest chords)
        const std::size_t n = samples.size();
        const std::size_t row = 2 * (kSteps + 1);
        diagonal = std::max({diagonal, length(samples[n - 1] - samples[n - 1 - row - 2]),
                             length(samples[n - 3] - samples[n - 1 - row])});
      }
    }
  }
  const double b = geo::kWgs84A * (1 - geo::kWgs84F);
  const double radius = b * b / geo::kWgs84A + std::min(min_h, 0.0) - 1000.0;
  const double sagitta = 1.01 * diagonal * diagonal / (8 * radius) + 1e-3;
  Obb box = fit_obb(samples, {c.x, c.y, c.z}, enu_frame(lon0, lat0));
  for (double& h : box.half) h += sagitta;
  return box;
}

std::array<Vec3, 3> enu_frame(double lon_deg, double lat_deg) {
  const double lon = lon_deg * kDeg, lat = lat_deg * kDeg;
  const double sl = std::sin(lon), cl = std::cos(lon), sp = std::sin(lat), cp = std::cos(lat);
  return {Vec3{-sl, cl, 0}, Vec3{-sp * cl, -sp * sl, cp}, Vec3{cp * cl, cp * sl, sp}};
}

Obb Obb::from_aabb(const Aabb& box) {
  Obb o;
  o.centre = (box.min + box.max) * 0.5;
  o.half = {(box.max.x - box.min.x) * 0.5, (box.max.y - box.min.y) * 0.5,
            (box.max.z - box.min.z) * 0.5};
  return o;
}

std::array<Vec3, 8> Obb::corners() const {
  std::array<Vec3, 8> c;
  for (int i = 0; i < 8; ++i) {
    c[static_cast<std::size_t>(i)] = centre + axis[0] * ((i & 1) ? half[0] : -half[0]) +
                                     axis[1] * ((i & 2) ? half[1] : -half[1]) +
                                     axis[2] * ((i & 4) ? half[2] : -half[2]);
  }
  return c;
}

double Obb::distance_to(Vec3 p) const {
  const Vec3 d = p - centre;
  double sum = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    const double excess = std::max(std::abs(dot(d, axis[i])) - half[i], 0.0);
    sum += excess * excess;
  }
  return std::sqrt(sum);
}

bool Obb::contains(Vec3 p) const {
  const Vec3 d = p - centre;
  for (std::size_t i = 0; i < 3; ++i)
    if (std::abs(dot(d, axis[i])) > half[i]) return false;
  return true;
}

Obb fit_obb(std::span<const Vec3> points, Vec3 origin, const std::array<Vec3, 3>& axes) {
  std::array<double, 3> lo{}, hi{};
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (const Vec3& p : points) {
    const Vec3 d = p - origin;
    for (std::size_t i = 0; i < 3; ++i) {
      const double t = dot(d, axes[i]);
      lo[i] = std::min(lo[i], t);
      hi[i] = std::max(hi[i], t);
    }
  }
  Obb o;
  o.axis = axes;
  o.centre = origin;
  for (std::size_t i = 0; i < 3; ++i) {
    o.centre += axes[i] * ((lo[i] + hi[i]) * 0.5);
    const double half = (hi[i] - lo[i]) * 0.5;
    o.half[i] = half + 1e-3 + 1e-9 * (half + length(origin));
  }
  return o;
}

HorizonOccluder::HorizonOccluder(double depth)
    : inv_a_(1.0 / (geo::kWgs84A - depth)),
      inv_b_(1.0 / (geo::kWgs84A * (1.0 - geo::kWgs84F) - depth)) {}

// In the space scaled by the semi-axes the ellipsoid is the unit sphere and segments stay
// segments. From the camera c (|c| > 1) the sphere hides: its inside, and the points of the cone
// of rays tangent to it that lie beyond the plane of the horizon circle (p·c < 1). A point p is
// in the cone when the angle between c − p and c is below asin(1/|c|):
// (c − p)·c ≥ |c − p|·sqrt(|c|² − 1).
bool HorizonOccluder::hides(Vec3 camera, Vec3 p) const {
  const Vec3 c{camera.x * inv_a_, camera.y * inv_a_, camera.z * inv_b_};
  const Vec3 q{p.x * inv_a_, p.y * inv_a_, p.z * inv_b_};
  const double cc = dot(c, c);
  if (cc <= 1.0) return false;
  if (dot(q, q) < 1.0) return true;
  if (dot(q, c) >= 1.0) return false;
  const Vec3 d = c - q;
  const double dc = dot(d, c);
  return dc > 0 && dc * dc >= dot(d, d) * (cc - 1.0);
}

bool HorizonOccluder::hides_all(Vec3 camera, std::span<const Vec3> points) const {
  return std::all_of(points.begin(), points.end(), [&](Vec3 p) { return hides(camera, p); });
}

}  // namespace tinstream::client
