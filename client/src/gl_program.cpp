#include "gl_program.hpp"

#include <algorithm>

namespace tinstream::client::gl {

namespace {

std::string shader_log(GLuint shader) {
  GLint length = 0;
  glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
  glGetShaderInfoLog(shader, length, nullptr, log.data());
  return log;
}

std::string program_log(GLuint program) {
  GLint length = 0;
  glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
  glGetProgramInfoLog(program, length, nullptr, log.data());
  return log;
}

Error program_error(const std::string& name, const char* step, const std::string& log) {
  return Error(ErrorCode::internal, "OpenGL program \"" + name + "\": " + step + " failed: " + log);
}

}  // namespace

Result<GLuint> build_program(const std::string& name, const std::vector<Stage>& stages,
                             const std::vector<std::string>& defines) {
  std::string header = "#version 330 core\n";
  for (const std::string& d : defines) header += d + "\n";
  const GLuint program = glCreateProgram();
  std::vector<GLuint> shaders;
  for (const Stage& stage : stages) {
    const GLuint shader = glCreateShader(stage.type);
    const char* sources[2] = {header.c_str(), stage.source};
    glShaderSource(shader, 2, sources, nullptr);
    glCompileShader(shader);
    GLint ok = GL_FALSE;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
      const std::string log = shader_log(shader);
      glDeleteShader(shader);
      for (GLuint s : shaders) glDeleteShader(s);
      glDeleteProgram(program);
      return program_error(name, "compiling a shader", log);
    }
    glAttachShader(program, shader);
    shaders.push_back(shader);
  }
  glLinkProgram(program);
  for (GLuint s : shaders) glDeleteShader(s);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    const std::string log = program_log(program);
    glDeleteProgram(program);
    return program_error(name, "linking", log);
  }
  return program;
}

}  // namespace tinstream::client::gl
