// --headless: EGL surfaceless context → renderer → stream until complete → PNG + JSON.
#include <epoxy/gl.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "tinstream/client/camera_path.hpp"
#include "tinstream/client/egl_context.hpp"
#include "tinstream/client/png.hpp"
#include "tinstream/client/viewer.hpp"

namespace tinstream::client {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Where statistics go: the --stats file, or stdout.
class StatsOut {
 public:
  explicit StatsOut(const std::filesystem::path& file) {
    if (!file.empty()) file_.open(file, std::ios::trunc);
  }
  bool ok() const { return !file_.is_open() || file_.good(); }
  void line(const std::string& text) {
    std::ostream& out = file_.is_open() ? static_cast<std::ostream&>(file_) : std::cout;
    out << text << '\n';
    out.flush();
  }

 private:
  std::ofstream file_;
};

struct Gl {
  std::unique_ptr<EglContext> context;
  std::unique_ptr<GlobeRenderer> renderer;
  std::unique_ptr<Overlay> overlay;
  bool overlay_primed = false;
};

Result<Gl> open_gl(const ViewerOptions& o, const Session& s) {
  Gl gl;
  auto context = EglContext::create();
  if (!context) return context.error();
  gl.context = std::move(*context);
  RendererOptions ro;
  ro.width = o.width;
  ro.height = o.height;
  ro.msaa = o.msaa;
  ro.force_log_depth = o.log_depth;
  ro.flush_triangles = o.flush_triangles;
  ro.globe_height = s.globe_height();
  auto renderer = GlobeRenderer::create(ro);
  if (!renderer) return renderer.error();
  gl.renderer = std::move(*renderer);
  if (o.legend) {
    auto overlay = Overlay::create();
    if (!overlay) return overlay.error();
    gl.overlay = std::move(*overlay);
  }
  return gl;
}

RenderStats draw(Gl& gl, const ViewerOptions& o, const Session& s, const Camera& camera) {
  const RenderStats stats =
      gl.renderer->render(camera, s.streamer->last_frame().draws, s.render_settings(o.wireframe));
  if (gl.overlay) {
    if (!gl.overlay_primed) {
      gl.overlay->new_headless_frame(o.width, o.height);
      draw_legend(s.legend);
      gl.overlay->discard_frame();
      gl.overlay_primed = true;
    }
    gl.overlay->new_headless_frame(o.width, o.height);
    draw_legend(s.legend);
    gl.overlay->render(o.width, o.height);
  }
  return stats;
}

Status write_snapshot(Gl& gl, const ViewerOptions& o) {
  if (o.out.empty()) return {};
  Image image{o.width, o.height, gl.renderer->read_rgba()};
  return write_png(o.out, image);
}

// One view: stream until complete or timed out, then draw it once.
int run_snapshot(const ViewerOptions& o, Session& s, Gl& gl, Camera& camera, StatsOut& stats) {
  const auto start = Clock::now();
  const double thread_cpu_start = thread_cpu_seconds();
  const double process_cpu_start = process_cpu_seconds();
  RunSummary run;
  run.camera = to_string(camera.pose());
  run.renderer = gl.renderer->gl_description();
  while (true) {
    const FrameResult& f = s.streamer->update(camera, *gl.renderer);
    ++run.frames;
    if (f.complete) {
      run.complete = true;
      run.time_to_complete_s = seconds_since(start);
      break;
    }
    if (seconds_since(start) > o.timeout_s) break;
    // Settled (nothing uploaded or left to upload): sleep until a worker hands in a tile (never
    // longer than 20 ms). After an upload the next frame may already draw more or be complete.
    if (f.settled()) s.loader->wait_for_results(std::chrono::milliseconds(20));
  }
  // No frame is drawn while the view streams in: the CPU so far is the streaming's alone.
  run.render_thread_cpu_s = thread_cpu_seconds() - thread_cpu_start;
  run.process_cpu_s = process_cpu_seconds() - process_cpu_start;
  run.render = draw(gl, o, s, camera);
  run.centre_level = centre_level(s, camera);
  if (s.streamer->failures() > 0)
    std::cerr << "tinstream-viewer: " << s.streamer->failures()
              << " tile(s) failed to load; the last: " << s.streamer->last_error() << '\n';
  const Status written = write_snapshot(gl, o);
  run.elapsed_s = seconds_since(start);
  stats.line(summary_json(o, s, run));
  if (!written) {
    std::cerr << "tinstream-viewer: " << written.error().message << '\n';
    return 1;
  }
  if (!o.out.empty()) std::cerr << "tinstream-viewer: wrote " << o.out.string() << '\n';
  if (!run.complete) {
    std::cerr << "tinstream-viewer: the view was not complete after " << o.timeout_s
              << " s (--timeout); the snapshot shows what had arrived\n";
    return 3;
  }
  return 0;
}

// A scripted flight: every frame streams, draws and reports; the flight's clock is wall time
// (or 1/fps per frame with --fps).
int run_path(const ViewerOptions& o, Session& s, Gl& gl, Camera& camera, StatsOut& stats) {
  auto path = load_camera_path(o.camera_path);
  if (!path) {
    std::cerr << "tinstream-viewer: " << path.error().message << '\n';
    return 2;
  }
  const double flight_s = path->duration();
  PathPlayer player(std::move(*path));
  const auto start = Clock::now();
  const double thread_cpu_start = thread_cpu_seconds();
  const double process_cpu_start = process_cpu_seconds();
  auto last = start;
  bool complete = false;
  std::uint64_t frame = 0;
  RunSummary run;
  run.renderer = gl.renderer->gl_description();
  while (!player.finished()) {
    const auto now = Clock::now();
    const double dt = o.fps > 0 ? (frame == 0 ? 0.0 : 1.0 / o.fps)
                                : std::chrono::duration<double>(now - last).count();
    last = now;
    camera.set_pose(player.advance(dt, complete));
    const auto t0 = Clock::now();
    const FrameResult& f = s.streamer->update(camera, *gl.renderer);
    const double update_ms = seconds_since(t0) * 1e3;
    const auto t1 = Clock::now();
    const RenderStats rs = draw(gl, o, s, camera);
    glFinish();  // the frame's real cost, not just the commands queued
    const double render_ms = seconds_since(t1) * 1e3;
    complete = f.complete;
    const LoaderCounters lc = s.loader->counters();
    stats.line(nlohmann::json{{"frame", frame},
                              {"t", seconds_since(start)},
                              {"frame_ms", update_ms + render_ms},
                              {"update_ms", update_ms},
                              {"render_ms", render_ms},
                              {"drawn", f.draws.size()},
                              {"triangles", rs.triangles},
                              {"skirt_triangles", rs.skirt_triangles},
                              {"flushes", rs.flushes},
                              {"wanted", f.wanted},
                              {"prefetched", f.prefetched},
                              {"upload_pending", f.upload_pending},
                              {"uploaded", f.uploaded},
                              {"uploaded_bytes", f.uploaded_bytes},
                              {"queued", lc.queued},
                              {"in_flight", lc.in_flight},
                              {"loaded", lc.decoded},
                              {"downloaded_bytes", lc.downloaded_bytes},
                              {"complete", f.complete},
                              {"max_sse_drawn", f.max_sse_drawn},
                              {"waiting", player.waiting()},
                              {"gpu_bytes", s.streamer->gpu_counters().bytes},
                              {"ram_bytes", s.streamer->ram_counters().bytes},
                              {"rss_bytes", resident_bytes()},
                              {"heap_trims", s.streamer->heap_trims()}}
                   .dump());
    ++frame;
    run.render = rs;
    if (player.waiting() && !f.complete && f.settled())
      s.loader->wait_for_results(std::chrono::milliseconds(5));
    if (seconds_since(start) > o.timeout_s + flight_s) break;
  }
  run.frames = frame;
  run.render_thread_cpu_s = thread_cpu_seconds() - thread_cpu_start;
  run.process_cpu_s = process_cpu_seconds() - process_cpu_start;
  run.complete = complete;
  run.elapsed_s = seconds_since(start);
  run.camera = to_string(camera.pose());
  run.centre_level = centre_level(s, camera);
  stats.line(summary_json(o, s, run));  // the last line: the totals (it has no "frame")
  const Status written = write_snapshot(gl, o);
  if (!written) {
    std::cerr << "tinstream-viewer: " << written.error().message << '\n';
    return 1;
  }
  return 0;
}

}  // namespace

int run_headless(const ViewerOptions& o) {
  auto session = open_session(o);
  if (!session) {
    std::cerr << "tinstream-viewer: " << session.error().message << '\n';
    return 2;
  }
  for (const std::string& w : session->warnings)
    std::cerr << "tinstream-viewer: warning: " << w << '\n';
  StatsOut stats(o.stats);
  if (!stats.ok()) {
    std::cerr << "tinstream-viewer: cannot write " << o.stats.string() << '\n';
    return 2;
  }
  auto gl = open_gl(o, *session);
  if (!gl) {
    std::cerr << "tinstream-viewer: " << gl.error().message << '\n';
    return 1;
  }
  Camera camera(o.width, o.height, o.fov);
  camera.log_depth = gl->renderer->log_depth();
  camera.set_pose(o.camera ? *o.camera : session->framing(camera));
  const int status = o.camera_path.empty() ? run_snapshot(o, *session, *gl, camera, stats)
                                           : run_path(o, *session, *gl, camera, stats);
  session->streamer->release_all(*gl->renderer);
  if (session->timeline) {
    std::ofstream out(o.timeline, std::ios::trunc);
    session->timeline->write(out);
    if (!out) {
      std::cerr << "tinstream-viewer: cannot write " << o.timeline.string() << '\n';
      return status == 0 ? 2 : status;
    }
  }
  return status;
}

}  // namespace tinstream::client
