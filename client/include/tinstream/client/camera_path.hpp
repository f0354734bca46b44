// tinstream/client/camera_path.hpp — scripted flights (`--camera-path FILE`), for benchmarks and
// tests.
//
// One step per line; '#' starts a comment:
//   SECONDS lon,lat,height[,heading[,pitch]]   fly to this pose in SECONDS (the first line's
//                                              SECONDS is ignored: the flight starts there)
//   wait complete                              stay until the view is complete (nothing pending)
// Between keyframes longitude/latitude and pitch move linearly, heading the short way round and
// height geometrically (a zoom looks uniform). Value types; thread-compatible.
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/camera.hpp"

namespace tinstream::client {

struct CameraPath {
  struct Step {
    bool wait_complete = false;
    double seconds = 0;
    CameraPose pose;
  };
  std::vector<Step> steps;  // steps[0] is a keyframe
  double duration() const;  // flight time, waits excluded
};

// Errors name the line. Requires a keyframe first.
Result<CameraPath> parse_camera_path(std::string_view text);
Result<CameraPath> load_camera_path(const std::filesystem::path& file);

CameraPose interpolate(const CameraPose& a, const CameraPose& b, double t);

// Plays a path frame by frame.
class PathPlayer {
 public:
  explicit PathPlayer(CameraPath path);
  // Moves `seconds` on and returns the pose for this frame; `view_complete` says whether the last
  // frame's view was complete (it ends a `wait complete`).
  CameraPose advance(double seconds, bool view_complete);
  bool finished() const { return next_ >= path_.steps.size(); }
  bool waiting() const { return !finished() && path_.steps[next_].wait_complete; }

 private:
  CameraPath path_;
  std::size_t next_ = 1;  // the step being flown towards (or waited on)
  CameraPose from_;       // the keyframe the current segment starts at
  double t_ = 0;          // seconds into the current segment
};

}  // namespace tinstream::client
