#include "tinstream/client/egl_context.hpp"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <cstdio>
#include <string>

namespace tinstream::client {

namespace {

std::string egl_error(const char* step) {
  char code[16];
  std::snprintf(code, sizeof code, "0x%04X", static_cast<unsigned>(eglGetError()));
  return std::string("EGL: ") + step + " failed (error " + code + ")";
}

}  // namespace

Result<std::unique_ptr<EglContext>> EglContext::create() {
  const char* client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!client_ext ||
      std::string(client_ext).find("EGL_MESA_platform_surfaceless") == std::string::npos)
    return unsupported(
        "EGL: the surfaceless platform (EGL_MESA_platform_surfaceless) is not available; headless "
        "rendering needs Mesa's libEGL (Debian: libegl-mesa0)");
  EGLDisplay display =
      eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (display == EGL_NO_DISPLAY)
    return unsupported(egl_error("eglGetPlatformDisplayEXT(surfaceless)"));
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display, &major, &minor)) return unsupported(egl_error("eglInitialize"));
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
  EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes);
  if (context == EGL_NO_CONTEXT)
    return unsupported(egl_error("eglCreateContext(OpenGL 3.3 core, no config)"));
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
