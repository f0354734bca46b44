#include "tinstream/client/egl_context.hpp"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace tinstream::client {

namespace {

std::string egl_error(const char* step) {
  char code[16];
  std::snprintf(code, sizeof code, "0x%04X", static_cast<unsigned>(eglGetError()));
  return std::string("EGL: ") + step + " failed (error " + code + ")";
}

bool has_extension(const char* list, std::string_view name) {
  if (!list) return false;
  const std::string_view all(list);
  for (std::size_t at = all.find(name); at != std::string_view::npos; at = all.find(name, at + 1)) {
    const bool starts = at == 0 || all[at - 1] == ' ';
    const bool ends = at + name.size() == all.size() || all[at + name.size()] == ' ';
    if (starts && ends) return true;
  }
  return false;
}

// An initialised display: a hardware EGL device first (EGL_EXT_platform_device: a GPU driver
// such as NVIDIA's on a server without X), then Mesa's surfaceless platform (llvmpipe where
// there is no GPU: CI, containers), then any device (Mesa's software device). Errors name what
// was tried.
Result<EGLDisplay> open_display() {
  const char* client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  std::string tried;
  auto initialise = [&](EGLDisplay display, const char* what) -> bool {
    EGLint major = 0, minor = 0;
    if (display != EGL_NO_DISPLAY && eglInitialize(display, &major, &minor)) return true;
    tried += std::string(tried.empty() ? "" : "; ") + what + ": " +
             egl_error(display == EGL_NO_DISPLAY ? "eglGetPlatformDisplayEXT" : "eglInitialize");
    return false;
  };
  std::vector<EGLDeviceEXT> devices;
  if (has_extension(client_ext, "EGL_EXT_platform_device") &&
      has_extension(client_ext, "EGL_EXT_device_enumeration")) {
    EGLint count = 0;
    if (eglQueryDevicesEXT(0, nullptr, &count) && count > 0) {
      devices.resize(static_cast<std::size_t>(count));
      if (!eglQueryDevicesEXT(count, devices.data(), &count)) count = 0;
      devices.resize(static_cast<std::size_t>(count));
    }
  }
  auto software = [](EGLDeviceEXT d) {
    return has_extension(eglQueryDeviceStringEXT(d, EGL_EXTENSIONS), "EGL_MESA_device_software");
  };
  for (EGLDeviceEXT d : devices) {
    if (software(d)) continue;
    EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, d, nullptr);
    if (initialise(display, "EGL device")) return display;
  }
  if (has_extension(client_ext, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay display =
        eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (initialise(display, "surfaceless platform")) return display;
  }
  for (EGLDeviceEXT d : devices) {
    if (!software(d)) continue;
    EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, d, nullptr);
    if (initialise(display, "EGL software device")) return display;
  }
  if (tried.empty())
    return unsupported(
        "EGL: neither an EGL device (EGL_EXT_platform_device) nor the surfaceless platform "
        "(EGL_MESA_platform_surfaceless) is available; headless rendering needs a GPU driver's "
        "libEGL or Mesa's (Debian: libegl-mesa0)");
  return unsupported("EGL: no display could be opened (" + tried + ")");
}

}  // namespace

Result<std::unique_ptr<EglContext>> EglContext::create() {
  auto opened = open_display();
  if (!opened) return opened.error();
  EGLDisplay display = *opened;
  std::unique_ptr<EglContext> ctx(new EglContext());
  ctx->display_ = display;
  if (!eglBindAPI(EGL_OPENGL_API)) return unsupported(egl_error("eglBindAPI(OpenGL)"));
  const EGLint attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                               3,
                               EGL_CONTEXT_MINOR_VERSION,
                               3,
                               EGL_CONTEXT_OPENGL_PROFILE_MASK,
                               EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                               EGL_NONE};
  // No config: the context only ever draws into framebuffer objects (EGL_KHR_no_config_context).
  // A driver without that extension gets any OpenGL-renderable config.
  EGLContext context = EGL_NO_CONTEXT;
  if (has_extension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_no_config_context"))
    context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes);
  if (context == EGL_NO_CONTEXT) {
    const EGLint wanted[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint n = 0;
    if (eglChooseConfig(display, wanted, &config, 1, &n) && n == 1)
      context = eglCreateContext(display, config, EGL_NO_CONTEXT, attributes);
  }
  if (context == EGL_NO_CONTEXT) return unsupported(egl_error("eglCreateContext(OpenGL 3.3 core)"));
  ctx->context_ = context;
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context))
    return unsupported(egl_error("eglMakeCurrent(surfaceless)"));
  if (epoxy_gl_version() < 33)
    return unsupported("EGL: the OpenGL context is version " + std::to_string(epoxy_gl_version()) +
                       ", 33 or later is needed");
  return ctx;
}

EglContext::~EglContext() {
  if (display_) {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (context_) eglDestroyContext(display_, context_);
    eglTerminate(display_);
  }
}

}  // namespace tinstream::client
