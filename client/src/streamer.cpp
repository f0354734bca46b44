#include "tinstream/client/streamer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#if defined(__GLIBC__)  // (defined by any libc header, so after <cstdlib>)
#include <malloc.h>
#endif

#include "tinstream/client/skirts.hpp"
#include "tinstream/geo/ecef.hpp"
#include "tinstream/geo/mercator.hpp"

namespace tinstream::client {

namespace {

// More root tiles than this per layer (a layer whose coarsest level is fine and wide) are left out.
constexpr std::size_t kMaxRoots = 4096;
// Roots are asked for before anything else.
constexpr double kRootPriority = 1e300;
// How many levels deeper than prefetch_levels prefetch goes while download threads would idle.
constexpr int kMaxDeeperPrefetch = 8;

// Whether the two rectangles share interior (touching along an edge does not count).
bool interiors_meet(const geo::MercatorRect& a, const geo::MercatorRect& b) {
  return a.min_x < b.max_x && a.max_x > b.min_x && a.min_y < b.max_y && a.max_y > b.min_y;
}

std::vector<geo::TileId> root_tiles(const LayerDescription& l) {
  const geo::MercatorRect& b = l.mercator_bounds;
  const geo::TileId nw = geo::TileId::containing({b.min_x, b.max_y}, l.min_level);
  const geo::TileId se = geo::TileId::containing({b.max_x, b.min_y}, l.min_level);
  std::vector<geo::TileId> roots;
  for (std::uint32_t y = nw.y; y <= se.y; ++y)
    for (std::uint32_t x = nw.x; x <= se.x; ++x) {
      if (roots.size() >= kMaxRoots) return roots;
      const geo::TileId id{l.min_level, x, y};
      if (l.may_contain(id)) roots.push_back(id);
    }
  return roots;
}

}  // namespace

Obb unloaded_tile_bounds(const LayerDescription& l, const geo::TileId& id) {
  // Every drawn vertex lies inside the data's bounding rectangle and height range.
  geo::MercatorRect r = id.bounds();
  r.min_x = std::max(r.min_x, l.mercator_bounds.min_x);
  r.max_x = std::min(r.max_x, l.mercator_bounds.max_x);
  r.min_y = std::max(r.min_y, l.mercator_bounds.min_y);
  r.max_y = std::min(r.max_y, l.mercator_bounds.max_y);
  const geo::NormalisedMercator m(l.projection);
  const geo::LonLatRect ll{geo::NormalisedMercator::lon_from_x(r.min_x), m.lat_from_y(r.min_y),
                           geo::NormalisedMercator::lon_from_x(r.max_x), m.lat_from_y(r.max_y)};
  return rectangle_obb(ll, l.min_z, l.max_z);
}

struct TileStreamer::View {
  const Camera& camera;
  Frustum frustum;
  Vec3 eye;
};

TileStreamer::TileStreamer(TileLoader& loader, StreamerOptions options)
    : loader_(loader),
      options_(options),
      layers_(loader.layers()),
      gpu_(options.gpu_budget),
      ram_(options.ram_budget),
      image_ram_(options.ram_budget) {
  for (const LayerDescription& l : layers_) {
    roots_.push_back(l.kind == TileKind::terrain ? root_tiles(l) : std::vector<geo::TileId>{});
    if (l.kind != TileKind::terrain) continue;
    lowest_height_ = std::min(lowest_height_, l.min_z);
  }
  // The occluder lies below the lowest terrain (its semi-axes shrunk by that depth sit inside
  // the surface at that height; 100 m more covers the difference to a parallel surface).
  occluder_ = HorizonOccluder(-lowest_height_ + 100.0);
  if (options_.heap_trim_interval.count() >= 0)
    trimmer_ = std::thread([this] {
      std::unique_lock lock(trim_mutex_);
      for (;;) {
        trim_wake_.wait(lock, [this] { return trim_requested_ || trim_stop_; });
        if (trim_stop_) return;
        trim_requested_ = false;
        lock.unlock();
#if defined(__GLIBC__)
        // Every arena, not only this thread's: the meshes and the decoding scratch came from the
        // workers' arenas.
        ::malloc_trim(0);
#endif
        lock.lock();
      }
    });
}

TileStreamer::~TileStreamer() {
  {
    std::lock_guard lock(trim_mutex_);
    trim_stop_ = true;
  }
  trim_wake_.notify_one();
  if (trimmer_.joinable()) trimmer_.join();
}

bool TileStreamer::failed_recently(const TileKey& key) {
  const auto it = failed_.find(key);
  if (it == failed_.end()) return false;
  if (std::chrono::steady_clock::now() < it->second) return true;
  failed_.erase(it);
  return false;
}

void TileStreamer::take_results() {
  for (LoadResult& r : loader_.take_results()) {
    if (r.key.kind == TileKind::imagery) {
      take_image(r);
      continue;
    }
    if (RequestTimeline* t = loader_.timeline()) t->record(r.key, TileEvent::taken);
    LevelCounters& level = levels_[r.key.tile.z];
    switch (r.status) {
      case LoadStatus::loaded: {
        ++level.loaded;
        ++tiles_taken_;
        const std::uint64_t bytes = r.mesh->byte_size();
        // Entries pinned in the previous frame (drawn, or waiting for upload) stay.
        ram_.insert(r.key, std::move(r.mesh), bytes, frame_, frame_ - 1);
        break;
      }
      case LoadStatus::absent:
        ++level.absent;
        absent_.insert(r.key);
        break;
      case LoadStatus::failed:
        ++level.failed;
        ++failures_;
        last_error_ = r.error;
        failed_[r.key] = std::chrono::steady_clock::now() + options_.failure_retry;
        break;
    }
  }
}

TileStreamer::Probe TileStreamer::probe(const View& view, std::uint16_t layer,
                                        const geo::TileId& id, double priority, bool needed) {
  const TileKey key{TileKind::terrain, layer, id};
  if (!layers_[layer].may_contain(id) || absent_.contains(key) || failed_recently(key)) return {};
  ResidentTile* resident = gpu_.peek(key);
  const Obb box = resident ? resident->bounds : unloaded_tile_bounds(layers_[layer], id);
  if (!view.frustum.intersects(box) || occluder_.hides_all(view.eye, box.corners()))
    return {State::culled, nullptr, 0};
  const double distance = box.distance_to(view.eye);
  if (resident) {
    gpu_.find(key);  // a hit, promoted
    gpu_.pin(key, frame_);
    // Its RAM copy is not pinned: the GPU holds it, the RAM tier may give it up first.
    return {State::ready, resident, distance};
  }
  gpu_.find(key);  // a miss
  RequestTimeline* timeline = loader_.timeline();
  if (timeline) timeline->record(key, needed ? TileEvent::needed : TileEvent::prefetched);
  if (!needed) {  // prefetch: asked for, unless already decoded; never uploaded for it
    if (ram_.peek(key)) return {State::not_ready, nullptr, distance};
    wanted_.push_back({key, priority, distance});
    ++frame_result_.prefetched;
    if (requested_ever_.insert(key).second) ++levels_[id.z].requested;
    return {State::not_ready, nullptr, distance};
  }
  ++frame_result_.pending_per_level[id.z];
  if (const std::shared_ptr<const TileMesh>* mesh = ram_.peek(key)) {
    ram_.pin(key, frame_);
    uploads_.push_back({key, priority, distance});
    return {State::not_ready, nullptr, distance, mesh->get()};
  }
  wanted_.push_back({key, priority, distance});
  if (requested_ever_.insert(key).second) ++levels_[id.z].requested;
  return {State::not_ready, nullptr, distance};
}

void TileStreamer::prefetch(const View& view, std::uint16_t layer, const geo::TileId& id,
                            int levels) {
  const LayerDescription& l = layers_[layer];
  if (id.z >= l.max_level || id.z >= static_cast<std::uint32_t>(geo::kMaxLevel)) return;
  if (levels <= 0) {  // where this frame's prefetch stopped
    if (options_.prefetch_levels > 0) prefetch_frontier_.emplace_back(layer, id);
    return;
  }
  // An upper bound of the tile's screen-space error: its level's largest error, seen from the
  // nearest point of the box that holds whatever it will contain.
  const double error = l.level_error(id.z);
  const double sse =
      view.camera.screen_space_error(error, unloaded_tile_bounds(l, id).distance_to(view.eye));
  if (error <= 0 || sse <= options_.max_sse) return;
  const geo::MercatorRect& data = l.mercator_bounds;
  for (const geo::TileId& child : id.children()) {
    // Only tiles that overlap the data (may_contain also admits those that touch its edge: a
    // guess below a tile not known to exist would ask for their 404s).
    if (!interiors_meet(child.bounds(), data)) continue;
    // Ranked after every tile a frame needs (whose priorities are positive errors), among
    // themselves by the estimate: workers send them only when nothing needed is waiting.
    if (probe(view, layer, child, -1.0 / sse, false).state == State::not_ready)
      prefetch(view, layer, child, levels - 1);
  }
}

void TileStreamer::deepen_prefetch(const View& view) {
  const auto threads = static_cast<std::size_t>(std::max(loader_.threads(), 1));
  for (int level = 0;
       level < kMaxDeeperPrefetch && wanted_.size() < threads && !prefetch_frontier_.empty();
       ++level) {
    std::vector<std::pair<std::uint16_t, geo::TileId>> frontier;
    frontier.swap(prefetch_frontier_);
    for (const auto& [layer, id] : frontier) prefetch(view, layer, id, 1);
  }
  prefetch_frontier_.clear();
}

TileStreamer::Refinement TileStreamer::refinement(const View& view, std::uint16_t layer,
                                                  const geo::TileId& id, double error,
                                                  double distance) const {
  Refinement r;
  r.sse = view.camera.screen_space_error(error, distance);
  r.texel_sse = view.camera.screen_space_error(imagery_texel_error(layer, id), distance);
  const bool terrain_refines = r.sse > options_.max_sse && error > 0;
  const bool imagery_refines = r.texel_sse > options_.max_sse;
  r.refines = (terrain_refines || imagery_refines) && id.z < layers_[layer].max_level &&
              id.z < static_cast<std::uint32_t>(geo::kMaxLevel);
  return r;
}

void TileStreamer::look_ahead(const View& view, std::uint16_t layer, const geo::TileId& id,
                              const Probe& p) {
  if (p.state == State::not_ready && !p.decoded) {
    prefetch(view, layer, id, options_.prefetch_levels);
    return;
  }
  double error = 0, distance = 0;
  if (p.state == State::ready) {
    error = p.tile->geometric_error;
    distance = p.distance;
  } else if (p.state == State::not_ready) {
    // Decoded: judged on its own box, as probe() will once it is resident.
    const Obb& box = p.decoded->bounds;
    if (!view.frustum.intersects(box) || occluder_.hides_all(view.eye, box.corners())) return;
    error = p.decoded->geometric_error;
    distance = box.distance_to(view.eye);
  } else {
    return;
  }
  const Refinement r = refinement(view, layer, id, error, distance);
  if (!r.refines) return;
  for (const geo::TileId& child : id.children())
    look_ahead(view, layer, child, probe(view, layer, child, std::max(r.sse, r.texel_sse)));
}

void TileStreamer::draw(const TileKey& key, const Probe& p, double sse, std::uint8_t mask,
                        bool stand_in) {
  frame_result_.draws.push_back({key, p.tile, mask, stand_in, sse, p.distance});
  ++frame_result_.drawn_per_level[key.tile.z];
  frame_result_.max_sse_drawn = std::max(frame_result_.max_sse_drawn, sse);
}

void TileStreamer::descend(const View& view, std::uint16_t layer, const geo::TileId& id,
                           const Probe& self) {
  const TileKey key{TileKind::terrain, layer, id};
  const Refinement r = refinement(view, layer, id, self.tile->geometric_error, self.distance);
  const double sse = r.sse;
  if (!r.refines) {
    draw(key, self, sse, 0xF);
    return;
  }
  const std::array<geo::TileId, 4> children = id.children();
  std::array<Probe, 4> child;
  bool waiting = false;
  for (std::size_t i = 0; i < 4; ++i) {
    child[i] = probe(view, layer, children[i], std::max(sse, r.texel_sse));
    waiting |= child[i].state == State::not_ready;
  }
  if (waiting) {  // no holes: the parent stays until every visible child is resident
    draw(key, self, sse, 0xF, /*stand_in=*/true);
    // Meanwhile, what the view will need below each child (the header's "Look-ahead").
    for (std::size_t i = 0; i < 4; ++i) look_ahead(view, layer, children[i], child[i]);
    return;
  }
  std::uint8_t mask = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto bit = static_cast<std::uint8_t>(1u << i);
    if (child[i].state == State::absent && (self.tile->quadrant_data & bit)) mask |= bit;
    if (child[i].state == State::ready) descend(view, layer, children[i], child[i]);
  }
  if (mask) draw(key, self, sse, mask);
}

double TileStreamer::imagery_texel_error(std::uint16_t layer, const geo::TileId& id) const {
  if (!imagery_enabled_ || options_.imagery_layer < 0 ||
      static_cast<std::size_t>(options_.imagery_layer) >= layers_.size())
    return 0;
  const LayerDescription& img = layers_[static_cast<std::size_t>(options_.imagery_layer)];
  const LayerDescription& terrain = layers_[layer];
  if (img.projection != terrain.projection || id.z >= img.max_level) return 0;
  const geo::MercatorRect r = id.bounds();
  if (!interiors_meet(r, img.mercator_bounds)) return 0;
  // Normalised Mercator spans [-1, 1] for 360°: a unit is π·a metres at the equator, scaled by
  // cos(latitude) (the spherical scale; the ellipsoid's differs by < 0.7 %, enough for a budget).
  constexpr double kPi = 3.14159265358979323846;
  constexpr double kImageryTilePixels = 256;
  const double lat =
      geo::NormalisedMercator(terrain.projection).lat_from_y((r.min_y + r.max_y) / 2);
  return (r.max_x - r.min_x) * kPi * geo::kWgs84A * std::cos(lat * kPi / 180) / kImageryTilePixels;
}

void TileStreamer::upload(GpuUploader& gpu) {
  std::sort(uploads_.begin(), uploads_.end(),
            [](const TileRequest& a, const TileRequest& b) { return less_urgent(b, a); });
  const auto release = [&gpu](const TileKey&, ResidentTile& t) { gpu.release(t.gpu); };
  std::uint64_t used = 0;
  for (const TileRequest& r : uploads_) {
    if (r.key.kind == TileKind::imagery) {
      if (upload_image(r, gpu, used) < 0) break;
      continue;
    }
    std::shared_ptr<const TileMesh>* mesh = ram_.find(r.key);
    if (!mesh) continue;
    const std::uint64_t bytes = (*mesh)->byte_size();
    if (frame_result_.uploaded > 0 && used + bytes > options_.upload_bytes_per_frame) break;
    const TileMesh& m = **mesh;
    ResidentTile t{gpu.upload(m),     m.centre,       m.frame,      m.bounds,
                   m.geometric_error, m.min_z,        m.max_z,      m.quadrant_data,
                   m.skirt_margin,    m.skirt_lowest, m.skirt_spans};
    const std::uint64_t gpu_bytes = t.gpu.bytes;
    if (!gpu_.insert(r.key, t, gpu_bytes, frame_, frame_, release)) break;
    if (RequestTimeline* tl = loader_.timeline()) tl->record(r.key, TileEvent::uploaded);
    used += bytes;
    ++frame_result_.uploaded;
  }
  frame_result_.uploaded_bytes = used;
  frame_result_.upload_pending = uploads_.size() - frame_result_.uploaded;
}

const FrameResult& TileStreamer::update(const Camera& camera, GpuUploader& gpu) {
  ++frame_;
  frame_result_ = FrameResult{};
  wanted_.clear();
  uploads_.clear();
  prefetch_frontier_.clear();
  take_results();

  const View view{camera, camera.frustum(), camera.position()};
  for (std::size_t l = 0; l < layers_.size(); ++l) {
    const auto layer = static_cast<std::uint16_t>(l);
    for (const geo::TileId& root : roots_[l]) {
      const Probe p = probe(view, layer, root, kRootPriority);
      if (p.state == State::ready) descend(view, layer, root, p);
      if (p.state == State::not_ready) look_ahead(view, layer, root, p);
    }
  }
  std::sort(frame_result_.draws.begin(), frame_result_.draws.end(),
            [](const DrawItem& a, const DrawItem& b) { return a.distance < b.distance; });
  plan_skirts(frame_result_.draws);
  drape();
  deepen_prefetch(view);
  frame_result_.complete = wanted_.size() == frame_result_.prefetched && uploads_.empty();
  frame_result_.wanted = wanted_.size();
  upload(gpu);
  loader_.submit(wanted_);
  trim_heap();
  return frame_result_;
}

void TileStreamer::trim_heap() {
  const std::uint64_t churn = gpu_.counters().evictions + ram_.counters().evictions + tiles_taken_;
  if (options_.heap_trim_interval.count() < 0) return;
  const bool churned = churn != trimmed_churn_;
  if (!churned && options_.idle_heap_trim_interval.count() < 0) return;
  const auto now = std::chrono::steady_clock::now();
  const auto interval = churned ? options_.heap_trim_interval : options_.idle_heap_trim_interval;
  if (heap_trims_ > 0 && now - last_trim_ < interval) return;
  {
    std::lock_guard lock(trim_mutex_);
    trim_requested_ = true;
  }
  trim_wake_.notify_one();
  trimmed_churn_ = churn;
  last_trim_ = now;
  ++heap_trims_;
}

void TileStreamer::release_all(GpuUploader& gpu) {
  gpu_.clear([&gpu](const TileKey&, ResidentTile& t) { gpu.release(t.gpu); });
}

}  // namespace tinstream::client
