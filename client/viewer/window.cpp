// The interactive window: GLFW (OpenGL 3.3 core) + Dear ImGui. The render thread (this one)
// streams, draws, handles input and the panel; the download pool works behind the streamer.
//
// Mouse: left drag pans (the grabbed point follows the cursor), right drag (or Ctrl + left)
// orbits around the point under the cursor (horizontal: heading, vertical: tilt), wheel zooms
// towards the cursor. Keys: W/S/A/D fly, Q/E down/up, arrows look around, Shift ×4 speed,
// F flies to the selected layer, R frames every layer.
// Scripted use: --camera-path flies the path in the window (input is ignored meanwhile); --out
// writes the window (panel and legend included) to a PNG once the view is complete and the path
// is flown, prints that frame's layout (the panel's and the legend's rectangles) as one JSON line
// on stdout, and closes it (exit status 3 when --timeout passed first).
#include "window.hpp"

// clang-format off
#include <epoxy/gl.h>  // before GLFW, which must not include GL/gl.h
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
// clang-format on
#include <backends/imgui_impl_glfw.h>
#include <imgui.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <iostream>
#include <limits>
#include <optional>
#include <string>

#include "tinstream/client/camera_path.hpp"
#include "tinstream/client/navigation.hpp"
#include "tinstream/client/png.hpp"
#include "tinstream/client/redraw.hpp"
#include "tinstream/geo/ecef.hpp"

namespace tinstream::client {

namespace {

using Clock = std::chrono::steady_clock;

struct GlfwSession {
  GLFWwindow* window = nullptr;
  bool initialised = false;
  ~GlfwSession() {
    if (window) glfwDestroyWindow(window);
    if (initialised) glfwTerminate();
  }
};

// What the panel shows besides the streamer's own counters.
struct PanelState {
  std::deque<float> frame_ms;  // the last 240 frames
  double rate_bytes_per_s = 0;
  std::uint64_t last_wire_bytes = 0;
  Clock::time_point last_rate = Clock::now();
  int layer_choice = 0;
  bool paused = false;
  bool wireframe = false;
  float max_sse = 2;
  int threads = 1;
  bool imagery = true;  // --imagery draped (the streamer's switch)
  std::optional<geo::Geodetic> cursor;
};

// Mouse drags in progress.
struct DragState {
  enum class Mode { none, pan, orbit } mode = Mode::none;
  Vec3 anchor;  // the grabbed point or the orbit pivot
  double last_x = 0, last_y = 0;
};

Vec3 point_under(GlobeRenderer& renderer, const Camera& camera, double x, double y) {
  if (auto p = renderer.pick(camera, static_cast<int>(x), static_cast<int>(y))) return *p;
  if (auto hit = intersect_ellipsoid(camera.position(), camera.ray_direction(x, y))) return *hit;
  // Beyond the limb: a point ahead, as far as the ellipsoid's centre.
  return camera.position() + camera.ray_direction(x, y) * length(camera.position());
}

void handle_mouse(GLFWwindow* window, GlobeRenderer& renderer, Camera& camera, DragState& drag,
                  double scale) {
  ImGuiIO& io = ImGui::GetIO();
  double x = 0, y = 0;
  glfwGetCursorPos(window, &x, &y);
  x *= scale;
  y *= scale;
  const bool left = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
  const bool right = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                     glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
  const bool ctrl = glfwGetKey(window, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS ||
                    glfwGetKey(window, GLFW_KEY_RIGHT_CONTROL) == GLFW_PRESS;
  if (drag.mode == DragState::Mode::none && !io.WantCaptureMouse && (left || right)) {
    drag.mode = (right || ctrl) ? DragState::Mode::orbit : DragState::Mode::pan;
    drag.anchor = point_under(renderer, camera, x, y);
    drag.last_x = x;
    drag.last_y = y;
  }
  if (!left && !right) drag.mode = DragState::Mode::none;
  if (drag.mode == DragState::Mode::pan) pan(camera, drag.anchor, x, y);
  if (drag.mode == DragState::Mode::orbit) {
    const double dx = x - drag.last_x, dy = y - drag.last_y;
    orbit(camera, drag.anchor, -dx * 0.005, -dy * 0.005);
  }
  drag.last_x = x;
  drag.last_y = y;
  if (!io.WantCaptureMouse && io.MouseWheel != 0) {
    const Vec3 target = point_under(renderer, camera, x, y);
    zoom_towards(camera, target, std::pow(0.85, io.MouseWheel));
  }
}

void handle_keys(GLFWwindow* window, Camera& camera, double dt) {
  if (ImGui::GetIO().WantCaptureKeyboard) return;
  const auto down = [&](int key) { return glfwGetKey(window, key) == GLFW_PRESS; };
  const CameraPose pose = camera.pose();
  // Speed ∝ height above the ellipsoid (at least 20 m/s), ×4 with Shift.
  const double speed =
      std::max(std::abs(pose.height), 20.0) * (down(GLFW_KEY_LEFT_SHIFT) ? 4.0 : 1.0);
  const double f = (down(GLFW_KEY_W) - down(GLFW_KEY_S)) * speed * dt;
  const double r = (down(GLFW_KEY_D) - down(GLFW_KEY_A)) * speed * dt;
  const double u = (down(GLFW_KEY_E) - down(GLFW_KEY_Q)) * speed * dt;
  if (f != 0 || r != 0 || u != 0) fly(camera, f, r, u);
  const double turn = 60 * dt;
  const double h = (down(GLFW_KEY_RIGHT) - down(GLFW_KEY_LEFT)) * turn;
  const double p = (down(GLFW_KEY_UP) - down(GLFW_KEY_DOWN)) * turn;
  if (h != 0 || p != 0) look(camera, h, p);
}

std::string megabytes(std::uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MB", static_cast<double>(bytes) / (1 << 20));
  return text;
}

// --imagery: its switch and counters (404: absent imagery tiles).
void draw_imagery_row(Session& s, PanelState& ps) {
  if (ImGui::Checkbox("imagery", &ps.imagery)) s.streamer->set_imagery_enabled(ps.imagery);
  ImGui::SameLine();
  ImGui::TextUnformatted(s.imagery->name.c_str());
  const ImageryStats i = imagery_stats(*s.streamer);
  ImGui::Text("requested %llu  loaded %llu  draped %llu  404 %llu  failed %llu",
              static_cast<unsigned long long>(i.requested),
              static_cast<unsigned long long>(i.loaded), static_cast<unsigned long long>(i.draped),
              static_cast<unsigned long long>(i.absent), static_cast<unsigned long long>(i.failed));
}

// Where the panel was laid out this frame (--out reports it; the layout test checks it).
struct PanelLayout {
  OverlayRect panel;
  OverlayRect source_line;  // the source's description, wrapped to the panel's width
};

OverlayRect last_item_rect() {
  const ImVec2 min = ImGui::GetItemRectMin(), max = ImGui::GetItemRectMax();
  return {min.x, min.y, max.x - min.x, max.y - min.y};
}

PanelLayout draw_panel(Session& s, const Camera& camera, PanelState& ps, FlyTo& flight,
                       double frame_ms) {
  PanelLayout layout;
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSize(ImVec2(390, 0), ImGuiCond_FirstUseEver);
  // Never taller than the window (at 640×360 it was): it scrolls instead.
  ImGui::SetNextWindowSizeConstraints(
      ImVec2(0, 0), ImVec2(std::numeric_limits<float>::max(), ImGui::GetIO().DisplaySize.y - 20));
  ImGui::Begin("tinstream");
  ImGui::TextWrapped("%s", s.source->describe().c_str());  // an absolute store path is long
  layout.source_line = last_item_rect();

  // Layers and flying to them.
  std::vector<const char*> names;
  for (const LayerDescription& l : s.layers) names.push_back(l.name.c_str());
  ImGui::Combo("layer", &ps.layer_choice, names.data(), static_cast<int>(names.size()));
  ImGui::SameLine();
  if (ImGui::Button("fly to")) {
    flight =
        FlyTo(camera.pose(), s.framing(camera, static_cast<std::size_t>(ps.layer_choice)), 2.5);
  }
  const CameraPose pose = camera.pose();
  ImGui::Text("camera %.5f, %.5f  %.0f m  heading %.0f  pitch %.0f", pose.lon, pose.lat,
              pose.height, pose.heading, pose.pitch);
  if (ps.cursor)
    ImGui::Text("cursor %.6f, %.6f  %.2f m", ps.cursor->lon, ps.cursor->lat, ps.cursor->height);
  else
    ImGui::TextUnformatted("cursor: sky");

  // Controls.
  if (ImGui::SliderFloat("max SSE (px)", &ps.max_sse, 0.25f, 32.0f, "%.2f",
                         ImGuiSliderFlags_Logarithmic))
    s.streamer->set_max_sse(ps.max_sse);
  if (ImGui::SliderInt("threads", &ps.threads, 1, 8)) s.loader->set_threads(ps.threads);
  ImGui::Checkbox("wireframe", &ps.wireframe);
  ImGui::SameLine();
  if (ImGui::Checkbox("pause streaming", &ps.paused)) s.loader->set_paused(ps.paused);

  // Frame time.
  ps.frame_ms.push_back(static_cast<float>(frame_ms));
  if (ps.frame_ms.size() > 240) ps.frame_ms.pop_front();
  const std::vector<float> graph(ps.frame_ms.begin(), ps.frame_ms.end());
  char label[48];
  std::snprintf(label, sizeof label, "%.1f ms", frame_ms);
  ImGui::PlotLines("frame", graph.data(), static_cast<int>(graph.size()), 0, label, 0.0f, 50.0f,
                   ImVec2(0, 50));

  // Streaming.
  const FrameResult& f = s.streamer->last_frame();
  const LoaderCounters lc = s.loader->counters();
  const auto now = Clock::now();
  const double since = std::chrono::duration<double>(now - ps.last_rate).count();
  if (since >= 0.5) {
    ps.rate_bytes_per_s = static_cast<double>(lc.wire_bytes - ps.last_wire_bytes) / since;
    ps.last_wire_bytes = lc.wire_bytes;
    ps.last_rate = now;
  }
  ImGui::Text("%s  download %.2f MB/s  queued %llu", f.complete ? "complete" : "streaming",
              ps.rate_bytes_per_s / (1 << 20), static_cast<unsigned long long>(lc.queued));
  if (ImGui::BeginTable("levels", 5, ImGuiTableFlags_Borders | ImGuiTableFlags_SizingFixedFit)) {
    for (const char* h : {"level", "drawn", "loaded", "pending", "in flight"})
      ImGui::TableSetupColumn(h);
    ImGui::TableHeadersRow();
    for (std::size_t z = 0; z < kLevels; ++z) {
      const LevelCounters& c = s.streamer->level_counters()[z];
      if (!f.drawn_per_level[z] && !c.loaded && !f.pending_per_level[z] && !lc.in_flight_levels[z])
        continue;
      ImGui::TableNextRow();
      const unsigned long long cells[5] = {z, f.drawn_per_level[z], c.loaded,
                                           f.pending_per_level[z], lc.in_flight_levels[z]};
      for (int i = 0; i < 5; ++i) {
        ImGui::TableSetColumnIndex(i);
        ImGui::Text("%llu", cells[i]);
      }
    }
    ImGui::EndTable();
  }
  const TierCounters& g = s.streamer->gpu_counters();
  const TierCounters& r = s.streamer->ram_counters();
  ImGui::Text("GPU  %s / %s  (%llu tiles, %llu evicted)", megabytes(g.bytes).c_str(),
              megabytes(g.budget).c_str(), static_cast<unsigned long long>(g.entries),
              static_cast<unsigned long long>(g.evictions));
  ImGui::Text("RAM  %s / %s  (%llu tiles, %llu evicted)", megabytes(r.bytes).c_str(),
              megabytes(r.budget).c_str(), static_cast<unsigned long long>(r.entries),
              static_cast<unsigned long long>(r.evictions));
  if (s.disk) {
    const TierCounters d = s.disk->counters();
    ImGui::Text("disk %s / %s  (%llu hits, %llu misses)", megabytes(d.bytes).c_str(),
                megabytes(d.budget).c_str(), static_cast<unsigned long long>(d.hits),
                static_cast<unsigned long long>(d.misses));
  }
  ImGui::Text("requests %llu  304 %llu  404 %llu  failed %llu  dropped %llu",
              static_cast<unsigned long long>(lc.requests),
              static_cast<unsigned long long>(lc.not_modified),
              static_cast<unsigned long long>(lc.not_found),
              static_cast<unsigned long long>(lc.failed),
              static_cast<unsigned long long>(lc.dropped));
  if (s.imagery) draw_imagery_row(s, ps);
  if (!s.streamer->last_error().empty())
    ImGui::TextWrapped("last error: %s", s.streamer->last_error().c_str());
  const ImVec2 pos = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
  layout.panel = {pos.x, pos.y, size.x, size.y};
  ImGui::End();
  return layout;
}

// --out: one JSON line on stdout with the written frame's layout, in window units (the window's
// size, then x, y, width, height of each rectangle; no legend: null).
void print_layout(const PanelLayout& p, const std::optional<OverlayRect>& legend) {
  const auto rect = [](const OverlayRect& r) {
    char text[96];
    std::snprintf(text, sizeof text, "[%.1f,%.1f,%.1f,%.1f]", r.x, r.y, r.width, r.height);
    return std::string(text);
  };
  const ImVec2 display = ImGui::GetIO().DisplaySize;
  std::printf(
      "{\"layout\":{\"window\":[%.0f,%.0f],\"panel\":%s,\"source_line\":%s,\"legend\":%s}}\n",
      display.x, display.y, rect(p.panel).c_str(), rect(p.source_line).c_str(),
      legend ? rect(*legend).c_str() : "null");
  std::fflush(stdout);
}

// Every window event owes frames (RedrawScheduler). Installed before ImGui's callbacks, which
// chain to these; ImGui 1.86 installs no cursor-position, size or refresh callback of its own.
void wake_on_event(GLFWwindow* window) {
  static_cast<RedrawScheduler*>(glfwGetWindowUserPointer(window))->wake(Wake::input);
}

void install_wake_callbacks(GLFWwindow* window, RedrawScheduler& redraw) {
  glfwSetWindowUserPointer(window, &redraw);
  glfwSetCursorPosCallback(window, [](GLFWwindow* w, double, double) { wake_on_event(w); });
  glfwSetMouseButtonCallback(window, [](GLFWwindow* w, int, int, int) { wake_on_event(w); });
  glfwSetScrollCallback(window, [](GLFWwindow* w, double, double) { wake_on_event(w); });
  glfwSetKeyCallback(window, [](GLFWwindow* w, int, int, int, int) { wake_on_event(w); });
  glfwSetCharCallback(window, [](GLFWwindow* w, unsigned int) { wake_on_event(w); });
  glfwSetWindowFocusCallback(window, [](GLFWwindow* w, int) { wake_on_event(w); });
  glfwSetCursorEnterCallback(window, [](GLFWwindow* w, int) { wake_on_event(w); });
  glfwSetFramebufferSizeCallback(window, [](GLFWwindow* w, int, int) { wake_on_event(w); });
  glfwSetWindowSizeCallback(window, [](GLFWwindow* w, int, int) { wake_on_event(w); });
  glfwSetWindowRefreshCallback(window, [](GLFWwindow* w) { wake_on_event(w); });
}

// Opens the window with an OpenGL 3.3 core context and makes it current. Returns 0, or the exit
// status after saying what was missing.
int open_window(GlfwSession& glfw, const ViewerOptions& o) {
  glfwSetErrorCallback([](int code, const char* text) {
    std::cerr << "GLFW error " << code << ": " << text << '\n';
  });
  if (!glfwInit()) {
    std::cerr << "tinstream-viewer: no display for a window (use --headless --out shot.png)\n";
    return 1;
  }
  glfw.initialised = true;
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfw.window = glfwCreateWindow(o.width, o.height, "tinstream-viewer", nullptr, nullptr);
  if (!glfw.window) {
    std::cerr << "tinstream-viewer: cannot open an OpenGL 3.3 core window\n";
    return 1;
  }
  glfwMakeContextCurrent(glfw.window);
  glfwSwapInterval(1);
  return 0;
}

// What draws into the window: the globe and the panel's overlay.
struct Graphics {
  std::unique_ptr<GlobeRenderer> renderer;
  std::unique_ptr<Overlay> overlay;
};

Result<Graphics> create_graphics(const Session& s, const ViewerOptions& o, int fb_w, int fb_h) {
  RendererOptions ro;
  ro.width = fb_w;
  ro.height = fb_h;
  ro.msaa = o.msaa;
  ro.force_log_depth = o.log_depth;
  ro.flush_triangles = o.flush_triangles;
  ro.globe_height = s.globe_height();
  auto renderer = GlobeRenderer::create(ro);
  if (!renderer) return renderer.error();
  auto overlay = Overlay::create();
  if (!overlay) return overlay.error();
  return Graphics{std::move(*renderer), std::move(*overlay)};
}

// Who moves the camera besides the user: a fly-to in progress, or the --camera-path.
struct Autopilot {
  FlyTo flight;
  std::optional<PathPlayer> path;
  double path_s = 0;  // the path's flight time, waits excluded

  bool scripted() const { return path && !path->finished(); }
};

// Places the camera at --camera, or far out flying to the layers; loads --camera-path.
Result<Autopilot> start_camera(const Session& s, const ViewerOptions& o, Camera& camera) {
  Autopilot pilot;
  if (o.camera) {
    camera.set_pose(*o.camera);
  } else {
    camera.set_pose(
        {(s.extent.west + s.extent.east) / 2, (s.extent.south + s.extent.north) / 2, 2e7, 0, -90});
    pilot.flight = FlyTo(camera.pose(), s.framing(camera), 3.0);
  }
  if (!o.camera_path.empty()) {
    auto p = load_camera_path(o.camera_path);
    if (!p) return p.error();
    pilot.path_s = p->duration();
    pilot.path.emplace(std::move(*p));
    pilot.flight = FlyTo();
  }
  return pilot;
}

// Follows the framebuffer's size (the renderer and the camera's viewport). Returns the
// framebuffer's pixels per window unit (cursor positions are in window units).
Result<double> follow_framebuffer(GLFWwindow* window, GlobeRenderer& renderer, Camera& camera,
                                  int& fb_w, int& fb_h) {
  glfwGetFramebufferSize(window, &fb_w, &fb_h);
  if (fb_w > 0 && fb_h > 0 && (fb_w != renderer.width() || fb_h != renderer.height())) {
    if (Status st = renderer.resize(fb_w, fb_h); !st) return st.error();
    camera.set_viewport(fb_w, fb_h);
  }
  int win_w = 1, win_h = 1;
  glfwGetWindowSize(window, &win_w, &win_h);
  return static_cast<double>(fb_w) / std::max(win_w, 1);
}

// Moves the camera for this frame: the path, else a fly-to, else the user's mouse and keys.
void steer_camera(GLFWwindow* window, const Session& s, GlobeRenderer& renderer, Camera& camera,
                  Autopilot& pilot, DragState& drag, const PanelState& ps, double dt, double scale,
                  bool complete) {
  if (pilot.scripted()) {
    camera.set_pose(pilot.path->advance(dt, complete));
  } else if (pilot.flight.active()) {
    camera.set_pose(pilot.flight.advance(dt));
  } else {
    handle_mouse(window, renderer, camera, drag, scale);
    handle_keys(window, camera, dt);
    if (!ImGui::GetIO().WantCaptureKeyboard) {
      if (ImGui::IsKeyPressed(GLFW_KEY_F))
        pilot.flight =
            FlyTo(camera.pose(), s.framing(camera, static_cast<std::size_t>(ps.layer_choice)), 2.5);
      if (ImGui::IsKeyPressed(GLFW_KEY_R))
        pilot.flight = FlyTo(camera.pose(), s.framing(camera), 2.5);
    }
  }
}

// The ground point under the cursor, for the panel (none over the sky).
std::optional<geo::Geodetic> ground_under_cursor(GLFWwindow* window, GlobeRenderer& renderer,
                                                 const Camera& camera, double scale) {
  double cx = 0, cy = 0;
  glfwGetCursorPos(window, &cx, &cy);
  if (auto p = renderer.pick(camera, static_cast<int>(cx * scale), static_cast<int>(cy * scale)))
    return geo::from_ecef({p->x, p->y, p->z});
  return std::nullopt;
}

// --out: once the view is complete and the path flown (or --timeout passed), writes the window
// to the PNG. Returns the exit status when it wrote (or failed to write), nothing before.
std::optional<int> snapshot_when_settled(const ViewerOptions& o, int complete_frames,
                                         const Autopilot& pilot, double elapsed_s, int fb_w,
                                         int fb_h) {
  const bool settled = complete_frames >= 3 && !pilot.flight.active() && !pilot.scripted();
  const bool timed_out = elapsed_s > o.timeout_s + pilot.path_s;
  if (!settled && !timed_out) return std::nullopt;
  const Image shot{fb_w, fb_h, read_framebuffer_rgba(0, fb_w, fb_h)};
  if (Status st = write_png(o.out, shot); !st) {
    std::cerr << "tinstream-viewer: " << st.error().message << '\n';
    return 1;
  }
  std::cerr << "tinstream-viewer: wrote " << o.out.string() << '\n';
  if (settled) return 0;
  std::cerr << "tinstream-viewer: the view was not complete after " << o.timeout_s
            << " s (--timeout); the window shows what had arrived\n";
  return 3;
}

// Blocks until an event arrives (a tile landing posts an empty one), at most wait_s (< 0: no
// limit) and never past --close-after.
void wait_for_events(double wait_s, double close_after_s, Clock::duration open) {
  if (close_after_s > 0) {
    const double left = close_after_s - std::chrono::duration<double>(open).count();
    wait_s = wait_s < 0 ? left : std::min(wait_s, left);
  }
  if (wait_s < 0)
    glfwWaitEvents();
  else
    glfwWaitEventsTimeout(std::max(wait_s, 1e-3));
}

bool same_pose(const CameraPose& a, const CameraPose& b) {
  return a.lon == b.lon && a.lat == b.lat && a.height == b.height && a.heading == b.heading &&
         a.pitch == b.pitch;
}

// --close-after: one JSON line on stdout with the frames the window drew.
void print_window_run(const RedrawScheduler& redraw, bool complete, double open_s,
                      double since_last_frame_s) {
  std::printf(
      "{\"window\":{\"seconds\":%.3f,\"frames\":%llu,\"since_last_frame_s\":%.3f,"
      "\"complete\":%s}}\n",
      open_s, static_cast<unsigned long long>(redraw.frames_drawn()), since_last_frame_s,
      complete ? "true" : "false");
  std::fflush(stdout);
}

}  // namespace

int run_window(const ViewerOptions& o) {
  auto session = open_session(o);
  if (!session) {
    std::cerr << "tinstream-viewer: " << session.error().message << '\n';
    return 2;
  }
  Session& s = *session;
  for (const std::string& w : s.warnings) std::cerr << "tinstream-viewer: warning: " << w << '\n';
  GlfwSession glfw;
  if (int st = open_window(glfw, o); st != 0) return st;
  int fb_w = 0, fb_h = 0;
  glfwGetFramebufferSize(glfw.window, &fb_w, &fb_h);
  auto graphics = create_graphics(s, o, fb_w, fb_h);
  if (!graphics) {
    std::cerr << "tinstream-viewer: " << graphics.error().message << '\n';
    return 1;
  }
  GlobeRenderer& renderer = *graphics->renderer;
  RedrawScheduler redraw;
  install_wake_callbacks(glfw.window, redraw);
  ImGui_ImplGlfw_InitForOpenGL(glfw.window, true);

  Camera camera(fb_w, fb_h, o.fov);
  camera.log_depth = renderer.log_depth();
  auto pilot = start_camera(s, o, camera);
  if (!pilot) {
    std::cerr << "tinstream-viewer: " << pilot.error().message << '\n';
    return 2;
  }
  PanelState ps;
  ps.wireframe = o.wireframe;
  ps.max_sse = static_cast<float>(o.max_sse);
  ps.threads = s.loader->threads();
  DragState drag;
  const auto start = Clock::now();
  auto last = start;
  auto last_drawn = start;
  double frame_ms = 0;
  bool complete = false;
  int complete_frames = 0;  // frames in a row with a complete view (the panel needs two to lay out)
  int status = 0;
  // A tile landed (a download worker's thread): the next frame takes it. Cleared after the loop,
  // before the window and `redraw` go away.
  s.loader->set_result_callback([&redraw] {
    redraw.wake(Wake::content);
    glfwPostEmptyEvent();
  });

  while (!glfwWindowShouldClose(glfw.window)) {
    glfwPollEvents();
    const auto woke = Clock::now();
    if (o.close_after_s > 0 &&
        std::chrono::duration<double>(woke - start).count() >= o.close_after_s) {
      print_window_run(redraw, complete, std::chrono::duration<double>(woke - start).count(),
                       std::chrono::duration<double>(woke - last_drawn).count());
      break;
    }
    const RedrawScheduler::Decision decision = redraw.next(woke);
    if (!decision.draw) {
      wait_for_events(decision.wait_s, o.close_after_s, woke - start);
      // The time asleep is no frame time: a key pressed after a long wait moves the camera
      // by one frame's step, not by the whole wait's.
      last = Clock::now();
      continue;
    }
    const auto now = Clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    const auto scale = follow_framebuffer(glfw.window, renderer, camera, fb_w, fb_h);
    if (!scale) {
      std::cerr << "tinstream-viewer: " << scale.error().message << '\n';
      break;
    }
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    const CameraPose before = camera.pose();
    steer_camera(glfw.window, s, renderer, camera, *pilot, drag, ps, dt, *scale, complete);
    ps.cursor = ground_under_cursor(glfw.window, renderer, camera, *scale);

    const auto t0 = Clock::now();
    const std::uint64_t evictions_before = tier_evictions(*s.streamer);
    const FrameResult& f = s.streamer->update(camera, renderer);
    renderer.render(camera, f.draws, s.render_settings(ps.wireframe));
    renderer.present(fb_w, fb_h);
    const PanelLayout layout = draw_panel(s, camera, ps, pilot->flight, frame_ms);
    std::optional<OverlayRect> legend;
    if (o.legend) legend = draw_legend(s.legend);
    graphics->overlay->render(fb_w, fb_h);
    complete = f.complete;
    complete_frames = f.complete ? complete_frames + 1 : 0;
    if (!o.out.empty()) {
      const double elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
      if (auto shot = snapshot_when_settled(o, complete_frames, *pilot, elapsed_s, fb_w, fb_h)) {
        status = *shot;
        print_layout(layout, legend);
        glfwSetWindowShouldClose(glfw.window, GLFW_TRUE);
      }
    }
    glfwSwapBuffers(glfw.window);
    last_drawn = Clock::now();
    frame_ms = std::chrono::duration<double, std::milli>(last_drawn - t0).count();
    FrameActivity activity = streamer_activity(*s.streamer, evictions_before);
    activity.camera_moved = !same_pose(before, camera.pose());
    // --out waits for frames in a row with a complete view: a scripted run draws every frame.
    activity.animating = pilot->flight.active() || pilot->scripted() || !o.out.empty();
    redraw.frame_drawn(activity, last_drawn);
  }
  s.loader->set_result_callback(nullptr);
  s.streamer->release_all(renderer);
  ImGui_ImplGlfw_Shutdown();
  graphics->renderer.reset();
  graphics->overlay.reset();
  return status;
}

}  // namespace tinstream::client
