#include "tinstream/client/navigation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "tinstream/geo/ecef.hpp"

namespace tinstream::client {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;

Vec3 geodetic_up(Vec3 p) {
  const geo::Geodetic g = geo::from_ecef({p.x, p.y, p.z});
  return enu_frame(g.lon, g.lat)[2];
}
}  // namespace

Vec3 rotate(Vec3 v, Vec3 axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return v * c + cross(axis, v) * s + axis * (dot(axis, v) * (1 - c));
}

void pan(Camera& camera, Vec3 grabbed, double px, double py) {
  const Vec3 origin = camera.position();
  const Vec3 dir = camera.ray_direction(px, py);
  const double r = length(grabbed);
  // Where the ray meets the sphere of radius r (or comes closest to it).
  const double b = dot(origin, dir), c = dot(origin, origin) - r * r;
  const double disc = b * b - c;
  Vec3 hit = disc >= 0 ? origin + dir * (-b - std::sqrt(disc)) : origin + dir * (-b);
  if (length(hit) == 0) return;
  hit = normalize(hit) * r;
  const Vec3 axis = cross(hit, grabbed);
  const double s = length(axis);
  if (s < 1e-12 * r * r) return;
  const double angle = std::atan2(s, dot(hit, grabbed));
  const Vec3 unit = axis / s;
  camera.set_frame(rotate(origin, unit, angle), rotate(camera.forward(), unit, angle),
                   rotate(camera.up(), unit, angle));
}

void orbit(Camera& camera, Vec3 pivot, double heading_rad, double tilt_rad) {
  const Vec3 up = geodetic_up(pivot);
  Vec3 pos = pivot + rotate(camera.position() - pivot, up, heading_rad);
  Vec3 forward = rotate(camera.forward(), up, heading_rad);
  Vec3 cam_up = rotate(camera.up(), up, heading_rad);
  const Vec3 right = normalize(cross(forward, cam_up));
  const Vec3 tilted_pos = pivot + rotate(pos - pivot, right, tilt_rad);
  const Vec3 tilted_forward = rotate(forward, right, tilt_rad);
  // Stay above the pivot's horizon (1°) and never look beyond straight down.
  const Vec3 offset = tilted_pos - pivot;
  const bool above = dot(offset, up) > std::sin(1 * kDeg) * length(offset);
  const bool not_over = dot(cross(tilted_forward, up), right) >= -1e-9;
  if (above && not_over) {
    pos = tilted_pos;
    forward = tilted_forward;
    cam_up = rotate(cam_up, right, tilt_rad);
  }
  camera.set_frame(pos, forward, cam_up);
}

void zoom_towards(Camera& camera, Vec3 target, double factor) {
  const Vec3 offset = camera.position() - target;
  if (factor < 1 && length(offset) * factor < 1.0) return;  // not closer than a metre
  camera.set_frame(target + offset * factor, camera.forward(), camera.up());
}

void fly(Camera& camera, double forward_m, double right_m, double up_m) {
  const CameraPose pose = camera.pose();
  const auto [east, north, up] = enu_frame(pose.lon, pose.lat);
  const double h = pose.heading * kDeg;
  const Vec3 ahead = east * std::sin(h) + north * std::cos(h);
  const Vec3 right = east * std::cos(h) - north * std::sin(h);
  const Vec3 p = camera.position() + ahead * forward_m + right * right_m + up * up_m;
  const geo::Geodetic g = geo::from_ecef({p.x, p.y, p.z});
  camera.set_pose({g.lon, g.lat, g.height, pose.heading, pose.pitch});
}

void look(Camera& camera, double heading_deg, double pitch_deg) {
  CameraPose pose = camera.pose();
  pose.heading = std::fmod(pose.heading + heading_deg + 360, 360);
  pose.pitch = std::clamp(pose.pitch + pitch_deg, -90.0, 90.0);
  camera.set_pose(pose);
}

FlyTo::FlyTo(const CameraPose& from, const CameraPose& to, double seconds)
    : from_(from), to_(to), duration_(std::max(seconds, 1e-3)), active_(true) {
  // Up and over: rise by half the great-circle distance (at most 5000 km) at mid-flight.
  const double a = from.lat * kDeg, b = to.lat * kDeg, dl = (to.lon - from.lon) * kDeg;
  const double angle = std::acos(
      std::clamp(std::sin(a) * std::sin(b) + std::cos(a) * std::cos(b) * std::cos(dl), -1.0, 1.0));
  arc_m_ = std::min(0.5 * angle * geo::kWgs84A, 5e6);
}

CameraPose FlyTo::advance(double seconds) {
  if (!active_) return to_;
  t_ += seconds;
  if (t_ >= duration_) {
    active_ = false;
    return to_;
  }
  const double s = t_ / duration_;
  const double eased = s * s * (3 - 2 * s);
  CameraPose p = interpolate(from_, to_, eased);
  const double lift = arc_m_ * std::sin(std::numbers::pi * eased);
  p.height += std::max(0.0, lift - std::max(from_.height, to_.height) * 0.5);
  return p;
}

}  // namespace tinstream::client
