// The in-process OpenGL target of the rendering tests (drape_test.cpp, render_test.cpp): an EGL
// context on Mesa, current on the calling thread, and a GlobeRenderer drawing into a
// size × size framebuffer without MSAA. The renderer is destroyed before the context (members
// in reverse order); both belong to the test's thread.
#pragma once

#include <memory>

#include "tinstream/base/result.hpp"
#include "tinstream/client/egl_context.hpp"
#include "tinstream/client/renderer.hpp"

namespace tinstream::client::testing {

struct OffscreenRenderer {
  std::unique_ptr<EglContext> context;
  std::unique_ptr<GlobeRenderer> renderer;
};

inline Result<OffscreenRenderer> open_offscreen_renderer(int size) {
  auto context = EglContext::create();
  if (!context) return context.error();
  RendererOptions options;
  options.width = options.height = size;
  options.msaa = 0;
  auto renderer = GlobeRenderer::create(options);
  if (!renderer) return renderer.error();
  return OffscreenRenderer{std::move(*context), std::move(*renderer)};
}

}  // namespace tinstream::client::testing
