// tinstream/client/navigation.hpp — moving the camera over the globe (the window's mouse and
// keyboard), as pure functions of a Camera so that they can be tested without a window.
//
//   pan            drag the globe: the grabbed point stays under the cursor
//   orbit          turn heading / tilt around a pivot on the terrain, keeping it in place
//   zoom_towards   move towards the point under the cursor by a factor of the distance
//   fly            keyboard flight in the local horizontal plane, speed ∝ height
//   look           turn the camera in place
//   FlyTo          an animated flight between two poses (up and over for long distances)
// Doubles throughout; thread-compatible.
#pragma once

#include "tinstream/client/camera.hpp"
#include "tinstream/client/camera_path.hpp"

namespace tinstream::client {

// v rotated by `angle` radians about the unit axis (right-handed).
Vec3 rotate(Vec3 v, Vec3 axis, double angle);

// Rotates the camera about the Earth's centre so that the ray through pixel (px, py) meets the
// sphere through `grabbed` at `grabbed` again.
void pan(Camera& camera, Vec3 grabbed, double px, double py);
// Heading turns about the ellipsoid normal at `pivot`; tilt about the camera's right axis through
// it. A tilt that would take the camera below the pivot's horizon (or past straight down) is
// left out.
void orbit(Camera& camera, Vec3 pivot, double heading_rad, double tilt_rad);
// Moves the camera towards `target` to factor × its distance (factor < 1 approaches).
void zoom_towards(Camera& camera, Vec3 target, double factor);
// Moves by (forward, right, up) metres in the local frame (forward: the heading's direction on
// the horizontal plane), keeping heading and pitch.
void fly(Camera& camera, double forward_m, double right_m, double up_m);
// Turns the camera in place.
void look(Camera& camera, double heading_deg, double pitch_deg);

class FlyTo {
 public:
  FlyTo() = default;
  FlyTo(const CameraPose& from, const CameraPose& to, double seconds);
  bool active() const { return active_; }
  // Advances the animation; the pose of this frame (the destination once finished).
  CameraPose advance(double seconds);

 private:
  CameraPose from_, to_;
  double duration_ = 0, t_ = 0, arc_m_ = 0;
  bool active_ = false;
};

}  // namespace tinstream::client
