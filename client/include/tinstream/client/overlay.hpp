// tinstream/client/overlay.hpp — Dear ImGui on top of the rendered frame: the legend in both
// modes, the control panel in the window.
//
// Debian's libimgui-dev (1.86) ships the ImGui core and its backends precompiled in libimgui.a;
// its OpenGL 3 backend loads GL entry points through GLX, which a headless EGL context does not
// have, so the overlay draws ImGui's draw lists itself (through libepoxy, like the renderer):
// one font texture, one program, streamed vertex/index buffers. The window mode takes input from
// the packaged GLFW backend (imgui_impl_glfw). Render thread only; one Overlay per GL context.
#pragma once

#include <memory>
#include <string>

#include "tinstream/base/result.hpp"

struct ImDrawData;

namespace tinstream::client {

struct LegendInfo {
  double ramp_min = 0, ramp_max = 1000;  // metres
  std::string title = "height (m, WGS84)";
  std::string footer;  // e.g. the layers and their attribution
};

class Overlay {
 public:
  // Creates the ImGui context (and makes it current) and the GL objects. Requires a current
  // OpenGL ≥ 3.3 core context.
  static Result<std::unique_ptr<Overlay>> create();
  ~Overlay();
  Overlay(const Overlay&) = delete;
  Overlay& operator=(const Overlay&) = delete;

  // Headless: starts an ImGui frame of the given size (no input).
  void new_headless_frame(int width, int height);
  // Ends the ImGui frame without drawing it. ImGui sizes auto-resizing windows during their first
  // frame and shows them from the second, so a single headless frame is preceded by one of these.
  void discard_frame();
  // Ends the ImGui frame and draws it into the currently bound framebuffer.
  void render(int framebuffer_width, int framebuffer_height);

  struct Impl;

 private:
  explicit Overlay(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// A rectangle of the overlay in ImGui's display units (window units, origin top left, y down).
struct OverlayRect {
  float x = 0, y = 0, width = 0, height = 0;
};

// ImGui calls that draw the colour-ramp legend in the bottom-right corner (inside a frame).
// Returns where ImGui placed it this frame (window mode reports it with --out).
OverlayRect draw_legend(const LegendInfo& legend);

}  // namespace tinstream::client
