#include "tinstream/ingest/ingest.hpp"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "tinstream/ingest/layer_sink.hpp"
#include "tinstream/lod/pyramid.hpp"
#include "tinstream/store/queued_writer.hpp"
#include "tinstream/subdivide/sorted_run.hpp"
#include "tinstream/transform/pass1.hpp"
#include "tinstream/triangulate/finest_tiles.hpp"

namespace tinstream::ingest {
namespace {

namespace fs = std::filesystem;

// glibc raises its mmap threshold each time a large block is freed (up to 32 MB), after which the
// per-tile buffers of the worker threads (a few hundred kB to a few MB each) come from the arenas
// and stay there when freed: over a long pyramid build the resident set crept up with the input
// size (3e7 points: 198 MB peak vs 175 MB at 1e7). A fixed threshold keeps them in mmap, returned
// to the system on free (3e7: 181 MB; bench/ingest/RESULTS.md). Process-wide, once.
void bound_heap_retention() {
#if defined(__GLIBC__)
  static std::once_flag once;
  std::call_once(once, [] { mallopt(M_MMAP_THRESHOLD, 1 << 20); });
#endif
}

// A private temporary directory, removed with everything in it when the ingest ends. While the
// ingest runs it holds an exclusive flock on `.lock` inside; the next ingest with the same
// temporary parent removes directories whose lock nobody holds any more (left by an ingest that
// was killed or crashed — SIGINT and SIGTERM cancel cleanly — which can hold gigabytes of runs).
class ScratchDir {
 public:
  static constexpr const char* kPrefix = "tinstream-ingest-";
  static Result<ScratchDir> create(const fs::path& parent, const std::string& layer) {
    std::error_code ec;
    const fs::path base = parent.empty() ? fs::temp_directory_path(ec) : parent;
    if (ec) return io_error("no temporary directory: " + ec.message());
    remove_abandoned(base);
    // Built under a name no cleaner looks at, locked, then renamed: a directory under the final
    // name is always locked while its ingest lives (the lock belongs to the open file, which the
    // rename keeps).
    const std::string unique =
        layer + "-" + std::to_string(::getpid()) + "-" +
        std::to_string(std::chrono::steady_clock::now().time_since_epoch().count());
    const fs::path making = base / (".making-" + std::string(kPrefix) + unique);
    fs::create_directories(making, ec);
    if (ec) {
      return io_error("cannot create temporary directory " + making.string() + ": " + ec.message());
    }
    ScratchDir d;
    d.path_ = making;
    d.lock_ = ::open((making / ".lock").c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (d.lock_ < 0 || ::flock(d.lock_, LOCK_EX | LOCK_NB) != 0) {
      return io_error("cannot lock temporary directory " + making.string() + ": " +
                      std::strerror(errno));
    }
    const fs::path final_path = base / (kPrefix + unique);
    fs::rename(making, final_path, ec);
    if (ec) {
      return io_error("cannot create temporary directory " + final_path.string() + ": " +
                      ec.message());
    }
    d.path_ = final_path;
    return d;
  }
  ScratchDir(ScratchDir&& o) noexcept
      : path_(std::exchange(o.path_, {})), lock_(std::exchange(o.lock_, -1)) {}
  ScratchDir& operator=(ScratchDir&&) = delete;
  ~ScratchDir() {
    if (!path_.empty()) {
      std::error_code ec;
      fs::remove_all(path_, ec);
    }
    if (lock_ >= 0) ::close(lock_);
  }
  const fs::path& path() const { return path_; }

  // Removes scratch directories under `base` whose lock is free (their ingest is gone).
  static void remove_abandoned(const fs::path& base) {
    std::error_code ec;
    for (fs::directory_iterator it(base, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (name.rfind(kPrefix, 0) != 0 || !it->is_directory(ec)) continue;
      const int fd = ::open((it->path() / ".lock").c_str(), O_RDWR | O_CLOEXEC);
      if (fd < 0) continue;  // not ours (or from a version without locks): left alone
      if (::flock(fd, LOCK_EX | LOCK_NB) == 0) fs::remove_all(it->path(), ec);
      ::close(fd);
      ec.clear();
    }
  }

 private:
  ScratchDir() = default;
  fs::path path_;
  int lock_ = -1;
};

Status cancelled(const std::string& where) {
  return Error(ErrorCode::cancelled, "ingest cancelled during " + where);
}

nlohmann::json options_json(const IngestOptions& o) {
  nlohmann::json inputs = nlohmann::json::array();
  for (const auto& in : o.inputs) {
    nlohmann::json j{{"path", in.path.string()},
                     {"crs", in.reproject.crs},
                     {"vertical_datum", in.reproject.vertical_datum},
                     {"weight", in.weight}};
    if (in.reproject.z_unit) j["z_unit"] = in.reproject.z_unit->name;
    if (in.source.class_filter.classes) j["classes"] = *in.source.class_filter.classes;
    inputs.push_back(std::move(j));
  }
  return {{"inputs", inputs},           {"projection", std::string(geo::to_string(o.projection))},
          {"max_points", o.max_points}, {"max_level", o.max_level},
          {"min_level", o.min_level},   {"epsilon", o.epsilon},
          {"pyramid", o.pyramid}};
}

}  // namespace

std::uint64_t peak_rss_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024u;  // Linux reports KiB
}

namespace {

double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto sec = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  return sec(usage.ru_utime) + sec(usage.ru_stime);
}

// Closes the running phase (if any) and opens the next one.
class PhaseClock {
 public:
  explicit PhaseClock(std::vector<PhaseTime>& out) : out_(out) {}
  void next(std::string name) {
    const auto now = std::chrono::steady_clock::now();
    const double cpu = process_cpu_seconds();
    if (!out_.empty()) {
      out_.back().seconds = std::chrono::duration<double>(now - wall_).count();
      out_.back().cpu_seconds = cpu - cpu_;
    }
    if (!name.empty()) out_.push_back({std::move(name), 0, 0});
    wall_ = now, cpu_ = cpu;
  }
  void stop() { next({}); }

 private:
  std::vector<PhaseTime>& out_;
  std::chrono::steady_clock::time_point wall_{};
  double cpu_ = 0;
};

// ── The ingest, one step per pass. Each step fills its part of the summary; `run_ingest` only
// strings them together and times them. ──

Status check_options(const IngestOptions& options) {
  if (Status s = store::validate_layer_name(options.layer); !s) return s;
  if (options.inputs.empty()) return invalid_argument("no input files given");
  if (options.max_points < 3 || options.max_points > 65535) {
    return invalid_argument("max_points " + std::to_string(options.max_points) +
                            " outside [3, 65535]");
  }
  if (options.max_level > 30 || options.min_level > options.max_level) {
    return invalid_argument("levels: need min_level ≤ max_level ≤ 30 (got " +
                            std::to_string(options.min_level) + ", " +
                            std::to_string(options.max_level) + ")");
  }
  if (!(options.epsilon >= 0.0)) return invalid_argument("epsilon must be ≥ 0 metres");
  return {};
}

// What passes 1 and 2 leave: pass 1's header (count, boxes, z range) and per-input summaries, and
// pass 2's sorted run (a file in the scratch directory) with its tile index.
struct SortedPoints {
  transform::RunSummary pass1;
  subdivide::SortedRun sorted;
};

// Pass 2's share of `memory_bytes`: pass 1's batches in flight (threads + 1 of them, each point
// as read, reprojected, in the run record's form, with its lon/lat and as handed over) live
// beside pass 2's sort buffers, so they come out of the same budget. (The batch size stays pass
// 1's default: it decides whether a read error or an earlier bad record of the same batch is
// reported.)
std::size_t sort_memory(std::size_t memory_bytes, unsigned threads) {
  const std::size_t in_flight =
      (threads + 1) * transform::TransformOptions{}.batch_size *
      (sizeof(sources::SourcePoint) + sizeof(transform::GeoPoint) + sizeof(transform::RunPoint) +
       sizeof(geo::LonLat) + sizeof(subdivide::InputPoint));
  return memory_bytes > 2 * in_flight ? memory_bytes - in_flight : memory_bytes / 2;
}

// Passes 1 and 2, which overlap: pass 1 reads and transforms the inputs and hands every batch to
// pass 2's builder, whose spill thread sorts and writes chunks (the run files of the transformed
// points) while pass 1 goes on; pass 1 itself writes no run file, only its header is kept. When
// pass 1 is done (phase "sort" begins), the chunks are merged into one Morton-sorted run in
// `scratch`, duplicates merged, the finest level chosen and the tile index tallied.
// Fills the summary's input counts, duplicates, points and finest level.
// Errors: a bad input (named by file and record), inputs without a usable point, a failed spill
// or merge, cancellation.
Result<SortedPoints> transform_and_sort(const IngestOptions& options, unsigned threads,
                                        const fs::path& scratch, PhaseClock& clock,
                                        IngestSummary& summary, const ProgressSink& progress) {
  subdivide::SubdivideOptions sopt;
  sopt.max_points = options.max_points;
  sopt.max_level = options.max_level;
  sopt.min_level = options.min_level;
  sopt.memory_bytes = sort_memory(options.memory_bytes, threads);
  sopt.merge_threads = threads >= 2 ? 2 : 1;  // --threads 1: one thread throughout
  sopt.tmp_dir = scratch;
  sopt.output = scratch / "sorted.run";
  auto builder = subdivide::SortedRunBuilder::create(sopt);
  if (!builder) return builder.error();
  std::vector<subdivide::InputPoint> handed;
  transform::TransformOptions topt;
  topt.projection = options.projection;
  topt.threads = threads;
  topt.on_points = [&](std::span<const transform::RunPoint> points) -> Status {
    handed.clear();
    for (const auto& p : points) handed.push_back({p.x, p.y, p.z, p.weight});
    return builder->add(handed);
  };
  auto pass1 = transform::transform_sources(options.inputs, topt, progress);
  if (!pass1) return pass1.error();
  summary.inputs = pass1->inputs;
  for (const auto& in : pass1->inputs) {
    summary.records_read += in.counters.records_read;
    summary.points_accepted += in.points_written;
  }
  summary.points_rejected = summary.records_read - summary.points_accepted;
  if (pass1->header.point_count == 0) {
    return invalid_argument(
        "the inputs hold no usable points (" + std::to_string(summary.records_read) +
        " records read, all rejected by the class filter, NODATA or as invalid)");
  }

  clock.next("sort");
  const std::uint64_t handed_points = builder->input_points();
  if (progress && !progress({"sort", handed_points, handed_points, "points"})) {
    return cancelled("sort").error();
  }
  auto sorted = builder->finish(progress);
  if (!sorted) return sorted.error();
  summary.duplicates_merged = sorted->duplicates_merged;
  summary.points = sorted->points;
  summary.finest_level = sorted->finest_level;
  return SortedPoints{std::move(*pass1), std::move(*sorted)};
}

// The layer's record as far as it is known before pass 3: bounds, heights, levels, counts and the
// options (tile count and per-level errors are filled in by the later passes).
store::LayerInfo layer_info(const IngestOptions& options, const SortedPoints& in,
                            std::uint64_t points_accepted) {
  store::LayerInfo info;
  info.name = options.layer;
  info.projection = options.projection;
  info.vertical_datum = options.inputs.front().reproject.vertical_datum;
  const auto& h = in.pass1.header;
  info.mercator_bounds = {h.mercator.min_x, h.mercator.min_y, h.mercator.max_x, h.mercator.max_y};
  info.bounds = {h.lonlat.min_x, h.lonlat.min_y, h.lonlat.max_x, h.lonlat.max_y};
  info.min_z = h.min_z;
  info.max_z = h.max_z;
  const std::uint32_t finest = in.sorted.finest_level;
  info.max_level = finest;
  info.min_level = options.pyramid ? std::min(options.min_level, finest) : finest;
  info.max_points = options.max_points;
  info.point_count = in.sorted.points;
  info.source_points = points_accepted;
  info.options_json = options_json(options).dump();
  info.attribution = options.attribution;
  return info;
}

// Pass 3: the finest tiles, triangulated on `threads` workers, each encoding and compressing its
// own; a writer thread stores them, so no worker waits while another commits a batch (and its WAL
// checkpoint). Removes the sorted run's file when done (its disk is free for pass 4).
// Fills the summary's finest level entry, tile count and halo overhead.
// Errors: a tile that fails (named), a store error, cancellation.
Status build_finest_level(const subdivide::SortedRun& sorted, store::LayerWriter& writer,
                          unsigned threads, IngestSummary& summary, const ProgressSink& progress) {
  // Room for the writer's stalls (a batch commit, a WAL checkpoint, pages under writeback): with
  // 4 tiles per worker the workers waited on it 11 % of pass 3 (1e7 points); 64 per worker,
  // bounded to 32 MB of compressed tiles, keeps them busy.
  store::QueuedWriter queue(writer, std::size_t{64} * threads, std::size_t{32} << 20);
  auto pass3 = triangulate::build_finest_tiles(
      sorted, threads,
      [&](tile::TinTile&& t) -> Status {
        auto prepared = store::prepare_tile(t);
        if (!prepared) return prepared.error();
        return queue.push(std::move(*prepared));
      },
      {}, progress);
  if (Status s = queue.finish(); pass3 && !s) return s;
  const std::uint64_t finest_tiles = queue.stored();
  if (!pass3) return pass3.error();
  summary.halo_overhead = static_cast<double>(pass3->gathered_points) /
                          static_cast<double>(std::max<std::uint64_t>(sorted.points, 1));
  std::error_code ec;
  fs::remove(sorted.path, ec);
  summary.levels.push_back({sorted.finest_level, finest_tiles, 0.0});
  summary.tiles = finest_tiles;
  return {};
}

// Pass 4: the LOD pyramid, levels finest − 1 … info.min_level built from their children (none
// when the pyramid is off), and the finest tiles of gridded inputs reduced when an epsilon is
// given ("reduced TINs"); what a level hands to the next beside its tiles goes to a file under
// `scratch`. Requires: build_finest_level done (summary.levels holds the finest
// level). Fills info.level_max_error and the summary's levels (sorted, coarsest first), tile
// count and min_level; sets info.min_level to the coarsest level built.
Status build_lod(const IngestOptions& options, const SortedPoints& in, const fs::path& scratch,
                 unsigned threads, store::LayerWriter& writer, store::LayerInfo& info,
                 IngestSummary& summary, const ProgressSink& progress) {
  const std::uint32_t finest = in.sorted.finest_level;
  info.level_max_error.assign(finest + 1, 0.0);
  const bool gridded = std::any_of(
      summary.inputs.begin(), summary.inputs.end(),
      [](const transform::InputSummary& input) { return input.format.rfind("GDAL", 0) == 0; });
  const bool reduce = gridded && options.epsilon > 0.0;
  if ((options.pyramid && info.min_level < finest) || reduce) {
    lod::PyramidOptions popt;
    popt.lod.max_points = options.max_points;
    popt.lod.epsilon = options.epsilon;
    popt.reduce_finest = reduce;
    popt.scratch = scratch;
    const std::uint32_t coarsest = options.pyramid ? info.min_level : finest;
    LayerSink sink(writer);
    auto pyramid = lod::build_pyramid(sink, finest, coarsest, popt, threads, progress);
    if (!pyramid) return pyramid.error();
    for (std::uint32_t z = coarsest; z <= finest; ++z) {
      const double err = z < pyramid->level_max_error.size() ? pyramid->level_max_error[z] : 0.0;
      info.level_max_error[z] = err;
      if (z == finest) {
        summary.levels.front().max_error = err;
        continue;
      }
      const std::uint64_t tiles = z < pyramid->level_tiles.size() ? pyramid->level_tiles[z] : 0;
      summary.levels.push_back({z, tiles, err});
      summary.tiles += tiles;
    }
  }
  std::sort(summary.levels.begin(), summary.levels.end(),
            [](const LevelSummary& a, const LevelSummary& b) { return a.level < b.level; });
  summary.min_level = summary.levels.front().level;
  info.min_level = summary.min_level;
  return {};
}

// Publish: the new layer version becomes visible in one transaction; the summary gets the layer
// as the store now records it.
Status publish(store::TileStore& store, store::LayerWriter& writer, store::LayerInfo& info,
               IngestSummary& summary, const ProgressSink& progress) {
  if (progress && !progress({"publish", 0, 1, "steps"})) return cancelled("publish");
  info.tile_count = summary.tiles;
  if (Status s = writer.publish(info); !s) return s;
  if (progress) progress({"publish", 1, 1, "steps"});
  auto published = store.layer(info.name);
  if (!published) return published.error();
  summary.layer_info = *published;
  return {};
}

}  // namespace

Result<IngestSummary> run_ingest(const IngestOptions& options, const ProgressSink& progress) {
  bound_heap_retention();
  const auto start = std::chrono::steady_clock::now();
  if (Status s = check_options(options); !s) return s.error();
  const unsigned threads =
      options.threads != 0 ? options.threads : std::max(1u, std::thread::hardware_concurrency());

  // Open the store first: a bad store path fails before hours of work.
  auto store = store::TileStore::open(options.store_path, store::TileStore::Mode::read_write);
  if (!store) return store.error();
  auto scratch = ScratchDir::create(options.tmp_dir, options.layer);
  if (!scratch) return scratch.error();

  IngestSummary summary;
  summary.layer = options.layer;
  PhaseClock clock(summary.phases);
  clock.next("transform");
  auto sorted = transform_and_sort(options, threads, scratch->path(), clock, summary, progress);
  if (!sorted) return sorted.error();

  // A new, invisible layer version.
  store::LayerInfo info = layer_info(options, *sorted, summary.points_accepted);
  auto writer = store->begin_layer(info);
  if (!writer) return writer.error();

  clock.next("triangulate");
  if (Status s = build_finest_level(sorted->sorted, **writer, threads, summary, progress); !s) {
    return s.error();
  }
  clock.next("lod");
  if (Status s =
          build_lod(options, *sorted, scratch->path(), threads, **writer, info, summary, progress);
      !s) {
    return s.error();
  }
  clock.next("publish");
  if (Status s = publish(*store, **writer, info, summary, progress); !s) return s.error();
  clock.stop();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summary.peak_rss_bytes = peak_rss_bytes();
  return summary;
}

}  // namespace tinstream::ingest
