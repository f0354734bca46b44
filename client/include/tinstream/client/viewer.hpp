// tinstream/client/viewer.hpp — what tinstream-viewer runs: the options, the streaming session
// they open (source → loader → streamer), the headless driver and the statistics it prints.
// The window mode (GLFW + ImGui) lives in client/viewer/ and uses the same Session.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/camera.hpp"
#include "tinstream/client/loader.hpp"
#include "tinstream/client/overlay.hpp"
#include "tinstream/client/renderer.hpp"
#include "tinstream/client/streamer.hpp"
#include "tinstream/client/tile_source.hpp"

namespace tinstream::client {

struct ViewerOptions {
  // Where tiles come from: exactly one of url / store.
  std::string url;
  std::filesystem::path store;
  std::vector<std::string> layers;  // empty: every layer
  std::string imagery;              // an imagery layer draped over the terrain; empty: none
  int threads = 0;                  // download threads, 0: one per core (at most 8)
  int decode_threads = 0;           // decodes at once (most urgent first), 0: one per core
  double max_sse = 2.0;             // pixels
  std::uint64_t gpu_mb = 512, cache_mb = 512, disk_mb = 2048;
  std::filesystem::path disk_cache;  // empty: no disk cache
  std::uint64_t upload_mb = 8;       // per frame
  int heap_trim_ms = 1000;           // StreamerOptions::heap_trim_interval; negative: never
  int idle_heap_trim_ms = 10000;     // StreamerOptions::idle_heap_trim_interval; negative: never
  int prefetch_levels = 3;           // StreamerOptions'; 0: none
  HttpOptions http;

  bool headless = false;
  int width = 1280, height = 720;
  double fov = 60;                    // degrees, vertical
  std::optional<CameraPose> camera;   // default: framing the layers
  std::filesystem::path out;          // headless PNG
  std::filesystem::path camera_path;  // headless scripted flight
  std::filesystem::path stats;        // statistics file (default: stdout)
  std::filesystem::path timeline;     // headless: the request timeline's JSON lines; empty: none
  double timeout_s = 120;
  double close_after_s = 0;  // window mode: close after this long and print its frame counts; 0: no
  double fps = 0;            // camera paths: 0 = real time, else a fixed step of 1/fps per frame
  bool wireframe = false;
  int msaa = 4;
  std::int64_t flush_triangles = -1;  // RendererOptions'
  bool legend = true;
  bool log_depth = false;  // force the logarithmic-depth fallback
  std::optional<std::pair<double, double>> ramp;
};

// Everything but the GL side: opened from the options, owned by the render thread.
struct Session {
  std::shared_ptr<TileSource> source;
  std::vector<LayerDescription> layers;
  std::shared_ptr<DiskCache> disk;
  std::unique_ptr<TileLoader> loader;
  std::unique_ptr<TileStreamer> streamer;
  std::shared_ptr<RequestTimeline> timeline;  // --timeline; null: none
  double ramp_min = 0, ramp_max = 1;
  geo::LonLatRect extent{};  // of all layers
  LegendInfo legend;
  std::optional<LayerDescription> imagery;  // --imagery (last in the loader's layer table)
  // What the user should know but that does not stop the viewer (printed on stderr): a terrain
  // layer on another Mercator quadtree than the imagery, which therefore is not draped there.
  std::vector<std::string> warnings;

  // Where the fallback globe is drawn: below every layer's lowest height.
  double globe_height() const;
  RenderSettings render_settings(bool wireframe) const;
  // A pose that frames layer `index` (or all layers when index is out of range).
  CameraPose framing(const Camera& camera, std::size_t index = static_cast<std::size_t>(-1)) const;
};

// Opens the source, reads the layers' metadata, the disk cache, starts the loader. Errors say
// what is wrong with the options or the source (unreachable server, unknown layer, no layers).
Result<Session> open_session(const ViewerOptions& options);

// --headless: renders offscreen through EGL, waits until nothing the view needs is pending (or
// the timeout), writes the PNG and one line of JSON statistics; with a camera path, flies it and
// writes one JSON line per frame. Returns the process exit status: 0 done, 2 bad input
// (options, source, layers), 3 timed out before the view was complete (the PNG is written all
// the same), 1 no usable OpenGL.
int run_headless(const ViewerOptions& options);

// The imagery counters the statistics line and the window's panel show: the streamer's imagery
// tiles requested, loaded, absent (404) and failed so far, and the terrain tiles of the last
// frame drawn with imagery (draped).
struct ImageryStats {
  std::uint64_t requested = 0, loaded = 0, absent = 0, failed = 0, draped = 0;
};
ImageryStats imagery_stats(const TileStreamer& streamer);

// The statistics line of a finished view (one JSON object).
struct RunSummary {
  bool complete = false;
  double time_to_complete_s = -1;  // −1: never complete
  double elapsed_s = 0;
  std::uint64_t frames = 0;
  std::string camera;
  std::string renderer;
  RenderStats render;
  int centre_level = -1;  // level of the drawn tile under the image centre (−1: none)
  // CPU seconds while streaming (a snapshot: from the start until complete or timed out, before
  // the final draw; a flight: the whole flight): the render thread's, and the whole process's.
  double render_thread_cpu_s = 0;
  double process_cpu_s = 0;
};

// The level of the drawn tile (of the last frame) that holds the ground point under the image
// centre: where the camera looks, how fine the terrain is. −1 when no drawn tile is there.
int centre_level(const Session& session, const Camera& camera);
std::string summary_json(const ViewerOptions& options, const Session& session,
                         const RunSummary& run);

// Resident set size of this process in bytes (/proc/self/statm).
std::uint64_t resident_bytes();
// CPU time used so far by the calling thread, and by the whole process, in seconds.
double thread_cpu_seconds();
double process_cpu_seconds();

}  // namespace tinstream::client
