// Compiling and linking GLSL programs with errors that name the program and quote the log.
// Render thread only (needs the current GL context).
#pragma once

#include <epoxy/gl.h>

#include <string>
#include <utility>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::client::gl {

struct Stage {
  GLenum type;
  const char* source;  // without the #version line
};

// `defines`: lines such as "#define WIREFRAME", inserted after "#version 330 core".
Result<GLuint> build_program(const std::string& name, const std::vector<Stage>& stages,
                             const std::vector<std::string>& defines = {});

}  // namespace tinstream::client::gl
