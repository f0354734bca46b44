// tinstream/client/streamer.hpp — what the render thread does with tiles each frame.
//
// update() runs on the render thread, once per frame, and never waits on I/O or a worker:
//   1. take the loader's finished results (a swap): meshes go into the RAM tier, 404s into the
//      set of absent tiles, failures into a short-lived failure list;
//   2. select tiles on the WGS84 ellipsoid: from each layer's root tiles down, cull by frustum and
//      horizon, refine while the screen-space error exceeds max_sse. A tile is replaced by its
//      children only when every visible child is resident; until then it stays drawn and the
//      missing children are requested (priority: this tile's screen-space error, so ancestors
//      come before descendants and nearer, coarser-looking tiles first). Children that do not
//      exist (404, or outside the layer's bounds) are covered by the parent's quadrant;
//   3. upload decoded meshes from the RAM tier to the GPU tier, most urgent first, up to
//      upload_bytes_per_frame (at least one per frame);
//   4. decide which tile sides hang a skirt this frame (skirts.hpp: only towards a drawn tile of
//      another level, never at the data's edge);
//   5. with an imagery layer (imagery.hpp, drape.cpp): give each drawn tile the imagery tile that
//      covers it (the same quadkey, else the nearest resident ancestor) and ask for missing ones;
//   6. hand the loader what is still missing (stale requests are dropped there).
// Prefetch (prefetch_levels): below a tile that is not resident yet, the selection goes on with
// an estimate instead of waiting for it — the layer's largest error of each level and the box of
// the unloaded tile — and asks for up to prefetch_levels levels of descendants whose estimated
// screen-space error still exceeds max_sse (ranked after every tile the frame needs). Without it
// each level costs a round trip before the next one is asked for: a close view 14 levels deep took
// 14 round trips however many download threads there were (bench/client). Prefetched tiles are
// requested only: not uploaded, and a frame's `complete` does not wait for them.
// While a frame asks for fewer tiles than the loader has download threads (the top of the
// pyramid, where a level holds one or two tiles), prefetch goes on a level at a time below where
// it stopped, up to kMaxDeeperPrefetch more levels, so that no connection sits idle through a
// round trip. With one download thread it never does (a frame that prefetches wants a tile).
// Tiles drawn, and those on the path to them, are pinned in the frame and never evicted.
//
// The GPU is reached only through GpuUploader (the renderer implements it), so the selection and
// the tiers are testable without OpenGL. The render thread owns everything here; the one other
// thread, the heap trimmer, only runs malloc_trim when update() asks it to (never blocking it).
#pragma once

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "tinstream/client/bounds.hpp"
#include "tinstream/client/camera.hpp"
#include "tinstream/client/loader.hpp"
#include "tinstream/client/lru_tier.hpp"

namespace tinstream::client {

// The box selection uses for a tile not loaded yet: its rectangle clipped to the layer's data
// bounds, over the layer's height range (every drawn vertex lies inside both), as rectangle_obb.
Obb unloaded_tile_bounds(const LayerDescription& layer, const geo::TileId& id);

// GL object names of one uploaded mesh (0 = none), as the renderer made them.
struct GpuMesh {
  std::uint32_t vao = 0, vbo = 0, ibo = 0;
  std::uint32_t index_count = 0, surface_index_count = 0;
  std::array<std::uint32_t, 4> skirt_index_count{};  // per side, after the surface (TileMesh)
  std::array<std::uint32_t, 4> cut_index_count{};    // per cut, after the sides (TileMesh)
  bool wide_indices = false;
  std::uint32_t texture = 0;  // an imagery tile: its texture (no buffers)
  std::uint64_t bytes = 0;
};

class GpuUploader {
 public:
  virtual ~GpuUploader() = default;
  virtual GpuMesh upload(const TileMesh& mesh) = 0;
  virtual void release(GpuMesh& mesh) = 0;
  // An imagery tile as a texture; its bytes count in the GPU tier like a mesh's. The default
  // (uploaders without textures) makes none and counts the pixels.
  virtual GpuMesh upload_image(const imagery::RgbaImage& image);
};

// A tile in the GPU tier: the buffers and what selection and drawing need to know about it.
struct ResidentTile {
  GpuMesh gpu;
  Vec3 centre;
  std::array<Vec3, 3> frame{};
  Obb bounds;
  double geometric_error = 0;
  double min_z = 0, max_z = 0;
  std::uint8_t quadrant_data = 0;
  double skirt_margin = 0, skirt_lowest = 0;  // TileMesh's
  std::vector<SkirtSpan> skirt_spans{};       // TileMesh's
};

struct DrawItem {
  TileKey key;
  const ResidentTile* tile = nullptr;  // valid until the next update()
  std::uint8_t quadrant_mask = 0xF;    // bit q: draw quadrant q (quadkey digit) of the tile
  // Drawn only until its children arrive (its screen-space error is above the target): it gets
  // resident imagery, but no imagery is asked for it (it would arrive for a tile soon gone).
  bool stand_in = false;
  double sse = 0;       // screen-space error, pixels
  double distance = 0;  // metres from the camera to the tile's box
  // Skirts of this frame (skirts.hpp): the skirt quads hung, as runs {first quad, count} in
  // index order (quad q: the 6 indices from surface_index_count + 6q; a run never mixes side
  // and cut quads), lowered skirt_depth metres but never below the height skirt_floor.
  // skirt_sides sums them up: bit s = a quad of side s (0 N, 1 E, 2 S, 3 W) hangs, bit 4 + c =
  // one of cut c (Cut).
  std::vector<std::array<std::uint32_t, 2>> skirt_runs{};
  std::uint8_t skirt_sides = 0;
  double skirt_depth = 0, skirt_floor = 0;
  // Imagery draped this frame (drape.cpp): the texture (0: none, the colour ramp) and where the
  // tile lies in it: texture coordinate = uv · (image_uv[0], image_uv[1]) + (image_uv[2],
  // image_uv[3]) — the identity for the imagery tile of the same quadkey, a sub-rectangle for an
  // ancestor's.
  std::uint32_t texture = 0;
  std::array<float, 4> image_uv{1, 1, 0, 0};
};

inline constexpr std::size_t kLevels = 31;

struct FrameResult {
  std::vector<DrawItem> draws;  // front to back
  bool complete = false;       // nothing the view needs is missing, queued, in flight or unuploaded
  std::size_t wanted = 0;      // tiles requested from the loader this frame (prefetched included)
  std::size_t prefetched = 0;  // of which asked for ahead of their missing ancestors
  std::size_t upload_pending = 0;  // decoded tiles waiting for the upload budget
  std::size_t uploaded = 0;
  std::uint64_t uploaded_bytes = 0;
  double max_sse_drawn = 0;
  std::array<std::uint32_t, kLevels> drawn_per_level{};
  std::array<std::uint32_t, kLevels> pending_per_level{};

  // Whether the next update() selects the same as this one unless a new result arrives: nothing
  // was uploaded (a tile uploaded now is drawn, refined or replaces its parent only in the next
  // frame) and nothing waits for the upload budget. A driver that waits for results may wait
  // only after a settled frame (headless.cpp: it slept up to 20 ms after every upload, one per
  // level of the view's last tiles).
  bool settled() const { return uploaded == 0 && upload_pending == 0; }
};

struct LevelCounters {
  std::uint64_t requested = 0;  // distinct tiles asked from the loader
  std::uint64_t loaded = 0;     // meshes received
  std::uint64_t absent = 0;     // 404s
  std::uint64_t failed = 0;
};

struct StreamerOptions {
  double max_sse = 2.0;                     // pixels
  std::uint64_t gpu_budget = 512ull << 20;  // bytes
  std::uint64_t ram_budget = 512ull << 20;  // bytes
  std::uint64_t upload_bytes_per_frame = 8u << 20;
  std::chrono::milliseconds failure_retry{10000};  // a failed tile is asked again after this
  // After a tier evicted or new tiles arrived, free heap pages go back to the system (glibc
  // malloc_trim) at most this often; negative: never. The download threads allocate (and free
  // their decoding scratch) in their own malloc arenas and the render thread frees the meshes
  // on eviction, so without it the RSS keeps every arena's high-water mark (bench/client: the
  // scripted flight's RSS).
  std::chrono::milliseconds heap_trim_interval{1000};
  // Without evictions or new tiles the heap is trimmed too, at most this often; negative: never.
  // Memory freed by others — a software rasteriser's per-frame bins (Mesa llvmpipe), a camera
  // move's dropped meshes — otherwise stays with the process while the tiers are not full.
  std::chrono::milliseconds idle_heap_trim_interval{10000};
  // Levels below a missing tile asked for ahead of it (the header's "Prefetch"); 0: none.
  int prefetch_levels = 3;
  // The loader's layer table index of the imagery layer draped over the terrain; −1: none.
  int imagery_layer = -1;
};

class TileStreamer {
 public:
  TileStreamer(TileLoader& loader, StreamerOptions options);
  ~TileStreamer();
  TileStreamer(const TileStreamer&) = delete;
  TileStreamer& operator=(const TileStreamer&) = delete;

  const FrameResult& update(const Camera& camera, GpuUploader& gpu);
  // Frees every GPU buffer (before the GL context goes away).
  void release_all(GpuUploader& gpu);

  void set_max_sse(double pixels) { options_.max_sse = pixels; }
  double max_sse() const { return options_.max_sse; }
  // Imagery switched off at run time (the window's panel): drape() gives no tile a texture and
  // asks for no imagery tile until it is switched on again; what is resident stays cached.
  void set_imagery_enabled(bool on) { imagery_enabled_ = on; }
  bool imagery_enabled() const { return imagery_enabled_; }
  const StreamerOptions& options() const { return options_; }

  const FrameResult& last_frame() const { return frame_result_; }
  // What the last update() handed the loader (needed and prefetched tiles).
  const std::vector<TileRequest>& requests() const { return wanted_; }
  const std::array<LevelCounters, kLevels>& level_counters() const { return levels_; }
  const LevelCounters& imagery_counters() const { return imagery_counters_; }
  const TierCounters& gpu_counters() const { return gpu_.counters(); }
  const TierCounters& ram_counters() const { return ram_.counters(); }
  const TierCounters& image_ram_counters() const { return image_ram_.counters(); }
  std::uint64_t frames() const { return frame_; }
  std::uint64_t failures() const { return failures_; }
  // How often update() asked for free heap memory to go back (heap_trim_interval, or
  // idle_heap_trim_interval in frames without churn); the trimmer
  // thread does it (malloc_trim takes milliseconds: 5–8, up to 37 in bench/client's flights).
  std::uint64_t heap_trims() const { return heap_trims_; }
  const std::string& last_error() const { return last_error_; }
  // Height of the lowest terrain any layer may have (for the globe and the horizon).
  double lowest_height() const { return lowest_height_; }

 private:
  enum class State { absent, culled, not_ready, ready };
  struct Probe {
    State state = State::absent;
    ResidentTile* tile = nullptr;
    double distance = 0;
    // not_ready but decoded (in the RAM tier, queued for upload this frame): its mesh.
    const TileMesh* decoded = nullptr;
  };
  struct View;
  // Whether a tile of this stored error, its box this far from the eye, is replaced by its
  // children, and the screen-space errors that decide it (descend and look_ahead decide alike).
  struct Refinement {
    double sse = 0, texel_sse = 0;
    bool refines = false;
  };

  void take_results();
  Probe probe(const View& view, std::uint16_t layer, const geo::TileId& id, double priority,
              bool needed = true);
  void prefetch(const View& view, std::uint16_t layer, const geo::TileId& id, int levels);
  // The header's deeper prefetch: below prefetch_frontier_ while wanted_ holds fewer tiles than
  // the loader's download threads.
  void deepen_prefetch(const View& view);
  Refinement refinement(const View& view, std::uint16_t layer, const geo::TileId& id, double error,
                        double distance) const;
  // Below a tile the view needs that is not drawn this frame (resident but waiting for a sibling,
  // or decoded and waiting for its upload), from its own stored error and box: asks for the
  // children the view will need once it is drawn, as descend() will, recursing through the ones
  // already resident or decoded; prefetches below the missing ones. Draws nothing. Without it,
  // each level of tiles already at hand cost a frame (and a tile's whole subtree waited for its
  // slowest sibling) before anything below it was asked for (bench/client, the timeline).
  void look_ahead(const View& view, std::uint16_t layer, const geo::TileId& id, const Probe& p);
  void descend(const View& view, std::uint16_t layer, const geo::TileId& id, const Probe& self);
  void draw(const TileKey& key, const Probe& p, double sse, std::uint8_t mask,
            bool stand_in = false);
  // Imagery (drape.cpp): picks each drawn tile's imagery tile, asks for what is missing.
  void drape();
  // The ground size (metres) of one texel of the draped imagery's tile of `id` (256-pixel tiles,
  // at the tile's centre latitude) when the imagery layer has a finer level over it; 0 when no
  // imagery is draped there or none finer exists. descend() refines a tile whose texels would
  // look larger than max_sse pixels as it refines one whose geometric error does: imagery is
  // draped per terrain tile at that tile's level, so a smooth terrain drawn with few tiles would
  // otherwise stretch one coarse imagery tile over the whole view (#19).
  double imagery_texel_error(std::uint16_t layer, const geo::TileId& id) const;
  void take_image(LoadResult& r);
  // 1 uploaded, 0 nothing to upload, −1 stop (the frame's upload budget or the GPU tier is full).
  int upload_image(const TileRequest& r, GpuUploader& gpu, std::uint64_t& used);
  void upload(GpuUploader& gpu);
  bool failed_recently(const TileKey& key);
  void trim_heap();

  TileLoader& loader_;
  StreamerOptions options_;
  const std::vector<LayerDescription>& layers_;
  std::vector<std::vector<geo::TileId>> roots_;  // per layer: its min_level tiles over its data
  double lowest_height_ = 0;
  HorizonOccluder occluder_;

  std::uint64_t frame_ = 0;
  LruTier<ResidentTile> gpu_;
  LruTier<std::shared_ptr<const TileMesh>> ram_;
  // Decoded imagery tiles: a RAM tier of their own, with the same budget as ram_.
  LruTier<std::shared_ptr<const imagery::RgbaImage>> image_ram_;
  std::unordered_set<TileKey, TileKeyHash> absent_;
  std::unordered_map<TileKey, std::chrono::steady_clock::time_point, TileKeyHash> failed_;
  std::unordered_set<TileKey, TileKeyHash> requested_ever_;
  std::array<LevelCounters, kLevels> levels_{};
  LevelCounters imagery_counters_;  // imagery tiles (levels_ counts terrain tiles only)
  bool imagery_enabled_ = true;
  std::uint64_t failures_ = 0;
  std::string last_error_;
  std::uint64_t tiles_taken_ = 0;    // meshes received from the loader
  std::uint64_t trimmed_churn_ = 0;  // evictions (both tiers) + tiles_taken_ at the last trim
  std::chrono::steady_clock::time_point last_trim_{};
  std::uint64_t heap_trims_ = 0;
  // The heap trimmer: a thread that runs malloc_trim when asked (trim_requested_).
  std::mutex trim_mutex_;
  std::condition_variable trim_wake_;
  bool trim_requested_ = false, trim_stop_ = false;
  std::thread trimmer_;

  // Per frame.
  FrameResult frame_result_;
  std::vector<TileRequest> wanted_;
  std::vector<TileRequest> uploads_;
  // Tiles whose children prefetch() left out for lack of levels (deepen_prefetch's start).
  std::vector<std::pair<std::uint16_t, geo::TileId>> prefetch_frontier_;
};

}  // namespace tinstream::client
