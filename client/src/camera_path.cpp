#include "tinstream/client/camera_path.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace tinstream::client {

double CameraPath::duration() const {
  double total = 0;
  for (std::size_t i = 1; i < steps.size(); ++i)
    if (!steps[i].wait_complete) total += steps[i].seconds;
  return total;
}

Result<CameraPath> parse_camera_path(std::string_view text) {
  CameraPath path;
  std::size_t line_no = 0;
  std::istringstream in{std::string(text)};
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::string first, second, extra;
    if (!(words >> first)) continue;
    const std::string where = "camera path line " + std::to_string(line_no) + ": ";
    if (!(words >> second) || (words >> extra))
      return invalid_argument(
          where + "expected \"SECONDS lon,lat,height[,heading[,pitch]]\" or \"wait complete\"");
    CameraPath::Step step;
    if (first == "wait") {
      if (second != "complete") return invalid_argument(where + "only \"wait complete\" is known");
      if (path.steps.empty())
        return invalid_argument(where + "the path must start with a keyframe");
      step.wait_complete = true;
    } else {
      const auto [ptr, ec] =
          std::from_chars(first.data(), first.data() + first.size(), step.seconds);
      if (ec != std::errc() || ptr != first.data() + first.size() || !std::isfinite(step.seconds) ||
          step.seconds < 0)
        return invalid_argument(std::string(where).append("\"").append(first).append(
            "\" is not a duration in seconds"));
      auto pose = parse_camera_pose(second);
      if (!pose) return invalid_argument(where + pose.error().message);
      step.pose = *pose;
    }
    path.steps.push_back(step);
  }
  if (path.steps.empty()) return invalid_argument("camera path: no keyframe");
  return path;
}

Result<CameraPath> load_camera_path(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) return not_found("camera path " + file.string() + " cannot be read");
  std::stringstream text;
  text << in.rdbuf();
  auto path = parse_camera_path(text.str());
  if (!path) return Error(path.error().code, file.string() + ": " + path.error().message);
  return path;
}

CameraPose interpolate(const CameraPose& a, const CameraPose& b, double t) {
  const auto short_way = [](double from, double to, double period) {
    double d = std::fmod(to - from, period);
    if (d > period / 2) d -= period;
    if (d < -period / 2) d += period;
    return d;
  };
  CameraPose p;
  p.lon = a.lon + short_way(a.lon, b.lon, 360) * t;
  if (p.lon > 180) p.lon -= 360;
  if (p.lon < -180) p.lon += 360;
  p.lat = a.lat + (b.lat - a.lat) * t;
  p.height = a.height > 1 && b.height > 1 ? a.height * std::pow(b.height / a.height, t)
                                          : a.height + (b.height - a.height) * t;
  p.heading = std::fmod(a.heading + short_way(a.heading, b.heading, 360) * t + 360, 360);
  p.pitch = a.pitch + (b.pitch - a.pitch) * t;
  return p;
}

PathPlayer::PathPlayer(CameraPath path) : path_(std::move(path)), from_(path_.steps.front().pose) {}

CameraPose PathPlayer::advance(double seconds, bool view_complete) {
  t_ += seconds;
  while (next_ < path_.steps.size()) {
    const CameraPath::Step& step = path_.steps[next_];
    if (step.wait_complete) {
      if (!view_complete) {
        t_ = 0;
        return from_;
      }
      ++next_;
      t_ = 0;
      view_complete = false;  // the next wait needs a view completed after this one
      continue;
    }
    if (t_ < step.seconds) return interpolate(from_, step.pose, t_ / step.seconds);
    t_ -= step.seconds;
    from_ = step.pose;
    ++next_;
  }
  return from_;
}

}  // namespace tinstream::client
