// tinstream/client/renderer.hpp — the OpenGL 3.3 core renderer of the globe and its tiles.
//
// Draws into its own framebuffer objects (colour RGBA8 + 32-bit float depth, optionally
// multisampled, resolved into a readable single-sample target), so the same code serves the
// headless snapshots (read_rgba) and the window (present: a blit to the default framebuffer).
// Depth: reversed-Z with glClipControl(GL_ZERO_TO_ONE) and an infinite far plane when the driver
// has ARB_clip_control (float depth ≈ near/z keeps relative precision from orbit to the ground),
// else a logarithmic depth written by the fragment shaders. Matrices are computed in double with
// the camera at the origin and each tile relative to its own centre (camera.hpp), so nothing
// jitters. Tiles are hillshaded (sun from the north-west, 45° up, in each tile's local frame)
// over a hypsometric colour ramp; an optional wireframe overlay (geometry-shader barycentrics)
// marks every triangle but the skirts (over imagery, it is the paper's Fig. 11 view); tiles with
// imagery (DrawItem::texture) show it unlit instead of the ramp; a coarse ellipsoid with a 10°
// graticule is drawn wherever no tile covers it. It implements GpuUploader for the streamer.
//
// Thread: the render thread, with the GL context current, only.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/camera.hpp"
#include "tinstream/client/streamer.hpp"

namespace tinstream::client {

// The colour ramp (low → high), shared by the shader and the legend.
inline constexpr std::array<std::array<float, 3>, 5> kRampStops{{{0.16f, 0.42f, 0.20f},
                                                                 {0.45f, 0.62f, 0.28f},
                                                                 {0.85f, 0.78f, 0.45f},
                                                                 {0.60f, 0.40f, 0.25f},
                                                                 {0.95f, 0.93f, 0.90f}}};

struct RenderSettings {
  bool wireframe = false;
  double ramp_min = 0, ramp_max = 1000;  // metres: heights mapped to the ends of the ramp
};

struct RenderStats {
  std::uint32_t tiles = 0;
  std::uint64_t triangles = 0;        // terrain triangles drawn (skirts included)
  std::uint64_t skirt_triangles = 0;  // of which skirts
  std::uint32_t globe_patches = 0;
  std::uint32_t flushes = 0;  // glFlush calls that handed the driver part of the frame
};

// Software rasterisers (Mesa llvmpipe, softpipe) bin every triangle of a frame in process memory
// until the frame is flushed: ~180 bytes a triangle here (bench/client, 4× MSAA), so a frame of
// 0.9 M triangles held ~150 MB beyond the tile budgets. Handing them the frame in parts bounds
// that memory. kSoftwareFlushTriangles is the part size used by default on such drivers.
inline constexpr std::uint64_t kSoftwareFlushTriangles = 32768;
// The triangles after which render() calls glFlush: `requested` when it is ≥ 0 (0: never), else
// (auto) kSoftwareFlushTriangles when `gl_renderer` (GL_RENDERER) names a software rasteriser and
// never on other drivers (a GPU keeps the frame in its own memory).
std::uint64_t flush_interval(std::string_view gl_renderer, std::int64_t requested);

struct RendererOptions {
  int width = 1280, height = 720;
  int msaa = 4;                       // samples; 0 or 1: none
  bool force_log_depth = false;       // as if the driver had no glClipControl
  std::int64_t flush_triangles = -1;  // flush_interval's `requested`: -1 auto, 0 never
  double globe_height = 0;  // metres: where the fallback ellipsoid is drawn (below all terrain)
};

class GlobeRenderer final : public GpuUploader {
 public:
  // Requires: an OpenGL ≥ 3.3 core context current on this thread.
  static Result<std::unique_ptr<GlobeRenderer>> create(const RendererOptions& options);
  ~GlobeRenderer() override;
  GlobeRenderer(const GlobeRenderer&) = delete;
  GlobeRenderer& operator=(const GlobeRenderer&) = delete;

  // Reallocates the render targets (a window resized).
  Status resize(int width, int height);
  int width() const { return width_; }
  int height() const { return height_; }
  bool log_depth() const { return log_depth_; }
  std::string gl_description() const;

  GpuMesh upload(const TileMesh& mesh) override;
  void release(GpuMesh& mesh) override;
  // An imagery tile as a mipmapped RGBA8 texture (its bytes: the pixels and their mipmaps).
  GpuMesh upload_image(const imagery::RgbaImage& image) override;

  // Draws the frame into the render target and resolves it; afterwards the resolved target is
  // bound for drawing (an overlay may go on top) and reading.
  RenderStats render(const Camera& camera, const std::vector<DrawItem>& draws,
                     const RenderSettings& settings);
  // The resolved image, rows top to bottom. glReadPixels: waits for the GPU.
  std::vector<std::uint8_t> read_rgba();
  // Copies the resolved image to the default framebuffer (window mode).
  void present(int framebuffer_width, int framebuffer_height);
  // The surface point under pixel (px, py) from the depth buffer; nullopt where nothing is drawn.
  std::optional<Vec3> pick(const Camera& camera, int px, int py);

  struct Impl;

 private:
  explicit GlobeRenderer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  int width_ = 0, height_ = 0;
  bool log_depth_ = false;
};

// The pixels of a framebuffer object (0: the window's back buffer), rows top to bottom, RGBA8.
// glReadPixels: waits for the GPU.
std::vector<std::uint8_t> read_framebuffer_rgba(std::uint32_t framebuffer, int width, int height);

}  // namespace tinstream::client
