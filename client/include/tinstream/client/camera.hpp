// tinstream/client/camera.hpp — a perspective camera on the WGS84 globe, all in double ECEF.
//
// A pose is what users type (`--camera lon,lat,height,heading,pitch`): degrees, metres above the
// ellipsoid, heading clockwise from north, pitch from the horizontal (−90 looks straight down),
// no roll. The camera itself is a position and an orthonormal frame (right, up, forward) in ECEF.
// Matrices are computed in double with the camera at the origin (model_view subtracts the camera
// from a tile's origin before anything becomes float), so a tile seen from 10 m is as steady as
// one seen from orbit. The projection is reversed-Z with an infinite far plane (depth = near / z,
// for a 32-bit float depth buffer with glClipControl(GL_ZERO_TO_ONE)); `log_depth` switches to a
// conventional infinite projection for drivers without clip control (the shader then writes a
// logarithmic depth). Value type; thread-compatible.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>

#include "tinstream/base/result.hpp"
#include "tinstream/client/bounds.hpp"
#include "tinstream/client/vec.hpp"

namespace tinstream::client {

struct CameraPose {
  double lon = 0, lat = 0;  // degrees
  double height = 1e7;      // metres above the WGS84 ellipsoid
  double heading = 0;       // degrees clockwise from north
  double pitch = -90;       // degrees, −90 = straight down
};

// Parses "lon,lat,height,heading,pitch" (heading and pitch optional: 0 and −90).
Result<CameraPose> parse_camera_pose(std::string_view text);
std::string to_string(const CameraPose& pose);

// Inward-facing planes n·(p − origin) ≥ offset, with |n| = 1.
struct Frustum {
  Vec3 origin;
  std::array<Vec3, 5> normal;  // near, left, right, bottom, top (no far plane)
  std::array<double, 5> offset;
  // False only when the box lies entirely outside one plane.
  bool intersects(const Obb& box) const;
};

class Camera {
 public:
  Camera(int width = 1280, int height = 720, double fov_y_deg = 60.0);

  void set_viewport(int width, int height);
  void set_fov_y(double degrees);
  void set_pose(const CameraPose& pose);
  // Requires: forward and up not parallel. The frame is re-orthonormalised.
  void set_frame(Vec3 position, Vec3 forward, Vec3 up);
  CameraPose pose() const;

  Vec3 position() const { return position_; }
  Vec3 forward() const { return forward_; }
  Vec3 up() const { return up_; }
  Vec3 right() const { return right_; }
  int width() const { return width_; }
  int height() const { return height_; }
  double fov_y() const { return fov_y_; }  // radians
  double near_plane() const { return near_; }
  bool log_depth = false;

  // Rotation of the world into eye space (camera at the origin, looking down −z).
  Mat4 view_rotation() const;
  // View matrix for geometry whose coordinates are relative to `origin` (ECEF).
  Mat4 model_view(Vec3 origin) const;
  Mat4 projection() const;
  Frustum frustum() const;
  // viewport height / (2·tan(fov_y / 2)): a length l at distance d covers l·factor/d pixels.
  double sse_factor() const;
  // Screen-space error in pixels of a geometric error seen from `distance` metres.
  double screen_space_error(double geometric_error, double distance) const;
  // The unit direction through pixel (px, py), pixels from the top-left corner.
  Vec3 ray_direction(double px, double py) const;
  // The pixel where p appears; nullopt behind the camera.
  std::optional<std::array<double, 2>> project(Vec3 p) const;

 private:
  void update_near();
  int width_, height_;
  double fov_y_;
  double near_ = 0.1;
  Vec3 position_, forward_{0, 0, -1}, up_{0, 1, 0}, right_{1, 0, 0};
};

// The point where the ray from `origin` along unit `dir` meets the ellipsoid raised by `height`,
// nearest first; nullopt when it misses.
std::optional<Vec3> intersect_ellipsoid(Vec3 origin, Vec3 dir, double height = 0);

// A pose that frames a lon/lat rectangle from above (pitch −60, heading 0, height such that the
// rectangle fills about two thirds of the view of `camera`).
CameraPose framing_pose(const geo::LonLatRect& rect, double ground_height, const Camera& camera);

}  // namespace tinstream::client
