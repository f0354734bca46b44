// tinstream/client/redraw.hpp — when the window draws a frame. Window mode draws on demand: a
// viewer that nothing changes in draws nothing and blocks in glfwWaitEvents instead of keeping a
// core busy (it drew every frame until #17's fourth session).
//
// The window loop asks next() before each frame: draw now, or wait (at most wait_s) and ask
// again. A frame is owed when
//   - an event arrived: input, a resize, an expose (wake(Wake::input), from the GLFW callbacks),
//     which owes 1 + settle_frames frames: Dear ImGui shows hover and click states a frame or
//     two after the event that caused them;
//   - a tile landed: the loader's result callback calls wake(Wake::content) on its worker thread
//     (and glfwPostEmptyEvent, which ends the render thread's wait): exactly one frame, whose
//     update() takes the tile;
//   - the frame just drawn changed what the next one shows (frame_drawn): the camera moved or is
//     animated (a fly-to, a camera path, held keys), tiles were uploaded or wait for the upload
//     budget (a tile uploaded in a frame is selected only by the next one), a tier evicted.
// While the view is not complete (requests in flight, failed tiles waiting for their retry) the
// wait is at most streaming_poll_s, so a retry is asked for without a tile landing. One trailing
// frame follows trailing_frame_s after the last frame that changed something (tiles, camera):
// its streamer update() runs the heap trim (StreamerOptions::heap_trim_interval) on what that last
// activity freed, which would otherwise stay with the process until the next input. Then, with
// the view complete and nothing moving, the wait has no end (wait_s < 0).
//
// Threads: wake() from any thread; everything else on the render thread.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>

#include "tinstream/client/streamer.hpp"

namespace tinstream::client {

// What the frame just drawn saw.
struct FrameActivity {
  bool camera_moved = false;   // the pose changed in this frame
  bool animating = false;      // something moves the camera next frame (fly-to, path, --out)
  bool tiles_changed = false;  // uploads done or pending, evictions
  bool complete = true;        // FrameResult::complete
};

// Evictions so far from the streamer's tiers (GPU, RAM, imagery RAM).
std::uint64_t tier_evictions(const TileStreamer& streamer);
// The streamer's part of the frame just drawn by streamer.update(): tiles_changed (uploaded,
// waiting for the upload budget, or evicted since `evictions_before` = tier_evictions before
// the update) and complete.
FrameActivity streamer_activity(const TileStreamer& streamer, std::uint64_t evictions_before);

enum class Wake { input, content };

struct RedrawOptions {
  int settle_frames = 2;           // frames after the one an input event owes
  double streaming_poll_s = 0.25;  // longest wait while the view is not complete
  // The trailing frame, this long after the last frame that changed something (longer than
  // StreamerOptions::heap_trim_interval's default 1 s); < 0: none.
  double trailing_frame_s = 1.5;
};

class RedrawScheduler {
 public:
  using Clock = std::chrono::steady_clock;

  explicit RedrawScheduler(RedrawOptions options = {}) : options_(options) {}

  // Any thread: something happened that a frame must show.
  void wake(Wake why);

  struct Decision {
    bool draw = false;
    double wait_s = -1;  // when not drawing: the longest wait before asking again; < 0: none
  };
  // Render thread, before a frame. Owes the first frame (nothing has been drawn yet).
  Decision next(Clock::time_point now);
  // Render thread, after drawing the frame next() asked for.
  void frame_drawn(const FrameActivity& activity, Clock::time_point now);

  std::uint64_t frames_drawn() const { return frames_drawn_; }

 private:
  RedrawOptions options_;
  std::atomic<bool> input_{false}, content_{false};
  int owed_ = 1;                  // frames to draw before waiting
  bool streaming_ = false;        // the last frame's view was not complete
  bool trailing_ = false;         // the trailing frame is owed at changed_ + trailing_frame_s
  Clock::time_point changed_;     // when the last frame that changed something was drawn
  Clock::time_point last_frame_;  // when the last frame was drawn
  std::uint64_t frames_drawn_ = 0;
};

}  // namespace tinstream::client
