// tinstream-viewer: the native streaming globe client (README "Viewing terrain").
#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#if defined(__GLIBC__)  // (defined by any libc header, so after <cstdlib>)
#include <malloc.h>
#endif
#include <iostream>
#include <sstream>

#include "tinstream/client/viewer.hpp"
#include "window.hpp"

namespace {

using tinstream::client::ViewerOptions;

bool parse_size(const std::string& text, int& w, int& h) {
  const auto x = text.find('x');
  if (x == std::string::npos) return false;
  try {
    std::size_t end = 0;
    w = std::stoi(text.substr(0, x), &end);
    if (end != x) return false;
    h = std::stoi(text.substr(x + 1), &end);
    if (end != text.size() - x - 1) return false;
  } catch (const std::exception&) {
    return false;
  }
  return w >= 16 && h >= 16 && w <= 16384 && h <= 16384;
}

}  // namespace

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // glibc gives each download thread a malloc arena of its own (up to 8 per core), and every
  // arena keeps its high-water mark: with 8 workers decoding meshes that the render thread frees
  // later, RSS grew far beyond the cache budgets. Two arenas bound that (bench/client, memory);
  // set before any thread starts. MALLOC_ARENA_MAX in the environment still decides.
  if (std::getenv("MALLOC_ARENA_MAX") == nullptr) ::mallopt(M_ARENA_MAX, 2);
#endif
  ViewerOptions o;
  CLI::App app{
      "tinstream-viewer: streams TIN terrain tiles from a tinstream-server (--url) or a tile store "
      "(--store) onto the WGS84 globe. Window mode (GLFW + Dear ImGui) by default; --headless "
      "renders offscreen through EGL and writes a PNG and JSON statistics.",
      "tinstream-viewer"};
  auto* url =
      app.add_option("--url", o.url, "tinstream-server base URL, e.g. http://127.0.0.1:8080");
  auto* store =
      app.add_option("--store", o.store, "read tiles straight from this tile store (SQLite)");
  url->excludes(store);
  app.add_option("--layer", o.layers, "layer to draw (repeatable; default: every layer)");
  app.add_option("--imagery", o.imagery,
                 "imagery layer to drape over the terrain (same quadtree; with --wireframe: the "
                 "triangles over the imagery)");
  app.add_option("--threads", o.threads, "download threads 1..8 (default: one per core, at most 8)")
      ->check(CLI::Range(1, 8));
  app.add_option("--decode-threads", o.decode_threads,
                 "tiles decoded at once, the most urgent first (default: one per core; more "
                 "than the cores slows the tile the view waits for)")
      ->check(CLI::Range(1, 64));
  app.add_option("--max-sse", o.max_sse,
                 "quality: largest screen-space error in pixels (default 2)")
      ->check(CLI::Range(0.05, 1000.0));
  app.add_option("--gpu-mb", o.gpu_mb, "GPU tier budget in MB (default 512)")
      ->check(CLI::Range(1, 1 << 20));
  app.add_option("--cache-mb", o.cache_mb, "RAM tier (decoded tiles) budget in MB (default 512)")
      ->check(CLI::Range(1, 1 << 20));
  app.add_option("--disk-cache", o.disk_cache,
                 "directory of the disk tier (compressed tiles, kept across runs)");
  app.add_option("--disk-mb", o.disk_mb, "disk tier budget in MB (default 2048)")
      ->check(CLI::Range(1, 1 << 24));
  app.add_option("--upload-mb", o.upload_mb, "largest GPU upload per frame in MB (default 8)")
      ->check(CLI::Range(1, 1024));
  app.add_option("--heap-trim-ms", o.heap_trim_ms,
                 "after cache evictions, give free heap memory back to the system at most every "
                 "MS ms (default 1000; -1: never)")
      ->check(CLI::Range(-1, 3600000));
  app.add_option("--idle-heap-trim-ms", o.idle_heap_trim_ms,
                 "without evictions or new tiles, give free heap memory back at most every MS ms "
                 "(default 10000; -1: never; --heap-trim-ms -1 turns both off)")
      ->check(CLI::Range(-1, 3600000));
  app.add_option("--prefetch-levels", o.prefetch_levels,
                 "ask for up to N levels below a tile that has not arrived yet, by the layer's "
                 "per-level error, instead of one level per round trip (default 3; 0: none)")
      ->check(CLI::Range(0, 30));
  app.add_option("--request-timeout", o.http.request_timeout_ms,
                 "per-request timeout in ms (default 10000)")
      ->check(CLI::Range(50, 600000));
  app.add_option("--retries", o.http.max_attempts,
                 "attempts per tile on errors and 5xx (default 4)")
      ->check(CLI::Range(1, 20));
  app.add_flag("--headless", o.headless, "render offscreen (EGL, no display) and exit");
  std::string size;
  app.add_option("--size", size, "image or window size WxH (default 1280x720)");
  std::string camera;
  app.add_option("--camera", camera,
                 "lon,lat,height[,heading[,pitch]]: degrees, metres above the ellipsoid, heading "
                 "clockwise from north, pitch −90 = down (default: framing the layers)");
  app.add_option("--fov", o.fov, "vertical field of view in degrees (default 60)")
      ->check(CLI::Range(5.0, 120.0));
  app.add_option(
      "--out", o.out,
      "the PNG to write once the view is complete (window mode: the window, panel "
      "included, then it prints the panel's and legend's rectangles as a JSON line and closes)");
  app.add_option("--camera-path", o.camera_path,
                 "fly this scripted path (headless: one JSON statistics line per frame)");
  app.add_option("--fps", o.fps,
                 "camera path: advance 1/fps seconds per frame instead of real time")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--stats", o.stats, "headless: write the JSON statistics here instead of stdout");
  app.add_option("--timeline", o.timeline,
                 "headless (debugging): write when each tile was asked for, sent, answered, "
                 "decoded, taken and uploaded here, one JSON line a tile (seconds since start)");
  app.add_option("--timeout", o.timeout_s,
                 "with --out: seconds to wait for a complete view (default 120)")
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--close-after", o.close_after_s,
                 "window mode: close after this many seconds and print one JSON line: frames "
                 "drawn, seconds since the last one, whether the view was complete")
      ->check(CLI::Range(0.0, 86400.0));
  app.add_flag("--wireframe", o.wireframe, "draw the triangle edges over the terrain");
  app.add_option("--msaa", o.msaa, "multisampling samples, 0 for none (default 4)")
      ->check(CLI::Range(0, 16));
  app.add_option("--flush-triangles", o.flush_triangles,
                 "hand the driver each frame in parts of N triangles (glFlush), which bounds the "
                 "memory a software rasteriser (Mesa llvmpipe) holds for a frame; default: 32768 "
                 "on llvmpipe/softpipe, never on a GPU; 0: never")
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{1} << 40));
  bool no_legend = false;
  app.add_flag("--no-legend", no_legend, "leave the colour legend out");
  app.add_flag("--log-depth", o.log_depth,
               "use the logarithmic-depth fallback even with glClipControl");
  std::string ramp;
  app.add_option("--ramp", ramp,
                 "MIN,MAX heights (m) of the colour ramp (default: the layers' range)");
  CLI11_PARSE(app, argc, argv);

  o.legend = !no_legend;
  if (!size.empty() && !parse_size(size, o.width, o.height)) {
    std::cerr << "tinstream-viewer: --size \"" << size << "\": expected WxH, 16..16384 each\n";
    return 2;
  }
  if (!camera.empty()) {
    auto pose = tinstream::client::parse_camera_pose(camera);
    if (!pose) {
      std::cerr << "tinstream-viewer: --" << pose.error().message << '\n';
      return 2;
    }
    o.camera = *pose;
  }
  if (!ramp.empty()) {
    std::istringstream in(ramp);
    double lo = 0, hi = 0;
    char comma = 0;
    if (!(in >> lo >> comma >> hi) || comma != ',' || !(hi > lo)) {
      std::cerr << "tinstream-viewer: --ramp \"" << ramp << "\": expected MIN,MAX with MIN < MAX\n";
      return 2;
    }
    o.ramp = std::make_pair(lo, hi);
  }
  if (o.url.empty() && o.store.empty()) {
    std::cerr << "tinstream-viewer: give a tile source: --url http://HOST:PORT or --store FILE "
                 "(--help)\n";
    return 2;
  }
  return o.headless ? tinstream::client::run_headless(o) : tinstream::client::run_window(o);
}
