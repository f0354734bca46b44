// The imagery ingest: plan the mosaic, walk the finest tiles in Morton order, render them on a
// worker pool, assemble the coarser levels as children complete, publish.
#include "tinstream/imagery/ingest_imagery.hpp"

#include <gdal.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "mosaic.hpp"
#include "tinstream/base/fault.hpp"
#include "tinstream/base/worker_threads.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::imagery {

namespace {

using Clock = std::chrono::steady_clock;

// The tiles of one level that overlap a footprint, depth-first from the world tile, children in
// quadkey digit order: i.e. in Morton order, produced one at a time without listing them.
class FinestTiles {
 public:
  FinestTiles(std::vector<geo::MercatorRect> footprints, std::uint32_t level)
      : footprints_(std::move(footprints)), level_(level) {
    stack_.push_back({0, 0, 0});
  }

  std::optional<geo::TileId> next() {
    while (!stack_.empty()) {
      const geo::TileId t = stack_.back();
      stack_.pop_back();
      if (!covered(t)) continue;
      if (t.z == level_) return t;
      const auto children = t.children();
      // Pushed last to first, so the first (north-west) child comes out next.
      stack_.insert(stack_.end(), children.rbegin(), children.rend());
    }
    return std::nullopt;
  }

 private:
  bool covered(const geo::TileId& t) const {
    const geo::MercatorRect r = t.bounds();
    for (const auto& f : footprints_) {
      if (f.overlaps(r)) return true;
    }
    return false;
  }

  std::vector<geo::MercatorRect> footprints_;
  std::uint32_t level_;
  std::vector<geo::TileId> stack_;
};

// A finest tile as a worker left it: its pixels and encoding, nothing when no pixel is visible.
struct RenderedTile {
  std::uint64_t seq = 0;
  geo::TileId id;
  Status status;
  std::optional<RgbaImage> image;
  std::vector<std::uint8_t> encoded;
};

// Worker threads that render and encode finest tiles. start(), submit() and take() are called by
// one thread (the ingest's); results come back in any order, each with the sequence number it was
// submitted with. The workers are a WorkerThreads group (the exception barrier): whatever escapes
// a worker's loop ends that worker and fails the ingest through take(), which never waits for a
// tile no worker will render. Fault points: "imagery.render" (one tile, inside the loop),
// "imagery.worker.spawn" (starting a worker).
class RenderPool {
 public:
  RenderPool(const MosaicPlan& plan, const ImageryIngestOptions& options)
      : plan_(plan), options_(options) {}
  ~RenderPool() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    jobs_ready_.notify_all();
    (void)workers_.join();  // their failures were handed to take()
  }
  RenderPool(const RenderPool&) = delete;
  RenderPool& operator=(const RenderPool&) = delete;

  // Starts `threads` workers; an Error when one cannot be started (the destructor stops those
  // that were).
  Status start(unsigned threads) {
    for (unsigned i = 0; i < threads; ++i) {
      if (Status s = workers_.start([this] { return run_worker(); }); !s) return s;
    }
    return {};
  }

  void submit(std::uint64_t seq, const geo::TileId& id) {
    {
      std::lock_guard lock(mutex_);
      jobs_.emplace_back(seq, id);
    }
    jobs_ready_.notify_one();
  }

  // The next finished tile, or the failure of a worker that died.
  Result<RenderedTile> take() {
    std::unique_lock lock(mutex_);
    results_ready_.wait(lock, [&] { return !results_.empty() || !worker_failure_.ok(); });
    if (!worker_failure_.ok()) return worker_failure_.error();
    RenderedTile r = std::move(results_.front());
    results_.pop_front();
    return r;
  }

 private:
  Status run_worker() {
    Status s = guarded("imagery worker", [this] { work(); });
    if (!s.ok()) {
      {
        std::lock_guard lock(mutex_);
        if (worker_failure_.ok()) worker_failure_ = s;
      }
      results_ready_.notify_all();
    }
    return s;
  }

  void work() {
    std::unique_ptr<TileRenderer> renderer;
    std::string failure;
    try {
      renderer = std::make_unique<TileRenderer>(plan_, options_.resampling, 256);
    } catch (const std::exception& e) {
      failure = e.what();  // every job this worker takes then fails with it
    }
    while (true) {
      std::pair<std::uint64_t, geo::TileId> job;
      {
        std::unique_lock lock(mutex_);
        jobs_ready_.wait(lock, [&] { return stopping_ || !jobs_.empty(); });
        if (stopping_) return;
        job = jobs_.front();
        jobs_.pop_front();
      }
      fault::point("imagery.render");
      RenderedTile r;
      if (renderer) {
        r = render(*renderer, options_, job.first, job.second);
      } else {
        r.seq = job.first;
        r.id = job.second;
        r.status = Error(ErrorCode::internal, "imagery worker: " + failure);
      }
      {
        std::lock_guard lock(mutex_);
        results_.push_back(std::move(r));
      }
      results_ready_.notify_one();
    }
  }

  // A tile's own failures (GDAL, the encoder) become the tile's status.
  static RenderedTile render(TileRenderer& renderer, const ImageryIngestOptions& options,
                             std::uint64_t seq, const geo::TileId& id) {
    RenderedTile r;
    r.seq = seq;
    r.id = id;
    try {
      auto image = renderer.render(id);
      if (!image) {
        r.status = image.error();
        return r;
      }
      if (image->fully_transparent()) return r;
      auto encoded = encode(*image, options.format, options.encode);
      if (!encoded) {
        r.status = encoded.error();
        return r;
      }
      r.encoded = std::move(*encoded);
      r.image = std::move(*image);
    } catch (const std::exception& e) {
      r.status = Error(ErrorCode::internal, "tile " + id.to_string() + ": " + e.what());
    }
    return r;
  }

  const MosaicPlan& plan_;
  const ImageryIngestOptions& options_;
  std::mutex mutex_;
  std::condition_variable jobs_ready_, results_ready_;
  std::deque<std::pair<std::uint64_t, geo::TileId>> jobs_;     // guarded by mutex_
  std::deque<RenderedTile> results_;                           // guarded by mutex_
  bool stopping_ = false;                                      // guarded by mutex_
  Status worker_failure_;                                      // guarded by mutex_
  WorkerThreads workers_{"imagery worker", "imagery.worker"};  // last: joined first
};

// Builds the levels above the finest from tiles handed in Morton order. A parent is finished
// when a tile of another parent arrives at its level (Morton order: all of a parent's
// descendants come together) or at finish(); then it is downsampled from its children, stored
// through `store`, and handed on to its own parent.
class PyramidBuilder {
 public:
  using Store = std::function<Status(const geo::TileId&, const RgbaImage&)>;

  PyramidBuilder(std::uint32_t min_level, std::uint32_t max_level, Store store)
      : min_level_(min_level), pending_(max_level + 1), store_(std::move(store)) {}

  // A tile of level ≤ max_level, with its pixels or none (transparent).
  Status add(const geo::TileId& tile, std::optional<RgbaImage> image) {
    if (tile.z <= min_level_) return {};
    const geo::TileId parent = tile.parent();
    Pending& p = pending_[parent.z];
    if (p.parent && *p.parent != parent) {
      if (Status s = close(parent.z); !s) return s;
    }
    p.parent = parent;
    p.children[static_cast<std::size_t>(tile.child_index())] = std::move(image);
    return {};
  }

  // Finishes every open parent, finest level first.
  Status finish() {
    for (std::size_t z = pending_.size(); z-- > min_level_;) {
      if (Status s = close(static_cast<std::uint32_t>(z)); !s) return s;
    }
    return {};
  }

 private:
  struct Pending {
    std::optional<geo::TileId> parent;
    std::array<std::optional<RgbaImage>, 4> children;
  };

  Status close(std::uint32_t level) {
    Pending& p = pending_[level];
    if (!p.parent) return {};
    const geo::TileId id = *p.parent;
    std::array<const RgbaImage*, 4> children{};
    bool any = false;
    for (std::size_t k = 0; k < 4; ++k) {
      if (p.children[k]) children[k] = &*p.children[k], any = true;
    }
    std::optional<RgbaImage> image;
    if (any) image = downsample_children(children);
    p = Pending{};
    if (image && image->fully_transparent()) image.reset();
    if (image) {
      if (Status s = store_(id, *image); !s) return s;
    }
    return add(id, std::move(image));
  }

  std::uint32_t min_level_;
  std::vector<Pending> pending_;  // index: level of the parent being assembled
  Store store_;
};

// Calls the sink at most four times a second (and always for the last tile).
class Throttle {
 public:
  explicit Throttle(const ProgressSink& sink) : sink_(sink) {}
  bool report(std::uint64_t done, std::uint64_t total) {
    if (!sink_) return true;
    const auto now = Clock::now();
    if (done != total && now - last_ < std::chrono::milliseconds(250)) return true;
    last_ = now;
    return sink_({"imagery", done, total, "tiles"});
  }

 private:
  const ProgressSink& sink_;
  Clock::time_point last_{};
};

struct Levels {
  std::uint32_t min_level = 0, max_level = 0;
};

Result<Levels> choose_levels(const ImageryIngestOptions& o, std::uint32_t native) {
  Levels l;
  l.max_level = o.max_level.value_or(native);
  l.min_level = o.min_level;
  if (l.max_level > static_cast<std::uint32_t>(geo::kMaxLevel)) {
    return invalid_argument("--max-level " + std::to_string(l.max_level) + " is above " +
                            std::to_string(geo::kMaxLevel));
  }
  if (l.min_level > l.max_level) {
    return invalid_argument("--min-level " + std::to_string(l.min_level) +
                            " is above the finest level " + std::to_string(l.max_level) +
                            (o.max_level ? "" : " (the sources' native resolution)"));
  }
  return l;
}

// The projection: the option, else the terrain layer of the same name's, else spherical.
std::pair<geo::Projection, std::string> choose_projection(const ImageryIngestOptions& o,
                                                          store::TileStore& store) {
  if (o.projection) return {*o.projection, "--projection"};
  if (auto terrain = store.layer(o.layer)) {
    return {terrain->projection, "the terrain layer '" + o.layer + "'"};
  }
  return {geo::Projection::spherical, "default"};
}

std::string options_json(const ImageryIngestOptions& o, const Levels& levels) {
  nlohmann::json sources = nlohmann::json::array();
  for (const auto& s : o.sources) sources.push_back(s.filename().string());
  nlohmann::json j = {{"resampling", o.resampling},
                      {"min_level", levels.min_level},
                      {"max_level", levels.max_level},
                      {"sources", sources}};
  if (o.format != ImageFormat::png) j["quality"] = o.encode.quality;
  if (o.format == ImageFormat::webp) j["lossless"] = o.encode.lossless;
  if (!o.crs.empty()) j["crs"] = o.crs;
  return j.dump();
}

// Renders the finest level on the pool and feeds the pyramid, in Morton order. At most
// `window` tiles are in flight; results are reordered by sequence number before use.
Status render_levels(const MosaicPlan& plan, const ImageryIngestOptions& options,
                     const Levels& levels, store::ImageryWriter& writer, ImagerySummary& summary,
                     const ProgressSink& progress) {
  std::vector<geo::MercatorRect> footprints;
  for (const auto& s : plan.sources) footprints.push_back(s.bounds);
  std::uint64_t total = 0;
  for (FinestTiles count(footprints, levels.max_level); count.next();) ++total;

  const auto put = [&](const geo::TileId& id, std::vector<std::uint8_t> bytes) -> Status {
    auto& level = summary.levels[id.z - levels.min_level];
    level.tiles += 1;
    level.bytes += bytes.size();
    return writer.put({id, std::move(bytes), {}});
  };
  PyramidBuilder pyramid(levels.min_level, levels.max_level,
                         [&](const geo::TileId& id, const RgbaImage& image) -> Status {
                           auto bytes = encode(image, options.format, options.encode);
                           if (!bytes) return bytes.error();
                           return put(id, std::move(*bytes));
                         });

  unsigned threads = options.threads != 0 ? options.threads : std::thread::hardware_concurrency();
  threads = std::max(1u, threads);
  const std::uint64_t window = 4ull * threads;
  RenderPool pool(plan, options);
  if (Status s = pool.start(threads); !s) return s;
  FinestTiles tiles(footprints, levels.max_level);
  Throttle throttle(progress);
  std::map<std::uint64_t, RenderedTile> ready;
  std::uint64_t submitted = 0, consumed = 0;
  bool more = true;
  while (true) {
    while (more && submitted - consumed < window) {
      const auto next = tiles.next();
      if (!next) {
        more = false;
        break;
      }
      pool.submit(submitted++, *next);
    }
    if (consumed == submitted) break;
    auto r = pool.take();
    if (!r) return r.error();
    ready.emplace(r->seq, std::move(*r));
    for (auto it = ready.find(consumed); it != ready.end(); it = ready.find(consumed)) {
      RenderedTile tile = std::move(it->second);
      ready.erase(it);
      ++consumed;
      if (!tile.status) return tile.status;
      if (tile.image) {
        if (Status s = put(tile.id, std::move(tile.encoded)); !s) return s;
      }
      if (Status s = pyramid.add(tile.id, std::move(tile.image)); !s) return s;
      if (!throttle.report(consumed, total)) return Error(ErrorCode::cancelled, "cancelled");
    }
  }
  summary.finest_visited = consumed;
  return pyramid.finish();
}

}  // namespace

Result<ImagerySummary> ingest_imagery(const ImageryIngestOptions& options,
                                      const ProgressSink& progress) {
  const auto start = Clock::now();
  if (Status s = store::validate_layer_name(options.layer); !s) return s.error();
  if (Status s = check_resampling(options.resampling); !s) return s.error();
  auto store = store::TileStore::open(options.store_path, store::TileStore::Mode::read_write);
  if (!store) return store.error();
  ImagerySummary summary;
  summary.layer = options.layer;
  summary.format = std::string(to_string(options.format));
  std::tie(summary.projection, summary.projection_rule) = choose_projection(options, *store);

  GDALSetCacheMax64(static_cast<GIntBig>(options.memory_bytes / 2));
  auto plan = plan_mosaic(options.sources, options.crs, summary.projection, 256);
  if (!plan) return plan.error();
  auto levels = choose_levels(options, plan->native_level);
  if (!levels) return levels.error();
  summary.native_level = plan->native_level;
  summary.min_level = levels->min_level;
  summary.max_level = levels->max_level;
  for (const auto& s : plan->sources) {
    summary.sources.push_back({s.path, s.driver, s.crs, s.bands, s.width, s.height, s.resolution});
  }
  for (std::uint32_t z = levels->min_level; z <= levels->max_level; ++z) {
    summary.levels.push_back({z, 0, 0});
  }
  const geo::NormalisedMercator mercator(summary.projection);
  const geo::LonLat sw = mercator.inverse({plan->bounds.min_x, plan->bounds.min_y});
  const geo::LonLat ne = mercator.inverse({plan->bounds.max_x, plan->bounds.max_y});
  summary.bounds = {sw.lon, sw.lat, ne.lon, ne.lat};

  store::ImageryInfo info;
  info.name = options.layer;
  info.projection = summary.projection;
  info.format = summary.format;
  info.tile_size = 256;
  info.mercator_bounds = plan->bounds;
  info.bounds = summary.bounds;
  info.min_level = levels->min_level;
  info.max_level = levels->max_level;
  info.options_json = options_json(options, *levels);
  info.attribution = options.attribution;
  auto writer = store->begin_imagery(info);
  if (!writer) return writer.error();
  // From here on the writer abandons its version on every early return (its destructor).
  if (Status s = render_levels(*plan, options, *levels, **writer, summary, progress); !s) {
    return s.error();
  }
  for (const auto& l : summary.levels) {
    summary.tiles += l.tiles;
    summary.bytes += l.bytes;
  }
  if (summary.tiles == 0) {
    return invalid_argument("no source pixel is visible at level " +
                            std::to_string(levels->max_level) +
                            " (every source is transparent or NODATA there)");
  }
  if (progress && !progress({"publish", 0, 1, "layers"})) {
    return Error(ErrorCode::cancelled, "cancelled");
  }
  if (Status s = (*writer)->publish(info); !s) return s.error();
  summary.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

}  // namespace tinstream::imagery
