// Pass 4 driver. The calling thread owns the TileSink's reads and writes: it reads the children
// of a parent (still encoded), hands the parent to a worker, and writes finished parents. Workers
// do all the CPU work: decoding the children and sources (or taking them from the cache of
// decoded tiles that a coarser level reads again), building the parent, encoding it for the sink.
//
//   calling thread:  read 4 blobs ─▶ tasks ─▶ [workers: decode, build_parent, sink.encode]
//                    ─▶ done ─▶ sink.put   (at most max_in_flight parents between read and put)
#include "tinstream/lod/pyramid.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "side_store.hpp"
#include "tinstream/base/worker_threads.hpp"
#include "tinstream/lod/error.hpp"
#include "tinstream/lod/parent.hpp"

namespace tinstream::lod {

using tile::TinTile;

namespace {

// What a job hands back: the tile encoded for the sink and its side record.
struct Built {
  std::unique_ptr<EncodedTile> stored;
  std::vector<std::uint8_t> side;
};

// A fixed set of workers running submitted jobs; finished results are collected by the owner.
class TilePool {
 public:
  using Job = std::function<Result<Built>()>;

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
  std::vector<Result<Built>> wait_results() {
    std::unique_lock lock(m_);
    cv_done_.wait(lock, [&] { return !done_.empty(); });
    std::vector<Result<Built>> out;
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
      Result<Built> r = Error(ErrorCode::internal, "lod: job did not run");
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
  std::deque<Result<Built>> done_;
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
Result<TinTile> decode_child(const TileSink& sink, const EncodedTile& stored) {
  auto decoded = sink.decode(stored);
  if (!decoded) {
    return Error(decoded.error().code,
                 "lod: tile " + stored.id().to_string() + ": " + decoded.error().message);
  }
  return decoded;
}

// A tile as read for the next level: the stored blob and its side record (none for an unreduced
// finest tile), decoded on a worker.
struct ReadTile {
  std::unique_ptr<EncodedTile> stored;
  std::optional<std::vector<std::uint8_t>> side;
};

Result<LodTile> decode_lod_tile(const TileSink& sink, const ReadTile& read) {
  auto tile = decode_child(sink, *read.stored);
  if (!tile) return tile.error();
  LodTile out;
  out.tile = std::move(*tile);
  if (read.side) {
    if (Status s = detail::decode_side(*read.side, out); !s) return s.error();
  }
  return out;
}

// Bytes a decoded tile holds (its vectors' contents).
std::size_t tile_bytes(const LodTile& t) {
  auto bytes = [](const auto& v) { return v.size() * sizeof(v[0]); };
  const TinTile& tt = t.tile;
  return sizeof(LodTile) + bytes(tt.north) + bytes(tt.east) + bytes(tt.south) + bytes(tt.west) +
         bytes(tt.interior) + bytes(tt.triangles) + bytes(t.bounds) + bytes(t.reaches) +
         bytes(t.witnesses);
}

// Decoded tiles that a coarser level reads again, shared by the workers, at most `budget` bytes
// of them. Every level reads the tiles of its source level in the same (Morton) order, so the
// levels above the one where the data fit 4^source_depth tiles re-read the same tiles level after
// level, and a tile read as a child is read again as a source: a cache that keeps what it
// admitted while it is still needed (no eviction, which a cyclic scan would defeat) spares
// those decodes up to its budget. Decoding gives the same tile every time, so hits and misses
// give the same parents. The calling thread takes hits (a job holds what it was given) and,
// between levels, drops the tiles no coarser level reads; workers add what they decoded.
class DecodedTiles {
 public:
  explicit DecodedTiles(std::size_t budget) : budget_(budget) {}

  std::shared_ptr<const LodTile> find(const geo::TileId& id) {
    std::lock_guard lock(m_);
    const auto it = tiles_.find(id);
    return it == tiles_.end() ? nullptr : it->second;
  }
  // Keeps `tile` if it fits the budget.
  void add(const geo::TileId& id, std::shared_ptr<const LodTile> tile) {
    const std::size_t size = tile_bytes(*tile);
    std::lock_guard lock(m_);
    if (bytes_ + size > budget_ || tiles_.count(id)) return;
    bytes_ += size;
    tiles_.emplace(id, std::move(tile));
  }
  // Drops the tiles for which `dead` is true.
  template <typename Dead>
  void drop(Dead dead) {
    std::lock_guard lock(m_);
    for (auto it = tiles_.begin(); it != tiles_.end();) {
      if (dead(it->first)) {
        bytes_ -= tile_bytes(*it->second);
        it = tiles_.erase(it);
      } else {
        ++it;
      }
    }
  }

 private:
  const std::size_t budget_;
  std::mutex m_;  // guards tiles_, bytes_
  std::map<geo::TileId, std::shared_ptr<const LodTile>> tiles_;
  std::size_t bytes_ = 0;
};

// A tile a job needs: decoded already (from the cache) or still as read from the sink, and
// whether a coarser level reads it again (then the cache may keep it).
struct NeededTile {
  std::shared_ptr<const LodTile> decoded;
  std::optional<ReadTile> read;
  bool read_again = false;
};

// The decoded tile, decoding (and caching) it on the first call.
Result<std::shared_ptr<const LodTile>> decoded(const TileSink& sink, NeededTile& t,
                                               DecodedTiles& cache) {
  if (!t.decoded) {
    auto d = decode_lod_tile(sink, *t.read);
    if (!d) return d.error();
    t.decoded = std::make_shared<const LodTile>(std::move(*d));
    if (t.read_again) cache.add(t.decoded->tile.id, t.decoded);
    t.read.reset();  // the compressed copy is not needed any more
  }
  return t.decoded;
}

// The tiles of the children's level while a level is built, read back from the sink on the
// calling thread (the last few decoded are kept: neighbouring parents read the same).
class LevelTiles {
 public:
  LevelTiles(TileSink& sink, const std::set<geo::TileId>& level) : sink_(sink), level_(level) {}

  // The tile at column x, row y of `level` when the level has it.
  std::optional<geo::TileId> present(std::uint32_t level, std::int64_t x, std::int64_t y) const {
    const std::int64_t n = std::int64_t{1} << level;
    if (x < 0 || y < 0 || x >= n || y >= n) return std::nullopt;
    const geo::TileId id{level, static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y)};
    if (!level_.count(id)) return std::nullopt;
    return id;
  }

  // A decoded tile of the level.
  Result<const TinTile*> tile(const geo::TileId& id) {
    for (const auto& [cached_id, t] : cache_) {
      if (cached_id == id) return &t;
    }
    auto stored = sink_.get(id);
    if (!stored) return stored.error();
    if (!*stored) return not_found("lod: tile " + id.to_string() + " vanished");
    auto decoded = decode_child(sink_, **stored);
    if (!decoded) return decoded.error();
    if (cache_.size() >= 8) cache_.pop_front();
    cache_.emplace_back(id, std::move(*decoded));
    return &cache_.back().second;
  }

 private:
  TileSink& sink_;
  const std::set<geo::TileId>& level_;
  std::deque<std::pair<geo::TileId, TinTile>> cache_;
};

// Where a child is absent, the parent's corner there takes its height from the tiles of the
// children's level (docs/tile-format.md §2.1), and its NODATA flag too: a tile of that level
// that has the corner gives both (NODATA or not, as it has it), else the corner is NODATA. The
// parent across the corner, whose child there is present, takes the same from that child: the
// two agree, and thin their shared side alike (issue #20: the 250 m Luxembourg DEM at
// --max-points 2048 had one flag the corner data, the other NODATA). Runs on the calling thread
// (it reads the sink); answers are kept per corner, which up to four parents share.
class AbsentCorners {
 public:
  explicit AbsentCorners(LevelTiles& level) : level_(level) {}

  // Corner k of `parent`, whose child k is absent: its height and NODATA flag.
  Result<AbsentCorner> corner(const geo::TileId& parent, int k) {
    const geo::TileId child = parent.children()[static_cast<std::size_t>(k)];
    // The corner in the children's level: column gx, row gy of the tile grid lines.
    const std::int64_t gx = std::int64_t{child.x} + (k & 1), gy = std::int64_t{child.y} + (k >> 1);
    const auto key = std::pair{gx, gy};
    if (const auto it = known_.find(key); it != known_.end()) return it->second;
    auto z = compute(child.z, gx, gy);
    if (z) known_.emplace(key, *z);
    return z;
  }

 private:
  Result<AbsentCorner> compute(std::uint32_t level, std::int64_t gx, std::int64_t gy) {
    const std::int64_t n = std::int64_t{1} << level;
    auto present = [&](std::int64_t x, std::int64_t y) { return level_.present(level, x, y); };
    // A tile of the level that has the corner: its height and flag there (all of them agree).
    for (int q = 0; q < 4; ++q) {
      const std::int64_t tx = gx - 1 + (q & 1), ty = gy - 1 + (q >> 1);
      const auto id = present(tx, ty);
      if (!id) continue;
      auto t = level_.tile(*id);
      if (!t) return t.error();
      const auto c = static_cast<std::size_t>(3 - q);  // the corner at (gx, gy)
      return AbsentCorner{(*t)->corners[c].z, (*t)->corner_nodata[c]};
    }
    // Else the nearest data vertex of the level, searched in square rings of tiles around the
    // corner: ring r holds the tiles r tiles away from the four that meet there, at least r tile
    // widths from the corner.
    const double x = -1.0 + 2.0 * static_cast<double>(gx) / static_cast<double>(n);
    const double y = 1.0 - 2.0 * static_cast<double>(gy) / static_cast<double>(n);
    const double width = 2.0 / static_cast<double>(n);
    std::optional<NearestVertex> best;
    for (std::int64_t ring = 0; ring <= n; ++ring) {
      for (std::int64_t ty = gy - 1 - ring; ty <= gy + ring; ++ty) {
        for (std::int64_t tx = gx - 1 - ring; tx <= gx + ring; ++tx) {
          const bool edge =
              ty == gy - 1 - ring || ty == gy + ring || tx == gx - 1 - ring || tx == gx + ring;
          if (!edge) continue;
          const auto id = present(tx, ty);
          if (!id) continue;
          auto t = level_.tile(*id);
          if (!t) return t.error();
          const auto v = nearest_data_vertex(**t, x, y);
          if (v && (!best || v->closer_than(*best))) best = v;
        }
      }
      const double reach = static_cast<double>(ring + 1) * width;
      if (best && best->d2 < reach * reach * (1 - 1e-9)) break;
    }
    if (!best) return Error(ErrorCode::internal, "lod: no data vertex for a NODATA corner");
    return AbsentCorner{best->z, true};
  }

  LevelTiles& level_;
  std::map<std::pair<std::int64_t, std::int64_t>, AbsentCorner> known_;
};

// Where a child is absent, its stretch of the parent's outer border as the tiles of the
// children's level across that border have it (parent.hpp's AbsentBorder): the side of the tile
// across, and the side's midpoint where both children along it are absent. The parent across
// builds its side from its own children there, which are those tiles, so both parents get the
// same side points (issue #20: the 250 m Luxembourg DEM at --max-points 2048 had 11/1059/699,
// whose child 12/2118/1398 is absent, without the points that 11/1059/698 and 11/1058/699 took
// from 12/2118/1397 and 12/2117/1398 on their shared sides). Only the children's level is read:
// the border's candidates are the children's, for sources of any depth (deeper sources' border
// points are orphans, which do not thin the border).
class AbsentSides {
 public:
  explicit AbsentSides(LevelTiles& level) : level_(level) {}

  // The border of `parent` across its absent children (present[k]: child k is present).
  Result<AbsentBorder> border(const geo::TileId& parent, const std::array<bool, 4>& present) {
    using D = geo::Direction;
    struct Side {
      D d;
      std::array<std::size_t, 2> along;            // the children along it, west or north first
      std::int64_t dx, dy;                         // the step across it
      std::vector<tile::Vertex> TinTile::*facing;  // the side of the tile across that faces it
    };
    static constexpr std::array<Side, 4> kSides = {{{D::north, {0, 1}, 0, -1, &TinTile::south},
                                                    {D::east, {1, 3}, 1, 0, &TinTile::west},
                                                    {D::south, {2, 3}, 0, 1, &TinTile::north},
                                                    {D::west, {0, 2}, -1, 0, &TinTile::east}}};
    const auto kids = parent.children();
    AbsentBorder out;
    for (const Side& side : kSides) {
      const auto di = static_cast<std::size_t>(side.d);
      // The side's midpoint, column gx and row gy of the children's level's grid lines.
      const geo::TileId& first = kids[side.along[0]];
      const std::int64_t gx = std::int64_t{first.x} + (side.d == D::east ? 1 : 0) +
                              (side.d == D::north || side.d == D::south ? 1 : 0);
      const std::int64_t gy = std::int64_t{first.y} + (side.d == D::south ? 1 : 0) +
                              (side.d == D::east || side.d == D::west ? 1 : 0);
      bool midpoint_seen = false;
      for (std::size_t h = 0; h < 2; ++h) {
        const geo::TileId& child = kids[side.along[h]];
        if (present[side.along[h]]) continue;
        const auto id = level_.present(child.z, std::int64_t{child.x} + side.dx,
                                       std::int64_t{child.y} + side.dy);
        if (!id) continue;
        auto t = level_.tile(*id);
        if (!t) return t.error();
        out.sides[di][h] = (**t).*side.facing;
        // Where both children along the side are absent, the midpoint from the first tile
        // across that has it, as the parent across takes it from its children (which all flag
        // it alike).
        if (present[side.along[0]] || present[side.along[1]] || midpoint_seen) continue;
        midpoint_seen = true;
        const auto k = static_cast<std::size_t>((gx - id->x) + 2 * (gy - id->y));
        if (!(*t)->corner_nodata[k]) out.midpoints[di] = (*t)->corners[k];
      }
    }
    return out;
  }

 private:
  LevelTiles& level_;
};

// Pass 4 for one layer: the state the levels share, and one method per step. Runs on the calling
// thread (it alone reads and writes the sink); the jobs it makes run on the pool.
class PyramidBuilder {
 public:
  PyramidBuilder(TileSink& sink, std::uint32_t finest_level, std::uint32_t min_level,
                 const PyramidOptions& options, unsigned threads, const ProgressSink& progress)
      : sink_(sink),
        finest_(finest_level),
        min_(min_level),
        options_(options),
        threads_(std::max(threads, 1u)),
        max_in_flight_(options.max_in_flight ? options.max_in_flight : 2 * threads_ + 2),
        max_sources_(std::size_t{1} << (2 * std::clamp<std::uint32_t>(options.source_depth, 1, 8))),
        progress_(progress),
        side_(options.scratch),
        cache_(options.decoded_cache_bytes) {
    summary_.level_max_error.assign(finest_ + 1, 0.0);
    summary_.level_tiles.assign(finest_ + 1, 0);
    summary_.level_vertices.assign(finest_ + 1, 0);
  }

  Result<PyramidSummary> run() {
    if (Status s = pool_.start(threads_); !s) return s.error();
    auto finest_ids = sink_.tile_ids(finest_);
    if (!finest_ids.ok()) return finest_ids.error();
    if (options_.reduce_finest) {
      if (Status s = reduce_finest_level(*finest_ids); !s) return s.error();
    }
    if (finest_ == min_) {  // no parent: the finest level is the whole pyramid
      for (const auto& id : *finest_ids) {
        auto t = sink_.get(id);
        if (!t.ok()) return t.error();
        if (*t) account(**t);
      }
      return summary_;
    }
    if (Status s = index_levels(*finest_ids); !s) return s.error();
    for (std::uint32_t z = finest_; z-- > min_;) {
      if (Status s = build_level(z); !s) return s.error();
    }
    if (Status s = report(true); !s.ok()) return s.error();
    return summary_;
  }

 private:
  using Level = std::vector<std::pair<std::uint64_t, geo::TileId>>;  // (Morton code, id), sorted

  void account(const EncodedTile& t) {
    const std::uint32_t z = t.id().z;
    summary_.level_max_error[z] = std::max(summary_.level_max_error[z], t.geometric_error());
    ++summary_.level_tiles[z];
    summary_.level_vertices[z] += t.vertex_count();
  }

  Status report(bool force) {
    if (!progress_ || (!force && !throttle_.due())) return {};
    if (!progress_(Progress{"lod", done_, total_, "tiles"}))
      return Error(ErrorCode::cancelled, "lod: cancelled");
    return {};
  }

  // Runs `load` for every item on the calling thread, the job it returns on the pool, and `store`
  // on the calling thread, with at most max_in_flight items between load and store.
  Status run_level(const std::vector<geo::TileId>& items,
                   const std::function<Result<TilePool::Job>(const geo::TileId&)>& load,
                   const std::function<Status(Built&&)>& store) {
    std::size_t next = 0, in_flight = 0;
    std::optional<Error> failure;
    while ((next < items.size() && !failure) || in_flight > 0) {
      while (!failure && in_flight < max_in_flight_ && next < items.size()) {
        auto job = load(items[next++]);
        if (!job.ok()) {
          failure = job.error();
          break;
        }
        pool_.submit(std::move(*job));
        ++in_flight;
      }
      if (in_flight == 0) break;
      for (auto& r : pool_.wait_results()) {
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
        ++done_;
        if (Status s = report(false); !s.ok()) failure = s.error();
      }
    }
    if (failure) return *failure;
    return sink_.flush();
  }

  // Stores a built tile and its side record.
  Status put(Built&& b) {
    const geo::TileId id = b.stored->id();
    if (Status s = side_.put(id, std::move(b.side)); !s.ok()) return s;
    return sink_.put(std::move(b.stored));
  }

  Result<std::optional<ReadTile>> read(const geo::TileId& id) {
    auto t = sink_.get(id);
    if (!t.ok()) return t.error();
    if (!*t) return std::optional<ReadTile>{};
    auto record = side_.get(id);
    if (!record.ok()) return record.error();
    return std::optional<ReadTile>{ReadTile{std::move(*t), std::move(*record)}};
  }

  // The optional reduced TIN at the finest level (PyramidOptions::reduce_finest).
  Status reduce_finest_level(const std::vector<geo::TileId>& finest_ids) {
    total_ += finest_ids.size();
    const LodOptions lod = options_.lod;
    return run_level(
        finest_ids,
        [&](const geo::TileId& id) -> Result<TilePool::Job> {
          auto t = sink_.get(id);
          if (!t.ok()) return t.error();
          if (!*t) return not_found("lod: finest tile " + id.to_string() + " vanished");
          std::shared_ptr<const EncodedTile> blob = std::move(*t);
          return TilePool::Job([blob, lod, sink = &sink_]() -> Result<Built> {
            auto decoded = decode_child(*sink, *blob);
            if (!decoded) return decoded.error();
            auto reduced = reduce_finest(*decoded, lod);
            if (!reduced) return reduced.error();
            auto stored = sink->encode(reduced->tile);
            if (!stored) return stored.error();
            return Built{std::move(*stored), detail::encode_side(*reduced)};
          });
        },
        [this](Built&& b) { return put(std::move(b)); });
  }

  // Lists every level's tiles (the parents of the level below: each is built or the pyramid
  // fails), in Morton order, the finest tiles' vertex counts (depth_of), and the coarsest level
  // that reads each tile as a child or a source. Every level's ids stay listed and its side
  // records kept, since any coarser level may read it.
  Status index_levels(const std::vector<geo::TileId>& finest_ids) {
    levels_.assign(finest_ + 1, {});
    auto index_level = [&](std::uint32_t z, const std::vector<geo::TileId>& ids) {
      auto& l = levels_[z];
      l.reserve(ids.size());
      for (const auto& id : ids) l.emplace_back(id.morton(), id);
      std::sort(l.begin(), l.end());
    };
    index_level(finest_, finest_ids);
    // (reads each finest tile's row once; its vertex count is in the stored header)
    finest_points_.assign(1, 0);
    finest_points_.reserve(levels_[finest_].size() + 1);
    for (const auto& [m, id] : levels_[finest_]) {
      auto t = sink_.get(id);
      if (!t.ok()) return t.error();
      if (!*t) return not_found("lod: finest tile " + id.to_string() + " vanished");
      finest_points_.push_back(finest_points_.back() + (*t)->vertex_count());
    }
    for (std::uint32_t z = finest_; z-- > min_;) {
      std::set<geo::TileId> parent_set;
      for (const auto& [m, c] : levels_[z + 1]) parent_set.insert(c.parent());
      index_level(z, std::vector<geo::TileId>(parent_set.begin(), parent_set.end()));
    }
    last_reader_.assign(finest_ + 1, {});
    for (std::uint32_t s = min_; s <= finest_; ++s) {
      last_reader_[s].assign(levels_[s].size(), UINT32_MAX);
    }
    for (std::uint32_t z = finest_; z-- > min_;) {
      for (const auto& [m, pid] : levels_[z]) {
        for (const auto& c : pid.children()) {
          if (const auto at = position(c)) last_reader_[z + 1][*at] = z;
        }
        if (const std::uint32_t depth = depth_of(pid, z); depth > 1) {
          const auto [b, e] = under(pid, z + depth);
          for (auto it = b; it != e; ++it) {
            last_reader_[z + depth][static_cast<std::size_t>(it - levels_[z + depth].begin())] = z;
          }
        }
      }
    }
    return {};
  }

  // The tiles of level s under `p` (a contiguous Morton range).
  std::pair<Level::const_iterator, Level::const_iterator> under(const geo::TileId& p,
                                                                std::uint32_t s) const {
    const auto& l = levels_[s];
    const std::uint32_t shift = 2 * (s - p.z);
    const std::uint64_t lo = p.morton() << shift, hi = (p.morton() + 1) << shift;
    const auto b = std::lower_bound(l.begin(), l.end(), std::pair{lo, geo::TileId{}});
    const auto e = std::lower_bound(b, l.end(), std::pair{hi, geo::TileId{}});
    return {b, e};
  }

  // The depth of the sources of a parent at level z (1: its children). A parent is thinned from
  // its sources: its finest tiles where they hold at most as many vertices as 4^source_depth full
  // tiles (max_sources × max_points, and number at most 4 × max_sources), else its tiles at the
  // deepest level where they number at most 4^source_depth. The first rule keeps the memory
  // bound (points, not tiles, take the memory) and takes the finest tiles where the data's edge
  // leaves them partly empty: a chain against them is exact (bench/lod/RESULTS.md, 18:30).
  std::uint32_t depth_of(const geo::TileId& pid, std::uint32_t z) const {
    for (std::uint32_t sl = finest_; sl > z + 1; --sl) {
      const auto [b, e] = under(pid, sl);
      const auto count = static_cast<std::size_t>(e - b);
      if (count <= max_sources_) return sl - z;
      if (sl == finest_ && count <= 4 * max_sources_) {
        const auto first = static_cast<std::size_t>(b - levels_[sl].begin());
        const std::uint64_t points = finest_points_[first + count] - finest_points_[first];
        if (points <= std::uint64_t{max_sources_} * options_.lod.max_points) return sl - z;
      }
    }
    return 1;
  }

  // The position of a listed tile in its level.
  std::optional<std::size_t> position(const geo::TileId& id) const {
    const auto& l = levels_[id.z];
    const auto it = std::lower_bound(l.begin(), l.end(), std::pair{id.morton(), geo::TileId{}});
    if (it == l.end() || it->second != id) return std::nullopt;
    return static_cast<std::size_t>(it - l.begin());
  }

  // The coarsest level that reads `id` (UINT32_MAX: none).
  std::uint32_t last_read(const geo::TileId& id) const {
    const auto at = position(id);
    return at ? last_reader_[id.z][*at] : UINT32_MAX;
  }

  // Builds and stores every parent of level z.
  Status build_level(std::uint32_t z) {
    std::vector<geo::TileId> parents;
    parents.reserve(levels_[z].size());
    for (const auto& [m, id] : levels_[z]) parents.push_back(id);
    // No level from here on reads these again.
    cache_.drop([&](const geo::TileId& id) { return last_read(id) > z; });
    total_ += parents.size();
    if (Status s = report(true); !s.ok()) return s;
    std::set<geo::TileId> child_set;
    for (const auto& [m, id] : levels_[z + 1]) child_set.insert(id);
    LevelTiles child_tiles(sink_, child_set);
    AbsentCorners absent(child_tiles);
    AbsentSides across(child_tiles);
    std::uint64_t written = 0;
    Status s = run_level(
        parents, [&](const geo::TileId& pid) { return parent_job(pid, z, absent, across); },
        [&](Built&& b) -> Status {
          account(*b.stored);
          if (Status st = put(std::move(b)); !st.ok()) return st;
          ++written;
          return {};
        });
    if (!s.ok()) return s;
    summary_.tiles_built += written;
    return {};
  }

  // A tile a parent's job needs: from the cache when it is there, else as read from the sink
  // (nothing when the sink has no such tile).
  Result<std::optional<NeededTile>> need(const geo::TileId& id, std::uint32_t z) {
    const bool again = last_read(id) < z;
    if (auto hit = cache_.find(id)) return std::optional<NeededTile>{NeededTile{hit, {}, again}};
    auto t = read(id);
    if (!t.ok()) return t.error();
    if (!*t) return std::optional<NeededTile>{};
    return std::optional<NeededTile>{NeededTile{nullptr, std::move(**t), again}};
  }

  // Gathers what the parent `pid` (level z) needs — its children (or, where one is absent, that
  // corner's height and flag and the border across it) and its sources — and returns the job
  // that builds it.
  Result<TilePool::Job> parent_job(const geo::TileId& pid, std::uint32_t z, AbsentCorners& absent,
                                   AbsentSides& across) {
    auto kids = std::make_shared<std::array<std::optional<NeededTile>, 4>>();
    std::array<AbsentCorner, 4> absent_corners;
    const auto ids = pid.children();
    for (std::size_t i = 0; i < 4; ++i) {
      if (z + 1 == finest_) {  // each finest tile accounted once, from the sink
        auto t = read(ids[i]);
        if (!t.ok()) return t.error();
        if (*t) {
          account(*(*t)->stored);
          (*kids)[i] = NeededTile{nullptr, std::move(**t), last_read(ids[i]) < z};
          continue;
        }
      } else {
        auto t = need(ids[i], z);
        if (!t.ok()) return t.error();
        if (*t) {
          (*kids)[i] = std::move(**t);
          continue;
        }
      }
      auto corner = absent.corner(pid, static_cast<int>(i));
      if (!corner) return corner.error();
      absent_corners[i] = *corner;
    }
    std::array<bool, 4> present{};
    for (std::size_t i = 0; i < 4; ++i) present[i] = (*kids)[i].has_value();
    auto border = std::make_shared<AbsentBorder>();
    if (std::count(present.begin(), present.end(), true) < 4) {
      auto b = across.border(pid, present);
      if (!b) return b.error();
      *border = std::move(*b);
    }
    const std::uint32_t depth = depth_of(pid, z);
    // All the data under one child, thinned from the same sources (the same counts give the same
    // source level): its vertices are the candidates, the sources only measure.
    const bool one_child =
        std::count_if(kids->begin(), kids->end(), [](const auto& r) { return r.has_value(); }) == 1;
    auto sources = std::make_shared<std::vector<NeededTile>>();
    if (depth > 1) {
      const auto [b, e] = under(pid, z + depth);
      for (auto it = b; it != e; ++it) {
        auto t = need(it->second, z);
        if (!t.ok()) return t.error();
        if (!*t) return not_found("lod: tile " + it->second.to_string() + " vanished");
        sources->push_back(std::move(**t));
      }
    }
    return TilePool::Job([kids, sources, depth, one_child, pid, lod = options_.lod, absent_corners,
                          border, cache = &cache_, sink = &sink_]() {
      return build_parent(pid, *kids, absent_corners, *border, *sources, depth, one_child, lod,
                          *cache, *sink);
    });
  }

  // A parent's job, on a worker: decodes what it needs (or takes it from the cache), thins the
  // parent from its sources, encodes it for the sink.
  static Result<Built> build_parent(const geo::TileId& pid,
                                    std::array<std::optional<NeededTile>, 4>& kids,
                                    const std::array<AbsentCorner, 4>& absent_corners,
                                    const AbsentBorder& border, std::vector<NeededTile>& sources,
                                    std::uint32_t depth, bool one_child, const LodOptions& lod,
                                    DecodedTiles& cache, const TileSink& sink) {
    ChildViews children;
    children.absent_corners = absent_corners;
    children.absent_border = &border;
    for (std::size_t i = 0; i < 4; ++i) {
      if (!kids[i]) continue;
      auto t = decoded(sink, *kids[i], cache);
      if (!t) return t.error();
      children.tiles[i] = t->get();
    }
    SourceViews src;
    src.depth = depth;
    src.candidates_from_children = one_child && depth > 1;
    src.tiles.reserve(sources.size());
    for (auto& r : sources) {
      auto t = decoded(sink, r, cache);
      if (!t) return t.error();
      src.tiles.push_back(t->get());
    }
    auto parent = build_from_sources(pid, children, src, lod);
    if (!parent) return parent.error();
    auto stored = sink.encode(parent->tile);
    if (!stored) return stored.error();
    return Built{std::move(*stored), detail::encode_side(*parent)};
  }

  TileSink& sink_;
  const std::uint32_t finest_, min_;
  const PyramidOptions& options_;
  const unsigned threads_;
  const std::size_t max_in_flight_;
  const std::size_t max_sources_;
  const ProgressSink& progress_;
  PyramidSummary summary_;
  detail::SideStore side_;
  DecodedTiles cache_;  // before the pool: its jobs use it
  std::uint64_t done_ = 0, total_ = 0;
  Throttle throttle_;
  std::vector<Level> levels_;
  // Prefix sums of the finest tiles' vertex counts, in levels_[finest_]'s order (0 first).
  std::vector<std::uint64_t> finest_points_;
  std::vector<std::vector<std::uint32_t>> last_reader_;
  TilePool pool_;  // last: its workers are joined before the rest goes
};

}  // namespace

Result<PyramidSummary> build_pyramid(TileSink& sink, std::uint32_t finest_level,
                                     std::uint32_t min_level, const PyramidOptions& options,
                                     unsigned threads, const ProgressSink& progress) {
  if (finest_level > static_cast<std::uint32_t>(geo::kMaxLevel) || min_level > finest_level) {
    return invalid_argument("lod: levels must satisfy min_level ≤ finest_level ≤ 30, got " +
                            std::to_string(min_level) + " and " + std::to_string(finest_level));
  }
  if (options.lod.max_points < 4) return invalid_argument("lod: max_points must be at least 4");
  PyramidBuilder builder(sink, finest_level, min_level, options, threads, progress);
  return builder.run();
}

}  // namespace tinstream::lod
