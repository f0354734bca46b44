// tinstream/client/egl_context.hpp — an OpenGL context without a display or a window: a GPU's
// EGL device where there is one (EGL_EXT_platform_device, e.g. NVIDIA's driver on a headless
// server), else EGL's surfaceless platform (EGL_MESA_platform_surfaceless) on Mesa, e.g. its
// llvmpipe software renderer. No X server, no window; the renderer draws into its own framebuffer
// objects. Used by --headless (and so by the tests). Owns the display connection and the context;
// the thread that created it has it current. LIBGL_ALWAYS_SOFTWARE=1 (Mesa) or
// __EGL_VENDOR_LIBRARY_FILENAMES (glvnd) choose another.
#pragma once

#include <memory>
#include <string>

#include "tinstream/base/result.hpp"

namespace tinstream::client {

class EglContext {
 public:
  // An OpenGL ≥ 3.3 core-profile context, current on the calling thread. Errors say which EGL
  // step failed and what is missing.
  static Result<std::unique_ptr<EglContext>> create();
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

 private:
  EglContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
};

}  // namespace tinstream::client
