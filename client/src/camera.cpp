#include "tinstream/client/camera.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <numbers>
#include <sstream>
#include <vector>

#include "tinstream/geo/ecef.hpp"

namespace tinstream::client {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Vec3 to_vec(const geo::Ecef& e) { return {e.x, e.y, e.z}; }

Result<double> parse_number(std::string_view text, const char* what) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  double v = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(v))
    return invalid_argument(std::string("camera: ") + what + " \"" + std::string(text) +
                            "\" is not a finite number");
  return v;
}

}  // namespace

Result<CameraPose> parse_camera_pose(std::string_view text) {
  std::vector<std::string_view> parts;
  for (std::size_t start = 0;;) {
    const std::size_t comma = text.find(',', start);
    parts.push_back(text.substr(start, comma == std::string_view::npos ? comma : comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (parts.size() < 3 || parts.size() > 5)
    return invalid_argument("camera \"" + std::string(text) +
                            "\": expected lon,lat,height[,heading[,pitch]]");
  static constexpr const char* kNames[] = {"longitude", "latitude", "height", "heading", "pitch"};
  double v[5] = {0, 0, 0, 0, -90};
  for (std::size_t i = 0; i < parts.size(); ++i) {
    auto n = parse_number(parts[i], kNames[i]);
    if (!n) return n.error();
    v[i] = *n;
  }
  if (v[0] < -180 || v[0] > 180) return invalid_argument("camera: longitude outside [-180, 180]");
  if (v[1] < -90 || v[1] > 90) return invalid_argument("camera: latitude outside [-90, 90]");
  if (v[2] < -1e4 || v[2] > 1e9) return invalid_argument("camera: height outside [-1e4, 1e9] m");
  if (v[4] < -90 || v[4] > 90) return invalid_argument("camera: pitch outside [-90, 90]");
  return CameraPose{v[0], v[1], v[2], v[3], v[4]};
}

std::string to_string(const CameraPose& p) {
  std::ostringstream s;
  s.precision(10);
  s << p.lon << ',' << p.lat << ',' << p.height << ',' << p.heading << ',' << p.pitch;
  return s.str();
}

bool Frustum::intersects(const Obb& box) const {
  const Vec3 c = box.centre - origin;
  for (std::size_t i = 0; i < normal.size(); ++i) {
    const Vec3 n = normal[i];
    const double radius = box.half[0] * std::abs(dot(n, box.axis[0])) +
                          box.half[1] * std::abs(dot(n, box.axis[1])) +
                          box.half[2] * std::abs(dot(n, box.axis[2]));
    if (dot(n, c) - offset[i] < -radius) return false;
  }
  return true;
}

Camera::Camera(int width, int height, double fov_y_deg)
    : width_(std::max(width, 1)), height_(std::max(height, 1)), fov_y_(fov_y_deg * kDeg) {
  set_pose(CameraPose{});
}

void Camera::set_viewport(int width, int height) {
  width_ = std::max(width, 1);
  height_ = std::max(height, 1);
}

void Camera::set_fov_y(double degrees) { fov_y_ = std::clamp(degrees, 1.0, 150.0) * kDeg; }

void Camera::set_pose(const CameraPose& p) {
  const auto [east, north, up] = enu_frame(p.lon, p.lat);
  const double h = p.heading * kDeg, pitch = p.pitch * kDeg;
  position_ = to_vec(geo::to_ecef({p.lon, p.lat, p.height}));
  forward_ = (east * std::sin(h) + north * std::cos(h)) * std::cos(pitch) + up * std::sin(pitch);
  right_ = east * std::cos(h) - north * std::sin(h);
  up_ = cross(right_, forward_);
  update_near();
}

void Camera::set_frame(Vec3 position, Vec3 forward, Vec3 up) {
  position_ = position;
  forward_ = normalize(forward);
  right_ = normalize(cross(forward_, up));
  up_ = cross(right_, forward_);
  update_near();
}

CameraPose Camera::pose() const {
  const geo::Geodetic g = geo::from_ecef({position_.x, position_.y, position_.z});
  const auto [east, north, up] = enu_frame(g.lon, g.lat);
  CameraPose p{g.lon, g.lat, g.height, 0, 0};
  const double fu = std::clamp(dot(forward_, up), -1.0, 1.0);
  p.pitch = std::asin(fu) / kDeg;
  const double fe = dot(forward_, east), fn = dot(forward_, north);
  const double heading = std::hypot(fe, fn) > 1e-9
                             ? std::atan2(fe, fn)
                             : std::atan2(-dot(right_, north), dot(right_, east));
  p.heading = heading / kDeg;
  if (p.heading < 0) p.heading += 360;
  if (p.heading >= 360) p.heading -= 360;
  return p;
}

void Camera::update_near() { near_ = 0.1; }

Mat4 Camera::view_rotation() const {
  Mat4 r = Mat4::identity();
  const std::array<Vec3, 3> rows{right_, up_, -forward_};
  for (std::size_t row = 0; row < 3; ++row) {
    r.m[0][row] = rows[row].x;
    r.m[1][row] = rows[row].y;
    r.m[2][row] = rows[row].z;
  }
  return r;
}

Mat4 Camera::model_view(Vec3 origin) const {
  return view_rotation() * translation(origin - position_);
}

Mat4 Camera::projection() const {
  const double f = 1.0 / std::tan(fov_y_ * 0.5);
  const double aspect = static_cast<double>(width_) / height_;
  Mat4 p;
  p.m[0][0] = f / aspect;
  p.m[1][1] = f;
  p.m[2][3] = -1;  // w_clip = −z_eye
  if (log_depth) {
    p.m[2][2] = -1;  // conventional infinite far plane; the shader writes the depth
    p.m[3][2] = -2 * near_;
  } else {
    p.m[3][2] = near_;  // z_clip = near: depth = near / −z_eye, 1 at the near plane, → 0 far away
  }
  return p;
}

Frustum Camera::frustum() const {
  const double ty = std::tan(fov_y_ * 0.5);
  const double tx = ty * width_ / height_;
  Frustum f;
  f.origin = position_;
  f.normal = {forward_, normalize(right_ + forward_ * tx), normalize(-right_ + forward_ * tx),
              normalize(up_ + forward_ * ty), normalize(-up_ + forward_ * ty)};
  f.offset = {near_, 0, 0, 0, 0};
  return f;
}

double Camera::sse_factor() const { return height_ / (2.0 * std::tan(fov_y_ * 0.5)); }

double Camera::screen_space_error(double geometric_error, double distance) const {
  return geometric_error * sse_factor() / std::max(distance, 1e-6);
}

Vec3 Camera::ray_direction(double px, double py) const {
  const double ty = std::tan(fov_y_ * 0.5);
  const double tx = ty * width_ / height_;
  const double x = 2.0 * px / width_ - 1.0, y = 1.0 - 2.0 * py / height_;
  return normalize(forward_ + right_ * (x * tx) + up_ * (y * ty));
}

std::optional<std::array<double, 2>> Camera::project(Vec3 p) const {
  const Vec3 d = p - position_;
  const double z = dot(d, forward_);
  if (z <= 0) return std::nullopt;
  const double ty = std::tan(fov_y_ * 0.5);
  const double tx = ty * width_ / height_;
  const double x = dot(d, right_) / (z * tx), y = dot(d, up_) / (z * ty);
  return std::array<double, 2>{(x + 1) * 0.5 * width_, (1 - y) * 0.5 * height_};
}

std::optional<Vec3> intersect_ellipsoid(Vec3 origin, Vec3 dir, double height) {
  const double a = geo::kWgs84A + height, b = geo::kWgs84A * (1 - geo::kWgs84F) + height;
  const Vec3 o{origin.x / a, origin.y / a, origin.z / b}, d{dir.x / a, dir.y / a, dir.z / b};
  const double qa = dot(d, d), qb = 2 * dot(o, d), qc = dot(o, o) - 1;
  const double disc = qb * qb - 4 * qa * qc;
  if (disc < 0) return std::nullopt;
  const double root = std::sqrt(disc);
  double t = (-qb - root) / (2 * qa);
  if (t < 0) t = (-qb + root) / (2 * qa);
  if (t < 0) return std::nullopt;
  return origin + dir * t;
}

CameraPose framing_pose(const geo::LonLatRect& rect, double ground_height, const Camera& camera) {
  const double lon = (rect.west + rect.east) * 0.5, lat = (rect.south + rect.north) * 0.5;
  const double width_m = (rect.east - rect.west) * kDeg * geo::kWgs84A * std::cos(lat * kDeg);
  const double height_m = (rect.north - rect.south) * kDeg * geo::kWgs84A;
  const double aspect = static_cast<double>(camera.width()) / camera.height();
  const double size = std::max({width_m / aspect, height_m, 50.0});
  const double distance = std::min(1.5 * size / (2 * std::tan(camera.fov_y() * 0.5)), 2.5e7);
  const auto [east, north, up] = enu_frame(lon, lat);
  const Vec3 target = to_vec(geo::to_ecef({lon, lat, ground_height}));
  const double pitch = 60 * kDeg;
  const Vec3 eye = target + (up * std::sin(pitch) - north * std::cos(pitch)) * distance;
  const geo::Geodetic g = geo::from_ecef({eye.x, eye.y, eye.z});
  Camera c = camera;
  c.set_frame(eye, target - eye, up);
  CameraPose p = c.pose();
  p.lon = g.lon;
  p.lat = g.lat;
  p.height = g.height;
  return p;
}

}  // namespace tinstream::client
