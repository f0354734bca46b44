#include "tinstream/client/renderer.hpp"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "gl_program.hpp"
#include "shaders.hpp"
#include "tinstream/geo/ecef.hpp"
#include "tinstream/imagery/image.hpp"

namespace tinstream::client {

namespace {

constexpr float kSky[3] = {0.02f, 0.02f, 0.04f};
constexpr double kLogDepthFar = 1e9;  // metres
// The fallback ellipsoid: 10° patches of 16 × 16 cells (chords sag at most ~100 m below it).
constexpr int kPatchDegrees = 10;
constexpr int kPatchCells = 16;

struct TerrainProgram {
  GLuint id = 0;
  GLint mvp = -1, light = -1, ramp = -1, mask = -1, log_coef = -1, stops = -1, centre = -1,
        skirt = -1, image = -1, image_uv = -1;
};

struct GlobeProgram {
  GLuint id = 0;
  GLint mvp = -1, sun = -1, log_coef = -1;
};

struct GlobePatch {
  Vec3 centre;
  Obb box;
  GLint base_vertex = 0;
};

std::uint32_t snorm10(double v) {
  const auto i = static_cast<std::int32_t>(std::lround(std::clamp(v, -1.0, 1.0) * 511.0));
  return static_cast<std::uint32_t>(i) & 0x3FFu;
}

std::uint16_t unorm16(double t) {
  return static_cast<std::uint16_t>(std::lround(std::clamp(t, 0.0, 1.0) * 65535.0));
}

// Vertex attributes of MeshVertex (render_mesh.hpp) in the bound VAO/VBO.
void set_vertex_layout() {
  constexpr GLsizei stride = sizeof(MeshVertex);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(0));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 1, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(12));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 4, GL_INT_2_10_10_10_REV, GL_TRUE, stride, reinterpret_cast<void*>(16));
  glEnableVertexAttribArray(3);
  glVertexAttribPointer(3, 2, GL_UNSIGNED_SHORT, GL_TRUE, stride, reinterpret_cast<void*>(20));
}

void set_matrix(GLint location, const Mat4& m) {
  const std::array<float, 16> f = m.to_float();
  glUniformMatrix4fv(location, 1, GL_FALSE, f.data());
}

}  // namespace

std::uint64_t flush_interval(std::string_view gl_renderer, std::int64_t requested) {
  if (requested >= 0) return static_cast<std::uint64_t>(requested);
  for (const std::string_view software : {"llvmpipe", "softpipe", "swrast"})
    if (gl_renderer.find(software) != std::string_view::npos) return kSoftwareFlushTriangles;
  return 0;
}

struct GlobeRenderer::Impl {
  RendererOptions options;
  bool log_depth = false;
  std::uint64_t flush_triangles = 0;  // flush_interval's; 0: never
  int samples = 0;
  GLuint scene_fbo = 0, scene_color = 0, scene_depth = 0;
  GLuint resolve_fbo = 0, resolve_color = 0, resolve_depth = 0;
  std::array<TerrainProgram, 8> terrain{};  // index: wireframe·1 + masked·2 + imagery·4
  GlobeProgram globe;
  GLuint globe_vao = 0, globe_vbo = 0, globe_ibo = 0;
  GLsizei patch_index_count = 0;
  std::vector<GlobePatch> patches;

  ~Impl() {
    delete_targets();
    for (const TerrainProgram& p : terrain)
      if (p.id) glDeleteProgram(p.id);
    if (globe.id) glDeleteProgram(globe.id);
    if (globe_vao) glDeleteVertexArrays(1, &globe_vao);
    if (globe_vbo) glDeleteBuffers(1, &globe_vbo);
    if (globe_ibo) glDeleteBuffers(1, &globe_ibo);
  }

  void delete_targets() {
    if (scene_fbo && scene_fbo != resolve_fbo) glDeleteFramebuffers(1, &scene_fbo);
    if (resolve_fbo) glDeleteFramebuffers(1, &resolve_fbo);
    for (GLuint* rb : {&scene_color, &scene_depth, &resolve_color, &resolve_depth})
      if (*rb) glDeleteRenderbuffers(1, rb);
    scene_fbo = scene_color = scene_depth = resolve_fbo = resolve_color = resolve_depth = 0;
  }

  Status make_target(int width, int height, int sample_count, GLuint& fbo, GLuint& color,
                     GLuint& depth) {
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glGenRenderbuffers(1, &color);
    glBindRenderbuffer(GL_RENDERBUFFER, color);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, sample_count, GL_RGBA8, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
    glGenRenderbuffers(1, &depth);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, sample_count, GL_DEPTH_COMPONENT32F, width,
                                     height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE)
      return Error(ErrorCode::unsupported,
                   "OpenGL: a " + std::to_string(width) + "×" + std::to_string(height) +
                       " render target with " + std::to_string(sample_count) +
                       " samples is incomplete (status " + std::to_string(status) + ")");
    return {};
  }

  Status make_targets(int width, int height) {
    delete_targets();
    if (Status s = make_target(width, height, 0, resolve_fbo, resolve_color, resolve_depth); !s)
      return s;
    if (samples > 1) {
      if (Status s = make_target(width, height, samples, scene_fbo, scene_color, scene_depth); !s)
        return s;
    } else {
      scene_fbo = resolve_fbo;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, resolve_fbo);
    return {};
  }

  Status build_programs() {
    std::vector<std::string> common;
    if (log_depth) common.emplace_back("#define LOG_DEPTH");
    for (int variant = 0; variant < 8; ++variant) {
      std::vector<std::string> defines = common;
      std::vector<gl::Stage> stages{{GL_VERTEX_SHADER, shaders::kTerrainVertex}};
      if (variant & 1) {
        defines.emplace_back("#define WIREFRAME");
        stages.push_back({GL_GEOMETRY_SHADER, shaders::kTerrainGeometry});
      }
      if (variant & 2) defines.emplace_back("#define MASKED");
      if (variant & 4) defines.emplace_back("#define IMAGERY");
      stages.push_back({GL_FRAGMENT_SHADER, shaders::kTerrainFragment});
      auto program = gl::build_program("terrain", stages, defines);
      if (!program) return program.error();
      TerrainProgram& p = terrain[static_cast<std::size_t>(variant)];
      p.id = *program;
      p.mvp = glGetUniformLocation(p.id, "u_mvp");
      p.light = glGetUniformLocation(p.id, "u_light");
      p.ramp = glGetUniformLocation(p.id, "u_ramp");
      p.mask = glGetUniformLocation(p.id, "u_mask");
      p.log_coef = glGetUniformLocation(p.id, "u_log_coef");
      p.stops = glGetUniformLocation(p.id, "u_stops");
      p.centre = glGetUniformLocation(p.id, "u_centre");
      p.skirt = glGetUniformLocation(p.id, "u_skirt");
      p.image = glGetUniformLocation(p.id, "u_image");
      p.image_uv = glGetUniformLocation(p.id, "u_image_uv");
    }
    auto program = gl::build_program(
        "globe",
        {{GL_VERTEX_SHADER, shaders::kGlobeVertex}, {GL_FRAGMENT_SHADER, shaders::kGlobeFragment}},
        common);
    if (!program) return program.error();
    globe.id = *program;
    globe.mvp = glGetUniformLocation(globe.id, "u_mvp");
    globe.sun = glGetUniformLocation(globe.id, "u_sun");
    globe.log_coef = glGetUniformLocation(globe.id, "u_log_coef");
    return {};
  }

  // The fallback ellipsoid at options.globe_height: one vertex buffer of all patches, one shared
  // index list (every patch has the same grid), drawn with a base vertex per patch.
  void build_globe() {
    constexpr int n = kPatchCells + 1;
    std::vector<MeshVertex> vertices;
    for (int lat0 = -90; lat0 < 90; lat0 += kPatchDegrees) {
      for (int lon0 = -180; lon0 < 180; lon0 += kPatchDegrees) {
        GlobePatch patch;
        const double clon = lon0 + kPatchDegrees / 2.0, clat = lat0 + kPatchDegrees / 2.0;
        const geo::Ecef c = geo::to_ecef({clon, clat, options.globe_height});
        patch.centre = {c.x, c.y, c.z};
        patch.base_vertex = static_cast<GLint>(vertices.size());
        std::vector<Vec3> points;
        for (int j = 0; j < n; ++j) {
          const double lat = lat0 + static_cast<double>(kPatchDegrees) * j / kPatchCells;
          for (int i = 0; i < n; ++i) {
            const double lon = lon0 + static_cast<double>(kPatchDegrees) * i / kPatchCells;
            const geo::Ecef e = geo::to_ecef({lon, lat, options.globe_height});
            const Vec3 p{e.x, e.y, e.z};
            points.push_back(p);
            const Vec3 local = p - patch.centre;
            const Vec3 up = enu_frame(lon, lat)[2];
            vertices.push_back({{static_cast<float>(local.x), static_cast<float>(local.y),
                                 static_cast<float>(local.z)},
                                static_cast<float>(options.globe_height),
                                snorm10(up.x) | (snorm10(up.y) << 10) | (snorm10(up.z) << 20),
                                unorm16((lon + 180) / 360),
                                unorm16((90 - lat) / 180)});
          }
        }
        patch.box = fit_obb(points, patch.centre, enu_frame(clon, clat));
        patches.push_back(patch);
      }
    }
    std::vector<std::uint16_t> indices;
    for (int j = 0; j < kPatchCells; ++j)
      for (int i = 0; i < kPatchCells; ++i) {
        const auto v = [&](int di, int dj) {
          return static_cast<std::uint16_t>((j + dj) * n + i + di);
        };
        indices.insert(indices.end(), {v(0, 0), v(1, 0), v(1, 1), v(0, 0), v(1, 1), v(0, 1)});
      }
    patch_index_count = static_cast<GLsizei>(indices.size());
    glGenVertexArrays(1, &globe_vao);
    glBindVertexArray(globe_vao);
    glGenBuffers(1, &globe_vbo);
    glBindBuffer(GL_ARRAY_BUFFER, globe_vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertices.size() * sizeof(MeshVertex)),
                 vertices.data(), GL_STATIC_DRAW);
    glGenBuffers(1, &globe_ibo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, globe_ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(indices.size() * 2),
                 indices.data(), GL_STATIC_DRAW);
    set_vertex_layout();
    glBindVertexArray(0);
  }

  float log_coefficient() const { return static_cast<float>(1.0 / std::log2(kLogDepthFar + 1.0)); }
};

GlobeRenderer::GlobeRenderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

GlobeRenderer::~GlobeRenderer() = default;

Result<std::unique_ptr<GlobeRenderer>> GlobeRenderer::create(const RendererOptions& options) {
  if (epoxy_gl_version() < 33)
    return unsupported(
        "OpenGL 3.3 or later is needed (this context: " + std::to_string(epoxy_gl_version()) + ")");
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->log_depth = options.force_log_depth ||
                    !(epoxy_gl_version() >= 45 || epoxy_has_gl_extension("GL_ARB_clip_control"));
  GLint max_samples = 0;
  glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
  impl->samples = options.msaa > 1 ? std::min(options.msaa, static_cast<int>(max_samples)) : 0;
  const GLubyte* gl_renderer = glGetString(GL_RENDERER);
  impl->flush_triangles = flush_interval(
      gl_renderer ? reinterpret_cast<const char*>(gl_renderer) : "", options.flush_triangles);
  if (Status s = impl->build_programs(); !s) return s.error();
  impl->build_globe();
  std::unique_ptr<GlobeRenderer> r(new GlobeRenderer(std::move(impl)));
  r->log_depth_ = r->impl_->log_depth;
  if (Status s = r->resize(options.width, options.height); !s) return s.error();
  return r;
}

Status GlobeRenderer::resize(int width, int height) {
  width_ = std::max(width, 1);
  height_ = std::max(height, 1);
  return impl_->make_targets(width_, height_);
}

std::string GlobeRenderer::gl_description() const {
  const auto str = [](GLenum e) {
    const GLubyte* s = glGetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
  };
  return str(GL_RENDERER) + ", OpenGL " + str(GL_VERSION) +
         (log_depth_ ? ", log depth" : ", reversed-Z");
}

GpuMesh GlobeRenderer::upload(const TileMesh& mesh) {
  GpuMesh g;
  glGenVertexArrays(1, &g.vao);
  glBindVertexArray(g.vao);
  glGenBuffers(1, &g.vbo);
  glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.vertices.size() * sizeof(MeshVertex)),
               mesh.vertices.data(), GL_STATIC_DRAW);
  glGenBuffers(1, &g.ibo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.ibo);
  g.wide_indices = mesh.indices16.empty();
  const std::size_t index_bytes =
      g.wide_indices ? mesh.indices32.size() * 4 : mesh.indices16.size() * 2;
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(index_bytes),
               g.wide_indices ? static_cast<const void*>(mesh.indices32.data())
                              : static_cast<const void*>(mesh.indices16.data()),
               GL_STATIC_DRAW);
  set_vertex_layout();
  glBindVertexArray(0);
  g.index_count = static_cast<std::uint32_t>(mesh.index_count());
  g.surface_index_count = mesh.surface_index_count;
  g.skirt_index_count = mesh.skirt_index_count;
  g.cut_index_count = mesh.cut_index_count;
  g.bytes = mesh.vertices.size() * sizeof(MeshVertex) + index_bytes;
  return g;
}

GpuMesh GlobeRenderer::upload_image(const imagery::RgbaImage& image) {
  GpuMesh g;
  glGenTextures(1, &g.texture);
  glBindTexture(GL_TEXTURE_2D, g.texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  // Row 0 (north) at t = 0, where MeshVertex::v = 0 (the tile's north edge).
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, static_cast<GLsizei>(image.width),
               static_cast<GLsizei>(image.height), 0, GL_RGBA, GL_UNSIGNED_BYTE,
               image.pixels.data());
  glGenerateMipmap(GL_TEXTURE_2D);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, 0);
  g.bytes = image.pixels.size() * 4 / 3;  // with its mipmaps
  return g;
}

void GlobeRenderer::release(GpuMesh& mesh) {
  if (mesh.texture) glDeleteTextures(1, &mesh.texture);
  if (mesh.vao) glDeleteVertexArrays(1, &mesh.vao);
  if (mesh.vbo) glDeleteBuffers(1, &mesh.vbo);
  if (mesh.ibo) glDeleteBuffers(1, &mesh.ibo);
  mesh = GpuMesh{};
}

RenderStats GlobeRenderer::render(const Camera& camera, const std::vector<DrawItem>& draws,
                                  const RenderSettings& settings) {
  Impl& m = *impl_;
  RenderStats stats;
  glBindFramebuffer(GL_FRAMEBUFFER, m.scene_fbo);
  glViewport(0, 0, width_, height_);
  if (!m.log_depth) glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glDepthMask(GL_TRUE);
  glClearColor(kSky[0], kSky[1], kSky[2], 1.0f);
  glClearDepth(m.log_depth ? 1.0 : 0.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(m.log_depth ? GL_LESS : GL_GREATER);
  glDisable(GL_CULL_FACE);  // skirts are seen from both sides

  const Mat4 projection = camera.projection();
  const float log_coef = m.log_coefficient();
  int current = -1;
  std::uint64_t unflushed = 0;  // triangles handed to the driver since the last flush
  for (const DrawItem& d : draws) {
    const ResidentTile& t = *d.tile;
    if (t.gpu.index_count == 0) continue;
    const int variant =
        (settings.wireframe ? 1 : 0) | (d.quadrant_mask != 0xF ? 2 : 0) | (d.texture ? 4 : 0);
    const TerrainProgram& p = m.terrain[static_cast<std::size_t>(variant)];
    if (variant != current) {
      current = variant;
      glUseProgram(p.id);
      glUniform2f(p.ramp, static_cast<float>(settings.ramp_min),
                  static_cast<float>(settings.ramp_max));
      glUniform3fv(p.stops, 5, kRampStops[0].data());
      glUniform1f(p.log_coef, log_coef);
      glUniform1i(p.image, 0);
    }
    if (d.texture) {
      glActiveTexture(GL_TEXTURE0);
      glBindTexture(GL_TEXTURE_2D, d.texture);
      glUniform4fv(p.image_uv, 1, d.image_uv.data());
    }
    set_matrix(p.mvp, projection * camera.model_view(t.centre));
    // The sun in the tile's own frame: from the north-west, 45° above the horizon.
    const auto& [east, north, up] = t.frame;
    const Vec3 sun = normalize((north - east) * 0.5 + up * std::sqrt(0.5));
    glUniform3f(p.light, static_cast<float>(sun.x), static_cast<float>(sun.y),
                static_cast<float>(sun.z));
    glUniform1i(p.mask, d.quadrant_mask);
    glUniform3f(p.centre, static_cast<float>(t.centre.x), static_cast<float>(t.centre.y),
                static_cast<float>(t.centre.z));
    glUniform2f(p.skirt, static_cast<float>(d.skirt_depth), static_cast<float>(d.skirt_floor));
    glBindVertexArray(t.gpu.vao);
    // The surface, then the skirt quads hung this frame (skirts.hpp), a run per call; cut
    // quads lie on the mask's edge by design and are drawn unmasked.
    const GLenum type = t.gpu.wide_indices ? GL_UNSIGNED_INT : GL_UNSIGNED_SHORT;
    const std::size_t index_size = t.gpu.wide_indices ? 4 : 2;
    std::uint32_t side_quads = 0;
    for (const std::uint32_t n : t.gpu.skirt_index_count) side_quads += n / 6;
    std::uint32_t first = 0, count = t.gpu.surface_index_count;
    const auto flush = [&] {
      if (count == 0) return;
      // GL takes the byte offset into the bound index buffer as a pointer.
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(count), type,
                     reinterpret_cast<const void*>(  // NOLINT(performance-no-int-to-ptr)
                         std::uintptr_t{first} * index_size));
      stats.triangles += count / 3;
      unflushed += count / 3;
      if (m.flush_triangles > 0 && unflushed >= m.flush_triangles) {
        glFlush();  // the driver's binned triangles so far are rasterised and let go
        unflushed = 0;
        ++stats.flushes;
      }
    };
    bool unmasked = false;
    for (const auto& [quad, quads] : d.skirt_runs) {
      const std::uint32_t begin = t.gpu.surface_index_count + quad * 6;
      if (first + count != begin || (quad >= side_quads && !unmasked)) {
        flush();
        first = begin;
        count = 0;
      }
      if (quad >= side_quads && !unmasked) {
        glUniform1i(p.mask, 0xF);
        unmasked = true;
      }
      count += quads * 6;
      stats.skirt_triangles += std::uint64_t{quads} * 2;
    }
    flush();
    ++stats.tiles;
  }

  // The ellipsoid, last: hidden wherever terrain was drawn (early depth test), back faces culled.
  glEnable(GL_CULL_FACE);
  glCullFace(GL_BACK);
  glFrontFace(GL_CCW);
  glUseProgram(m.globe.id);
  glUniform1f(m.globe.log_coef, log_coef);
  const Vec3 sun = normalize(camera.position());
  glUniform3f(m.globe.sun, static_cast<float>(sun.x), static_cast<float>(sun.y),
              static_cast<float>(sun.z));
  glBindVertexArray(m.globe_vao);
  const Frustum frustum = camera.frustum();
  for (const GlobePatch& patch : m.patches) {
    if (!frustum.intersects(patch.box)) continue;
    set_matrix(m.globe.mvp, projection * camera.model_view(patch.centre));
    glDrawElementsBaseVertex(GL_TRIANGLES, m.patch_index_count, GL_UNSIGNED_SHORT, nullptr,
                             patch.base_vertex);
    ++stats.globe_patches;
  }
  glDisable(GL_CULL_FACE);
  glBindVertexArray(0);
  glBindTexture(GL_TEXTURE_2D, 0);
  glUseProgram(0);

  if (m.scene_fbo != m.resolve_fbo) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, m.scene_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, m.resolve_fbo);
    glBlitFramebuffer(0, 0, width_, height_, 0, 0, width_, height_,
                      GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT, GL_NEAREST);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, m.resolve_fbo);
  if (!m.log_depth) glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
  glDisable(GL_DEPTH_TEST);
  return stats;
}

std::vector<std::uint8_t> read_framebuffer_rgba(std::uint32_t framebuffer, int width, int height) {
  const auto w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
  std::vector<std::uint8_t> flipped(w * h * 4), rows(w * h * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
  if (framebuffer == 0) glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, flipped.data());
  for (std::size_t y = 0; y < h; ++y)
    std::copy_n(flipped.data() + (h - 1 - y) * w * 4, w * 4, rows.data() + y * w * 4);
  return rows;
}

std::vector<std::uint8_t> GlobeRenderer::read_rgba() {
  return read_framebuffer_rgba(impl_->resolve_fbo, width_, height_);
}

void GlobeRenderer::present(int framebuffer_width, int framebuffer_height) {
  glBindFramebuffer(GL_READ_FRAMEBUFFER, impl_->resolve_fbo);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
  glBlitFramebuffer(
      0, 0, width_, height_, 0, 0, framebuffer_width, framebuffer_height, GL_COLOR_BUFFER_BIT,
      framebuffer_width == width_ && framebuffer_height == height_ ? GL_NEAREST : GL_LINEAR);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

std::optional<Vec3> GlobeRenderer::pick(const Camera& camera, int px, int py) {
  if (px < 0 || py < 0 || px >= width_ || py >= height_) return std::nullopt;
  float depth = 0;
  glBindFramebuffer(GL_READ_FRAMEBUFFER, impl_->resolve_fbo);
  glReadPixels(px, height_ - 1 - py, 1, 1, GL_DEPTH_COMPONENT, GL_FLOAT, &depth);
  double z = 0;  // distance along the view axis
  if (log_depth_) {
    if (depth >= 1.0f) return std::nullopt;
    z = std::exp2(depth / impl_->log_coefficient()) - 1.0;
  } else {
    if (depth <= 0.0f) return std::nullopt;
    z = camera.near_plane() / depth;
  }
  const Vec3 dir = camera.ray_direction(px + 0.5, py + 0.5);
  return camera.position() + dir * (z / dot(dir, camera.forward()));
}

}  // namespace tinstream::client
