// Pass 4 driver. The calling thread owns the LayerWriter: it reads the children of a parent (still
// compressed), hands the parent to a worker, and writes finished parents. Workers do all the CPU
// work: decoding the children, building the parent, encoding it for the store.
//
//   calling thread:  read 4 blobs ─▶ tasks ─▶ [workers: decode, build_parent, prepare_tile]
//                    ─▶ done ─▶ writer.put   (at most max_in_flight parents between read and put)
#include "tinstream/lod/pyramid.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "tinstream/base/worker_threads.hpp"
#include "tinstream/lod/error.hpp"
#include "tinstream/lod/parent.hpp"

namespace tinstream::lod {

using tile::TinTile;

namespace {

// A fixed set of workers running submitted jobs; finished results are collected by the owner.
class TilePool {
 public:
  using Job = std::function<Result<store::StoredTile>()>;

  TilePool() = default;
  // Starts the workers; an Error when one cannot be started (the destructor stops and joins
  // those that were).
  Status start(unsigned threads) {
    for (unsigned i = 0; i < threads; ++i) {
      if (Status s = workers_.start([this] { work(); }); !s) return s;
    }
    return {};
  }
  ~TilePool() {
    {
      std::lock_guard lock(m_);
      stop_ = true;
    }
    cv_work_.notify_all();
    (void)workers_.join();
  }
  TilePool(const TilePool&) = delete;
  TilePool& operator=(const TilePool&) = delete;

  void submit(Job job) {
    {
      std::lock_guard lock(m_);
      jobs_.push_back(std::move(job));
    }
    cv_work_.notify_one();
  }
  // Blocks until at least one result is ready and returns all ready ones.
  std::vector<Result<store::StoredTile>> wait_results() {
    std::unique_lock lock(m_);
    cv_done_.wait(lock, [&] { return !done_.empty(); });
    std::vector<Result<store::StoredTile>> out;
    while (!done_.empty()) {
      out.push_back(std::move(done_.front()));
      done_.pop_front();
    }
    return out;
  }

 private:
  void work() {
    for (;;) {
      Job job;
      {
        std::unique_lock lock(m_);
        cv_work_.wait(lock, [&] { return stop_ || !jobs_.empty(); });
        if (stop_ && jobs_.empty()) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      Result<store::StoredTile> r = Error(ErrorCode::internal, "lod: job did not run");
      // The exception barrier: a job that throws is a failed tile. Fault point "lod.tile".
      if (Status s = guarded("lod",
                             [&] {
                               fault::point("lod.tile");
                               r = job();
                             });
          !s) {
        r = s.error();
      }
      {
        std::lock_guard lock(m_);
        done_.push_back(std::move(r));
      }
      cv_done_.notify_one();
    }
  }

  std::mutex m_;  // guards jobs_, done_, stop_
  std::condition_variable cv_work_, cv_done_;
  std::deque<Job> jobs_;
  std::deque<Result<store::StoredTile>> done_;
  bool stop_ = false;
  WorkerThreads workers_{"lod worker", "lod.tile"};  // last: joined before the rest goes
};

class Throttle {
 public:
  bool due() {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(200)) return false;
    last_ = now;
    return true;
  }

 private:
  std::chrono::steady_clock::time_point last_{};
};

// A child tile read back from the layer being written, decoded on a worker.
Result<TinTile> decode_child(const store::StoredTile& stored) {
  auto decoded = store::decode_tile(stored);
  if (!decoded) {
    return Error(decoded.error().code,
                 "lod: tile " + stored.id.to_string() + ": " + decoded.error().message);
  }
  return decoded;
}

}  // namespace

Result<PyramidSummary> build_pyramid(store::LayerWriter& writer, std::uint32_t finest_level,
                                     std::uint32_t min_level, const PyramidOptions& options,
                                     unsigned threads, const ProgressSink& progress) {
  if (finest_level > static_cast<std::uint32_t>(geo::kMaxLevel) || min_level > finest_level) {
    return invalid_argument("lod: levels must satisfy min_level ≤ finest_level ≤ 30, got " +
                            std::to_string(min_level) + " and " + std::to_string(finest_level));
  }
  if (options.lod.max_points < 4) return invalid_argument("lod: max_points must be at least 4");
  threads = std::max(threads, 1u);
  const std::size_t max_in_flight = options.max_in_flight ? options.max_in_flight : 2 * threads + 2;
  PyramidOptions opts = options;
  PyramidSummary summary;
  summary.level_max_error.assign(finest_level + 1, 0.0);
  summary.level_tiles.assign(finest_level + 1, 0);
  summary.level_vertices.assign(finest_level + 1, 0);
  auto account = [&](const store::StoredTile& t) {
    summary.level_max_error[t.id.z] = std::max(summary.level_max_error[t.id.z], t.geometric_error);
    ++summary.level_tiles[t.id.z];
    summary.level_vertices[t.id.z] += t.vertex_count;
  };

  TilePool pool;
  if (Status s = pool.start(threads); !s) return s.error();
  std::uint64_t done = 0;
  std::uint64_t total = 0;
  Throttle throttle;
  auto report = [&](bool force) -> Status {
    if (!progress || (!force && !throttle.due())) return {};
    if (!progress(Progress{"lod", done, total, "tiles"}))
      return Error(ErrorCode::cancelled, "lod: cancelled");
    return {};
  };

  // Runs `load` for every item on the calling thread, the job it returns on the pool, and `store`
  // on the calling thread, with at most max_in_flight items between load and store.
  auto run_level = [&](const std::vector<geo::TileId>& items,
                       const std::function<Result<TilePool::Job>(const geo::TileId&)>& load,
                       const std::function<Status(store::StoredTile &&)>& store) -> Status {
    std::size_t next = 0, in_flight = 0;
    std::optional<Error> failure;
    while ((next < items.size() && !failure) || in_flight > 0) {
      while (!failure && in_flight < max_in_flight && next < items.size()) {
        auto job = load(items[next++]);
        if (!job.ok()) {
          failure = job.error();
          break;
        }
        pool.submit(std::move(*job));
        ++in_flight;
      }
      if (in_flight == 0) break;
      for (auto& r : pool.wait_results()) {
        --in_flight;
        if (failure) continue;
        if (!r.ok()) {
          failure = r.error();
          continue;
        }
        if (Status s = store(std::move(*r)); !s.ok()) {
          failure = s.error();
          continue;
        }
        ++done;
        if (Status s = report(false); !s.ok()) failure = s.error();
      }
    }
    if (failure) return *failure;
    return writer.flush();
  };

  // ---- optional reduced TIN at the finest level ----------------------------------------------
  auto finest_ids = writer.tile_ids(finest_level);
  if (!finest_ids.ok()) return finest_ids.error();
  if (options.reduce_finest) {
    total += finest_ids->size();
    const LodOptions lod = opts.lod;
    Status s = run_level(
        *finest_ids,
        [&](const geo::TileId& id) -> Result<TilePool::Job> {
          auto t = writer.get_stored(id);
          if (!t.ok()) return t.error();
          if (!*t) return not_found("lod: finest tile " + id.to_string() + " vanished");
          auto blob = std::make_shared<store::StoredTile>(std::move(**t));
          const HeightRange heights = opts.finest_heights;
          return TilePool::Job([blob, lod, heights]() -> Result<store::StoredTile> {
            auto decoded = decode_child(*blob);
            if (!decoded) return decoded.error();
            TinTile& tile = *decoded;
            bool nodata = false;
            for (const auto& tr : tile.triangles) {
              for (auto v : tr) nodata = nodata || (v < 4 && tile.corner_nodata[v]);
            }
            if (Status st = reduce_finest_tile(tile, lod); !st.ok()) return st.error();
            if (nodata) {
              // The reduced tile's NODATA fan may reach over the original's data (parent.hpp).
              tile.geometric_error =
                  std::max(tile.geometric_error,
                           nodata_band_bound(tile, heights) + error_rounding_allowance(tile));
            }
            return store::prepare_tile(tile);
          });
        },
        [&](store::StoredTile&& t) { return writer.put(std::move(t)); });
    if (!s.ok()) return s.error();
  }
  if (finest_level == min_level) {
    for (const auto& id : *finest_ids) {
      auto t = writer.get_stored(id);
      if (!t.ok()) return t.error();
      if (*t) account(**t);
    }
    return summary;
  }

  // ---- levels finest-1 … min_level -----------------------------------------------------------
  std::vector<geo::TileId> child_ids = std::move(*finest_ids);
  for (std::uint32_t z = finest_level; z-- > min_level;) {
    std::set<geo::TileId> parent_set;
    for (const auto& c : child_ids) parent_set.insert(c.parent());
    std::vector<geo::TileId> parents(parent_set.begin(), parent_set.end());
    std::sort(parents.begin(), parents.end(),
              [](const auto& a, const auto& b) { return a.morton() < b.morton(); });
    total += parents.size();
    if (Status s = report(true); !s.ok()) return s.error();
    const LodOptions lod = opts.lod;
    std::vector<geo::TileId> written;
    written.reserve(parents.size());
    Status s = run_level(
        parents,
        [&](const geo::TileId& pid) -> Result<TilePool::Job> {
          auto blobs = std::make_shared<std::array<std::optional<store::StoredTile>, 4>>();
          const auto ids = pid.children();
          for (std::size_t i = 0; i < 4; ++i) {
            auto t = writer.get_stored(ids[i]);
            if (!t.ok()) return t.error();
            if (*t) {
              account(**t);
              (*blobs)[i] = std::move(**t);
            }
          }
          const HeightRange heights = opts.finest_heights;
          return TilePool::Job([blobs, pid, lod, heights]() -> Result<store::StoredTile> {
            std::array<std::optional<TinTile>, 4> kids;
            for (std::size_t i = 0; i < 4; ++i) {
              if (!(*blobs)[i]) continue;
              auto decoded = decode_child(*(*blobs)[i]);
              if (!decoded) return decoded.error();
              kids[i] = std::move(*decoded);
              (*blobs)[i].reset();  // the compressed copy is not needed any more
            }
            auto parent = build_parent(pid, std::move(kids), lod, nullptr, heights);
            if (!parent) return parent.error();
            return store::prepare_tile(*parent);
          });
        },
        [&](store::StoredTile&& t) -> Status {
          const store::StoredTile& stored = t;
          if (t.id.z == min_level) account(stored);
          const geo::TileId id = t.id;
          if (Status st = writer.put(std::move(t)); !st.ok()) return st;
          written.push_back(id);
          return {};
        });
    if (!s.ok()) return s.error();
    summary.tiles_built += written.size();
    child_ids = std::move(written);
  }
  if (Status s = report(true); !s.ok()) return s.error();
  return summary;
}

}  // namespace tinstream::lod
