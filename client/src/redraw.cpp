// RedrawScheduler (redraw.hpp): the frames a window owes, and how long it may wait.
#include "tinstream/client/redraw.hpp"

#include <algorithm>

namespace tinstream::client {

std::uint64_t tier_evictions(const TileStreamer& streamer) {
  return streamer.gpu_counters().evictions + streamer.ram_counters().evictions +
         streamer.image_ram_counters().evictions;
}

FrameActivity streamer_activity(const TileStreamer& streamer, std::uint64_t evictions_before) {
  const FrameResult& f = streamer.last_frame();
  FrameActivity a;
  a.tiles_changed =
      f.uploaded > 0 || f.upload_pending > 0 || tier_evictions(streamer) != evictions_before;
  a.complete = f.complete;
  return a;
}

void RedrawScheduler::wake(Wake why) {
  (why == Wake::input ? input_ : content_).store(true, std::memory_order_release);
}

RedrawScheduler::Decision RedrawScheduler::next(Clock::time_point now) {
  if (input_.exchange(false, std::memory_order_acq_rel))
    owed_ = std::max(owed_, 1 + options_.settle_frames);
  if (content_.exchange(false, std::memory_order_acq_rel)) owed_ = std::max(owed_, 1);
  if (owed_ > 0) {
    --owed_;
    return {true, 0};
  }
  const auto seconds = [&](Clock::time_point since) {
    return std::chrono::duration<double>(now - since).count();
  };
  double wait = -1;
  if (streaming_) {
    const double since = seconds(last_frame_);
    if (since >= options_.streaming_poll_s) return {true, 0};
    wait = options_.streaming_poll_s - since;
  }
  if (trailing_) {
    const double since = seconds(changed_);
    if (since >= options_.trailing_frame_s) {
      trailing_ = false;
      return {true, 0};
    }
    const double left = options_.trailing_frame_s - since;
    wait = wait < 0 ? left : std::min(wait, left);
  }
  return {false, wait};
}

void RedrawScheduler::frame_drawn(const FrameActivity& activity, Clock::time_point now) {
  ++frames_drawn_;
  last_frame_ = now;
  streaming_ = !activity.complete;
  if (activity.camera_moved || activity.animating || activity.tiles_changed) {
    owed_ = std::max(owed_, 1);
    trailing_ = options_.trailing_frame_s >= 0;
    changed_ = now;
  }
}

}  // namespace tinstream::client
