#include "tinstream/client/overlay.hpp"

#include <epoxy/gl.h>
#include <imgui.h>

#include <cstdint>
#include <cstdio>

#include "gl_program.hpp"
#include "shaders.hpp"
#include "tinstream/client/renderer.hpp"

namespace tinstream::client {

namespace {

// GL's convention: a byte offset into the bound buffer, passed as a pointer.
void* gl_offset(std::size_t bytes) {
  return reinterpret_cast<void*>(bytes);  // NOLINT(performance-no-int-to-ptr)
}

}  // namespace

struct Overlay::Impl {
  ImGuiContext* context = nullptr;
  GLuint program = 0, font_texture = 0, vao = 0, vbo = 0, ibo = 0;
  GLint projection = -1, texture = -1;

  ~Impl() {
    if (font_texture) glDeleteTextures(1, &font_texture);
    if (vao) glDeleteVertexArrays(1, &vao);
    if (vbo) glDeleteBuffers(1, &vbo);
    if (ibo) glDeleteBuffers(1, &ibo);
    if (program) glDeleteProgram(program);
    if (context) ImGui::DestroyContext(context);
  }
};

Overlay::Overlay(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Overlay::~Overlay() = default;

Result<std::unique_ptr<Overlay>> Overlay::create() {
  auto impl = std::make_unique<Impl>();
  impl->context = ImGui::CreateContext();
  ImGui::SetCurrentContext(impl->context);
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini next to the user's files
  io.BackendRendererName = "tinstream_overlay";
  io.BackendFlags |= ImGuiBackendFlags_RendererHasVtxOffset;
  ImGui::StyleColorsDark();

  auto program = gl::build_program("overlay", {{GL_VERTEX_SHADER, shaders::kOverlayVertex},
                                               {GL_FRAGMENT_SHADER, shaders::kOverlayFragment}});
  if (!program) return program.error();
  impl->program = *program;
  impl->projection = glGetUniformLocation(impl->program, "u_projection");
  impl->texture = glGetUniformLocation(impl->program, "u_texture");

  unsigned char* pixels = nullptr;
  int width = 0, height = 0;
  io.Fonts->GetTexDataAsRGBA32(&pixels, &width, &height);
  glGenTextures(1, &impl->font_texture);
  glBindTexture(GL_TEXTURE_2D, impl->font_texture);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE, pixels);
  // ImGui's texture ids are pointers; ours carry a GL texture name.
  io.Fonts->SetTexID(reinterpret_cast<ImTextureID>(  // NOLINT(performance-no-int-to-ptr)
      static_cast<std::intptr_t>(impl->font_texture)));

  glGenVertexArrays(1, &impl->vao);
  glBindVertexArray(impl->vao);
  glGenBuffers(1, &impl->vbo);
  glGenBuffers(1, &impl->ibo);
  glBindBuffer(GL_ARRAY_BUFFER, impl->vbo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, impl->ibo);
  constexpr GLsizei stride = sizeof(ImDrawVert);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, stride, gl_offset(offsetof(ImDrawVert, pos)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, stride, gl_offset(offsetof(ImDrawVert, uv)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, stride,
                        gl_offset(offsetof(ImDrawVert, col)));
  glBindVertexArray(0);
  return std::unique_ptr<Overlay>(new Overlay(std::move(impl)));
}

void Overlay::new_headless_frame(int width, int height) {
  ImGui::SetCurrentContext(impl_->context);
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize = ImVec2(static_cast<float>(width), static_cast<float>(height));
  io.DisplayFramebufferScale = ImVec2(1, 1);
  io.DeltaTime = 1.0f / 60.0f;
  ImGui::NewFrame();
}

void Overlay::discard_frame() {
  ImGui::SetCurrentContext(impl_->context);
  ImGui::EndFrame();
}

void Overlay::render(int framebuffer_width, int framebuffer_height) {
  ImGui::SetCurrentContext(impl_->context);
  ImGui::Render();
  const ImDrawData* data = ImGui::GetDrawData();
  if (!data || data->CmdListsCount == 0) return;
  glViewport(0, 0, framebuffer_width, framebuffer_height);
  glEnable(GL_BLEND);
  glBlendEquation(GL_FUNC_ADD);
  glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glDisable(GL_CULL_FACE);
  glDisable(GL_DEPTH_TEST);
  glEnable(GL_SCISSOR_TEST);
  glUseProgram(impl_->program);
  const float l = data->DisplayPos.x, r = data->DisplayPos.x + data->DisplaySize.x;
  const float t = data->DisplayPos.y, b = data->DisplayPos.y + data->DisplaySize.y;
  const float ortho[16] = {2 / (r - l), 0, 0, 0,  0, 2 / (t - b),       0,
                           0,           0, 0, -1, 0, (r + l) / (l - r), (t + b) / (b - t),
                           0,           1};
  glUniformMatrix4fv(impl_->projection, 1, GL_FALSE, ortho);
  glUniform1i(impl_->texture, 0);
  glActiveTexture(GL_TEXTURE0);
  glBindVertexArray(impl_->vao);
  glBindBuffer(GL_ARRAY_BUFFER, impl_->vbo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, impl_->ibo);
  const ImVec2 scale = data->FramebufferScale;
  for (int n = 0; n < data->CmdListsCount; ++n) {
    const ImDrawList* list = data->CmdLists[n];
    glBufferData(GL_ARRAY_BUFFER,
                 static_cast<GLsizeiptr>(static_cast<std::size_t>(list->VtxBuffer.Size) *
                                         sizeof(ImDrawVert)),
                 list->VtxBuffer.Data, GL_STREAM_DRAW);
    glBufferData(
        GL_ELEMENT_ARRAY_BUFFER,
        static_cast<GLsizeiptr>(static_cast<std::size_t>(list->IdxBuffer.Size) * sizeof(ImDrawIdx)),
        list->IdxBuffer.Data, GL_STREAM_DRAW);
    for (int c = 0; c < list->CmdBuffer.Size; ++c) {
      const ImDrawCmd& cmd = list->CmdBuffer[c];
      if (cmd.UserCallback) continue;  // none of ours use callbacks
      const float x0 = (cmd.ClipRect.x - l) * scale.x, y0 = (cmd.ClipRect.y - t) * scale.y;
      const float x1 = (cmd.ClipRect.z - l) * scale.x, y1 = (cmd.ClipRect.w - t) * scale.y;
      if (x1 <= x0 || y1 <= y0) continue;
      glScissor(static_cast<GLint>(x0),
                static_cast<GLint>(static_cast<float>(framebuffer_height) - y1),
                static_cast<GLsizei>(x1 - x0), static_cast<GLsizei>(y1 - y0));
      glBindTexture(GL_TEXTURE_2D,
                    static_cast<GLuint>(reinterpret_cast<std::intptr_t>(cmd.GetTexID())));
      glDrawElementsBaseVertex(GL_TRIANGLES, static_cast<GLsizei>(cmd.ElemCount),
                               sizeof(ImDrawIdx) == 2 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_INT,
                               gl_offset(cmd.IdxOffset * sizeof(ImDrawIdx)),
                               static_cast<GLint>(cmd.VtxOffset));
    }
  }
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glBindVertexArray(0);
  glUseProgram(0);
}

OverlayRect draw_legend(const LegendInfo& legend) {
  const float bar_w = 200, bar_h = 14;
  // Bottom right, as wide as its bar (the title and footer wrap): the panel (window mode) sits
  // top left and at 640×360 reaches the bottom left corner.
  const ImVec2 display = ImGui::GetIO().DisplaySize;
  ImGui::SetNextWindowPos(ImVec2(display.x - 10, display.y - 10), ImGuiCond_Always, ImVec2(1, 1));
  ImGui::SetNextWindowBgAlpha(0.55f);
  ImGui::Begin("legend", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                   ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
                   ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav);
  ImGui::PushTextWrapPos(ImGui::GetCursorPosX() + bar_w);
  ImGui::TextUnformatted(legend.title.c_str());
  const ImVec2 p = ImGui::GetCursorScreenPos();
  ImDrawList* dl = ImGui::GetWindowDrawList();
  const auto colour = [](std::size_t i) {
    const auto& s = kRampStops[i];
    return ImGui::GetColorU32(ImVec4(s[0], s[1], s[2], 1.0f));
  };
  const float seg = bar_w / static_cast<float>(kRampStops.size() - 1);
  for (std::size_t i = 0; i + 1 < kRampStops.size(); ++i) {
    const float x = p.x + seg * static_cast<float>(i);
    dl->AddRectFilledMultiColor(ImVec2(x, p.y), ImVec2(x + seg, p.y + bar_h), colour(i),
                                colour(i + 1), colour(i + 1), colour(i));
  }
  ImGui::Dummy(ImVec2(bar_w, bar_h));
  char text[64];
  std::snprintf(text, sizeof text, "%.0f", legend.ramp_min);
  ImGui::TextUnformatted(text);
  std::snprintf(text, sizeof text, "%.0f", (legend.ramp_min + legend.ramp_max) / 2);
  ImGui::SameLine(bar_w / 2 - ImGui::CalcTextSize(text).x / 2);
  ImGui::TextUnformatted(text);
  std::snprintf(text, sizeof text, "%.0f", legend.ramp_max);
  ImGui::SameLine(bar_w - ImGui::CalcTextSize(text).x);
  ImGui::TextUnformatted(text);
  if (!legend.footer.empty()) ImGui::TextUnformatted(legend.footer.c_str());
  ImGui::PopTextWrapPos();
  const ImVec2 pos = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
  ImGui::End();
  return {pos.x, pos.y, size.x, size.y};
}

}  // namespace tinstream::client
