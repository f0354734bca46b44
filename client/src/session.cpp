#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "tinstream/client/viewer.hpp"

namespace tinstream::client {

double Session::globe_height() const {
  double lowest = 0;
  for (const LayerDescription& l : layers) lowest = std::min(lowest, l.min_z);
  return lowest - 30.0;
}

RenderSettings Session::render_settings(bool wireframe) const {
  RenderSettings s;
  s.wireframe = wireframe;
  s.ramp_min = ramp_min;
  s.ramp_max = ramp_max;
  return s;
}

CameraPose Session::framing(const Camera& camera, std::size_t index) const {
  if (index < layers.size()) {
    const LayerDescription& l = layers[index];
    return framing_pose(l.bounds, (l.min_z + l.max_z) / 2, camera);
  }
  double ground = 0;
  for (const LayerDescription& l : layers)
    ground += (l.min_z + l.max_z) / 2 / static_cast<double>(layers.size());
  return framing_pose(extent, ground, camera);
}

Result<Session> open_session(const ViewerOptions& o) {
  if (o.url.empty() == o.store.empty())
    return invalid_argument("give exactly one tile source: --url http://HOST:PORT or --store FILE");
  Session s;
  auto source = o.url.empty() ? open_store_source(o.store) : open_http_source(o.url, o.http);
  if (!source) return source.error();
  s.source = std::move(*source);
  auto layers = s.source->layers(o.layers);
  if (!layers)
    return Error(layers.error().code, s.source->describe() + ": " + layers.error().message);
  if (layers->empty()) return not_found(s.source->describe() + " has no published layer");
  if (layers->size() > 65534) return unsupported("more than 65534 layers");
  s.layers = std::move(*layers);
  if (!o.disk_cache.empty() && s.source->remote()) {
    auto disk = DiskCache::open(o.disk_cache, o.disk_mb << 20);
    if (!disk) return disk.error();
    s.disk = std::move(*disk);
  }
  s.ramp_min = s.layers.front().min_z;
  s.ramp_max = s.layers.front().max_z;
  s.extent = s.layers.front().bounds;
  std::string names;
  for (const LayerDescription& l : s.layers) {
    s.ramp_min = std::min(s.ramp_min, l.min_z);
    s.ramp_max = std::max(s.ramp_max, l.max_z);
    s.extent = {std::min(s.extent.west, l.bounds.west), std::min(s.extent.south, l.bounds.south),
                std::max(s.extent.east, l.bounds.east), std::max(s.extent.north, l.bounds.north)};
    names += (names.empty() ? "" : ", ") + l.name +
             (l.attribution.empty() ? "" : " (" + l.attribution + ")");
  }
  if (o.ramp) {
    s.ramp_min = o.ramp->first;
    s.ramp_max = o.ramp->second;
  }
  if (s.ramp_max <= s.ramp_min) s.ramp_max = s.ramp_min + 1;
  s.legend.ramp_min = s.ramp_min;
  s.legend.ramp_max = s.ramp_max;
  s.legend.footer = names;
  // The imagery layer joins the loader's table after the terrain layers (same pool and tiers).
  std::vector<LayerDescription> table = s.layers;
  if (!o.imagery.empty()) {
    auto imagery = s.source->imagery_layer(o.imagery);
    if (!imagery) return imagery.error();
    s.imagery = *imagery;
    table.push_back(std::move(*imagery));
    s.legend.footer += "; imagery " + s.imagery->name +
                       (s.imagery->attribution.empty() ? "" : " (" + s.imagery->attribution + ")");
    // Imagery is draped tile for tile on its own quadtree: over a terrain layer of the other
    // Mercator (spherical / ellipsoidal) no tile matches, and that layer shows the colour ramp.
    const std::string imagery_projection(geo::to_string(s.imagery->projection));
    for (const LayerDescription& l : s.layers) {
      if (l.projection == s.imagery->projection) continue;
      const std::string terrain_projection(geo::to_string(l.projection));
      std::string w = "imagery layer \"";
      w.append(s.imagery->name).append("\" is on the ").append(imagery_projection);
      w.append(" Mercator quadtree, terrain layer \"").append(l.name).append("\" on the ");
      w.append(terrain_projection).append(" one: \"").append(l.name);
      w.append("\" is drawn with the colour ramp, not draped (ingest the imagery again with ");
      w.append("--projection ").append(terrain_projection).append(")");
      s.warnings.push_back(std::move(w));
      s.legend.footer.append(" (not over ").append(l.name).append(": other projection)");
    }
  }
  if (!o.timeline.empty()) s.timeline = std::make_shared<RequestTimeline>();
  s.loader = std::make_unique<TileLoader>(s.source, std::move(table), s.disk,
                                          LoaderOptions{o.threads, o.decode_threads, s.timeline});
  StreamerOptions so;
  so.max_sse = o.max_sse;
  so.gpu_budget = o.gpu_mb << 20;
  so.ram_budget = o.cache_mb << 20;
  so.upload_bytes_per_frame = o.upload_mb << 20;
  so.heap_trim_interval = std::chrono::milliseconds(o.heap_trim_ms);
  so.idle_heap_trim_interval = std::chrono::milliseconds(o.idle_heap_trim_ms);
  so.prefetch_levels = o.prefetch_levels;
  so.imagery_layer = s.imagery ? static_cast<int>(s.layers.size()) : -1;
  s.streamer = std::make_unique<TileStreamer>(*s.loader, so);
  return s;
}

std::uint64_t resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

namespace {
double cpu_seconds(clockid_t clock) {
  timespec t{};
  ::clock_gettime(clock, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}
}  // namespace

double thread_cpu_seconds() { return cpu_seconds(CLOCK_THREAD_CPUTIME_ID); }
double process_cpu_seconds() { return cpu_seconds(CLOCK_PROCESS_CPUTIME_ID); }

}  // namespace tinstream::client
