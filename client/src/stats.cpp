// The statistics line of tinstream-viewer (--headless): one JSON object.
#include <algorithm>
#include <nlohmann/json.hpp>

#include "tinstream/client/viewer.hpp"
#include "tinstream/geo/ecef.hpp"

namespace tinstream::client {

namespace {

nlohmann::json tier_json(const TierCounters& c) {
  return {{"hits", c.hits},
          {"misses", c.misses},
          {"evictions", c.evictions},
          {"inserts", c.inserts},
          {"refused", c.refused},
          {"bytes", c.bytes},
          {"peak_bytes", c.peak_bytes},
          {"budget", c.budget},
          {"largest_entry", c.largest_entry},
          {"entries", c.entries}};
}

}  // namespace

int centre_level(const Session& session, const Camera& camera) {
  const Vec3 dir = camera.ray_direction(camera.width() / 2.0, camera.height() / 2.0);
  int best = -1;
  for (const DrawItem& d : session.streamer->last_frame().draws) {
    const LayerDescription& l = session.layers[d.key.layer];
    const auto hit = intersect_ellipsoid(camera.position(), dir, (l.min_z + l.max_z) / 2);
    if (!hit) continue;
    const geo::Geodetic g = geo::from_ecef({hit->x, hit->y, hit->z});
    const geo::MercatorXY m = geo::NormalisedMercator(l.projection).forward({g.lon, g.lat});
    const geo::MercatorRect r = d.key.tile.bounds();
    // Only the quadrants the tile was drawn with count.
    const int q =
        (m.y < (r.min_y + r.max_y) / 2 ? 2 : 0) + (m.x >= (r.min_x + r.max_x) / 2 ? 1 : 0);
    if (r.contains(m) && (d.quadrant_mask & (1 << q)))
      best = std::max(best, static_cast<int>(d.key.tile.z));
  }
  return best;
}

ImageryStats imagery_stats(const TileStreamer& streamer) {
  const LevelCounters& c = streamer.imagery_counters();
  const std::vector<DrawItem>& draws = streamer.last_frame().draws;
  return {c.requested, c.loaded, c.absent, c.failed,
          static_cast<std::uint64_t>(std::count_if(
              draws.begin(), draws.end(), [](const DrawItem& d) { return d.texture != 0; }))};
}

std::string summary_json(const ViewerOptions& o, const Session& s, const RunSummary& run) {
  using nlohmann::json;
  const TileStreamer& st = *s.streamer;
  const FrameResult& f = st.last_frame();
  const LoaderCounters lc = s.loader->counters();
  const ImageryStats img = imagery_stats(st);

  json levels = json::array();
  std::uint64_t requested = 0, loaded = 0, absent = 0, failed = 0;
  for (std::size_t z = 0; z < kLevels; ++z) {
    const LevelCounters& c = st.level_counters()[z];
    requested += c.requested;
    loaded += c.loaded;
    absent += c.absent;
    failed += c.failed;
    if (c.requested || c.loaded || c.absent || c.failed || f.drawn_per_level[z])
      levels.push_back({{"level", z},
                        {"requested", c.requested},
                        {"loaded", c.loaded},
                        {"absent", c.absent},
                        {"failed", c.failed},
                        {"drawn", f.drawn_per_level[z]}});
  }
  std::vector<std::string> drawn;
  for (const DrawItem& d : f.draws) {
    char mask[4];
    std::snprintf(mask, sizeof mask, "%x", d.quadrant_mask);
    drawn.push_back(s.layers[d.key.layer].name + "/" + d.key.tile.quadkey() + ":" + mask);
  }
  std::sort(drawn.begin(), drawn.end());

  json j = {
      {"complete", run.complete},
      {"time_to_complete_s",
       run.time_to_complete_s < 0 ? json(nullptr) : json(run.time_to_complete_s)},
      {"elapsed_s", run.elapsed_s},
      {"frames", run.frames},
      {"source", s.source->describe()},
      {"layers",
       [&] {
         json a = json::array();
         for (const LayerDescription& l : s.layers) a.push_back(l.name);
         return a;
       }()},
      {"camera", run.camera},
      {"size", {o.width, o.height}},
      {"threads", s.loader->threads()},
      {"max_sse", st.max_sse()},
      {"max_sse_drawn", f.max_sse_drawn},
      {"centre_level", run.centre_level},
      {"renderer", run.renderer},
      {"tiles",
       {{"drawn", f.draws.size()},
        {"triangles", run.render.triangles},
        {"skirt_triangles", run.render.skirt_triangles},
        {"flushes", run.render.flushes},
        {"requested", requested},
        {"loaded", loaded},
        {"absent", absent},
        {"failed", failed},
        {"pending", f.wanted + f.upload_pending}}},
      {"levels", levels},
      {"drawn_tiles", drawn},
      {"requests",
       {{"sent", lc.requests},
        {"retries", lc.retries},
        {"connections", lc.connections},
        {"ok", lc.ok},
        {"not_modified", lc.not_modified},
        {"not_found", lc.not_found},
        {"failed", lc.failed},
        {"dropped", lc.dropped},
        {"wire_bytes", lc.wire_bytes},
        {"downloaded_bytes", lc.downloaded_bytes},
        {"decode_errors", lc.decode_errors},
        {"decode_seconds", lc.decode_seconds},
        {"decode_cpu_seconds", lc.decode_cpu_seconds},
        {"decode_wait_seconds", lc.decode_wait_seconds},
        {"most_decoding", lc.most_decoding}}},
      {"cpu", {{"render_thread_s", run.render_thread_cpu_s}, {"process_s", run.process_cpu_s}}},
      {"cache",
       {{"gpu", tier_json(st.gpu_counters())},
        {"ram", tier_json(st.ram_counters())},
        {"disk", s.disk ? tier_json(s.disk->counters()) : json(nullptr)}}},
      {"imagery", s.imagery ? json{{"layer", s.imagery->name},
                                   {"requested", img.requested},
                                   {"loaded", img.loaded},
                                   {"absent", img.absent},
                                   {"failed", img.failed},
                                   {"draped", img.draped},
                                   {"ram", tier_json(st.image_ram_counters())}}
                            : json(nullptr)},
      {"rss_bytes", resident_bytes()},
      {"last_error", st.last_error()},
  };
  return j.dump();
}

}  // namespace tinstream::client
