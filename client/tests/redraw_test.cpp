// When the window draws (redraw.hpp): the scheduler's decisions on their own, and the window's
// loop (scheduler + a real streamer and loader over a SQLite store, no window) with a condition
// variable standing in for glfwWaitEvents / glfwPostEmptyEvent.
#include "tinstream/client/redraw.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "synthetic_store.hpp"
#include "tinstream/client/tile_source.hpp"

namespace tinstream::client {
namespace {

using Clock = RedrawScheduler::Clock;
using std::chrono::milliseconds;

// Draws the frames next() asks for with `activity`, over `steps` calls `step` apart; returns how
// many it drew.
int frames_over(RedrawScheduler& r, Clock::time_point& now, int steps, Clock::duration step,
                const FrameActivity& activity = {}) {
  int drawn = 0;
  for (int i = 0; i < steps; ++i, now += step) {
    if (!r.next(now).draw) continue;
    ++drawn;
    r.frame_drawn(activity, now);
  }
  return drawn;
}

// Ten idle frames 16 ms apart, then a tile lands (a content wake) and the frame drawn for it
// uploads tiles. Returns whether next() asked for that frame.
bool draw_an_upload_frame(RedrawScheduler& r, Clock::time_point& now) {
  frames_over(r, now, 10, milliseconds(16));
  r.wake(Wake::content);
  if (!r.next(now).draw) return false;
  FrameActivity uploaded;
  uploaded.tiles_changed = true;
  r.frame_drawn(uploaded, now);
  return true;
}

TEST(RedrawScheduler, AnIdleWindowDrawsItsFirstFrameThenNothingAndWaitsWithoutEnd) {
  RedrawScheduler r;
  Clock::time_point now{};
  ASSERT_TRUE(r.next(now).draw);
  r.frame_drawn({}, now);
  // An hour of loop iterations (one a millisecond, as a polling loop at 1 kHz would make).
  EXPECT_EQ(frames_over(r, now, 3'600'000, milliseconds(1)), 0);
  const RedrawScheduler::Decision d = r.next(now);
  EXPECT_FALSE(d.draw);
  EXPECT_LT(d.wait_s, 0);  // glfwWaitEvents, no timeout
  EXPECT_EQ(r.frames_drawn(), 1u);
}

TEST(RedrawScheduler, ATileLandingDrawsExactlyOneFrame) {
  RedrawScheduler r;
  Clock::time_point now{};
  frames_over(r, now, 10, milliseconds(16));
  r.wake(Wake::content);
  EXPECT_EQ(frames_over(r, now, 1000, milliseconds(16)), 1);
  // Two tiles landing before the loop wakes owe one frame too: it takes both.
  r.wake(Wake::content);
  r.wake(Wake::content);
  EXPECT_EQ(frames_over(r, now, 1000, milliseconds(16)), 1);
}

TEST(RedrawScheduler, AFrameThatUploadedTilesOwesTheNextWhichDrawsThem) {
  RedrawScheduler r(RedrawOptions{2, 0.25, -1});  // no trailing frame (the next test)
  Clock::time_point now{};
  ASSERT_TRUE(draw_an_upload_frame(r, now));
  EXPECT_EQ(frames_over(r, now, 1000, milliseconds(16)), 1);
}

TEST(RedrawScheduler, OneTrailingFrameFollowsTheLastChangeForTheHeapTrim) {
  RedrawScheduler r(RedrawOptions{2, 0.25, 1.5});
  Clock::time_point now{};
  ASSERT_TRUE(draw_an_upload_frame(r, now));
  const Clock::time_point changed = now;
  ASSERT_TRUE(r.next(now).draw);  // the frame the upload owes, which changes nothing
  r.frame_drawn({}, now);
  const RedrawScheduler::Decision d = r.next(now + milliseconds(500));
  EXPECT_FALSE(d.draw);
  EXPECT_NEAR(d.wait_s, 1.0, 1e-9);  // until the trailing frame, not without end
  // An hour of 1 ms iterations: the trailing frame at 1.5 s after the change, then nothing.
  Clock::time_point drawn_at{};
  int drawn = 0;
  for (int i = 0; i < 3'600'000; ++i, now += milliseconds(1)) {
    if (!r.next(now).draw) continue;
    ++drawn;
    drawn_at = now;
    r.frame_drawn({}, now);
  }
  EXPECT_EQ(drawn, 1);
  EXPECT_EQ(drawn_at - changed, milliseconds(1500));
  EXPECT_LT(r.next(now).wait_s, 0);
}

TEST(RedrawScheduler, AnInputEventOwesItsFrameAndTheSettlingFrames) {
  RedrawScheduler r(RedrawOptions{3, 0.25});
  Clock::time_point now{};
  frames_over(r, now, 10, milliseconds(16));
  r.wake(Wake::input);
  EXPECT_EQ(frames_over(r, now, 1000, milliseconds(16)), 4);
}

TEST(RedrawScheduler, ACameraInMotionDrawsEveryIterationUntilItStops) {
  RedrawScheduler r(RedrawOptions{2, 0.25, -1});  // no trailing frame
  Clock::time_point now{};
  frames_over(r, now, 10, milliseconds(16));
  r.wake(Wake::input);
  FrameActivity moving;
  moving.camera_moved = true;
  EXPECT_EQ(frames_over(r, now, 500, milliseconds(16), moving), 500);
  FrameActivity flying;
  flying.animating = true;
  EXPECT_EQ(frames_over(r, now, 500, milliseconds(16), flying), 500);
  // The frame after the last move is drawn, then nothing.
  EXPECT_EQ(frames_over(r, now, 500, milliseconds(16)), 1);
}

TEST(RedrawScheduler, AnIncompleteViewIsRedrawnAtTheStreamingPollOnly) {
  RedrawScheduler r(RedrawOptions{2, 0.25});
  Clock::time_point now{};
  FrameActivity streaming;
  streaming.complete = false;
  ASSERT_TRUE(r.next(now).draw);
  r.frame_drawn(streaming, now);
  const RedrawScheduler::Decision d = r.next(now + milliseconds(100));
  EXPECT_FALSE(d.draw);
  EXPECT_NEAR(d.wait_s, 0.15, 1e-9);
  // Ten seconds of 1 ms iterations: frames at 0.25, 0.5, …, 9.75 s.
  EXPECT_EQ(frames_over(r, now, 10'000, milliseconds(1), streaming), 39);
}

// The window's loop without a window: the scheduler decides, a real streamer draws into a
// counting uploader, the loader's result callback wakes the loop (as glfwPostEmptyEvent does).
class NullUploader final : public GpuUploader {
 public:
  GpuMesh upload(const TileMesh& mesh) override {
    GpuMesh g;
    g.vao = ++next_;
    g.bytes = mesh.byte_size();
    return g;
  }
  void release(GpuMesh& mesh) override { mesh.vao = 0; }

 private:
  std::uint32_t next_ = 0;
};

struct EventQueue {  // glfwWaitEventsTimeout / glfwPostEmptyEvent
  std::mutex mutex;
  std::condition_variable cv;
  bool posted = false;
  void post() {
    {
      std::lock_guard lock(mutex);
      posted = true;
    }
    cv.notify_one();
  }
  // Returns whether an event was posted before the timeout.
  bool wait(double seconds) {
    std::unique_lock lock(mutex);
    const bool got =
        cv.wait_for(lock, std::chrono::duration<double>(seconds), [&] { return posted; });
    posted = false;
    return got;
  }
};

TEST(RedrawLoop, TilesLandingWakeTheLoopUntilTheViewIsCompleteThenItDrawsNothing) {
  testing::TempDir dir("redraw_loop");
  const std::filesystem::path store = dir.path / "s.db";
  testing::write_layer(store, testing::default_layer());
  auto source = open_store_source(store);
  ASSERT_TRUE(source) << source.error().message;
  auto layers = (*source)->layers({});
  ASSERT_TRUE(layers) << layers.error().message;
  TileLoader loader(*source, *layers, nullptr, LoaderOptions{2});
  StreamerOptions so;
  so.max_sse = 0.01;  // down to the finest level: three levels of round trips
  TileStreamer streamer(loader, so);
  NullUploader gpu;
  const geo::TileId root{10, 530, 350};
  const geo::MercatorRect rect = root.bounds();
  const geo::LonLat c = geo::NormalisedMercator().inverse(
      {(rect.min_x + rect.max_x) / 2, (rect.min_y + rect.max_y) / 2});
  Camera camera(1280, 720, 60);
  camera.set_pose({c.lon, c.lat, 60000, 0, -90});

  // No streaming poll within the test's time and no trailing frame (whose timer would end a wait
  // on a slow machine): only tiles landing may wake the loop.
  RedrawScheduler redraw(RedrawOptions{2, 1e6, -1});
  EventQueue events;
  loader.set_result_callback([&] {
    redraw.wake(Wake::content);
    events.post();
  });
  const auto deadline = Clock::now() + std::chrono::seconds(30);
  int frames = 0, waits = 0, timeouts = 0;
  bool complete = false;
  while (Clock::now() < deadline) {
    const RedrawScheduler::Decision d = redraw.next(Clock::now());
    if (!d.draw) {
      if (complete) break;  // idle with a complete view: the loop would block without end
      ASSERT_GE(d.wait_s, 0) << "the loop would wait for ever with an incomplete view";
      ++waits;
      timeouts += events.wait(std::min(d.wait_s, 5.0)) ? 0 : 1;
      continue;
    }
    const std::uint64_t evictions_before = tier_evictions(streamer);
    streamer.update(camera, gpu);
    ++frames;
    const FrameActivity a = streamer_activity(streamer, evictions_before);
    complete = a.complete;
    redraw.frame_drawn(a, Clock::now());
  }
  ASSERT_TRUE(complete) << "the view never completed on wakes alone";
  EXPECT_EQ(streamer.last_frame().draws.size(), 16u);
  EXPECT_GT(waits, 0);
  EXPECT_EQ(timeouts, 0) << "a wait ended without a tile landing";
  // At most a frame per tile landing (21 tiles) plus one after each upload and the first.
  EXPECT_LE(frames, 2 * 21 + 1);

  // Complete and idle: a thousand loop iterations over ten minutes draw nothing.
  Clock::time_point now = Clock::now();
  const std::uint64_t before = redraw.frames_drawn();
  for (int i = 0; i < 1000; ++i, now += milliseconds(600))
    EXPECT_FALSE(redraw.next(now).draw) << "iteration " << i;
  EXPECT_EQ(redraw.frames_drawn(), before);
  loader.set_result_callback(nullptr);
}

}  // namespace
}  // namespace tinstream::client
