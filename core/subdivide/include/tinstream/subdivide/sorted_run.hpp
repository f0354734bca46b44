// tinstream/subdivide/sorted_run.hpp — pass 2 of the ingest (docs/DESIGN.md §3.2): choose the
// finest level and put every point into Morton (quadkey) order, with bounded memory.
//
// Input: any stream of points in normalised Mercator (x, y ∈ [-1, 1]) with ellipsoidal heights.
// Output: ONE sorted run file of fixed 40-byte records (SortedPoint, key included) plus an
// in-memory tile index (first record and count of every non-empty finest tile, in Morton order) —
// not one file per tile. The temporary runs hold 32 bytes per record (kSpillRecordBytes).
//
// Order: records are sorted by (key, x, y) where key is the Morton code of the level-30 cell that
// holds the point (geo::TileId::containing). Level-30 cells nest exactly inside every coarser
// tile, so every tile of every level is one contiguous range of the run, and points inside a tile
// come in Z-order (a good insertion order for the triangulation).
//
// Duplicates: points with identical (x, y) are merged into one; the LOWEST z wins (it is the one
// closest to bare earth; the rule is independent of input order; on equal z the higher weight).
// They are counted.
//
// Finest level L: the smallest level at which no tile holds more than max_points points (after
// merging duplicates), but at least extent_level() of the points' bounding box (so that the data
// spans at most 2 × 2 tiles there: a small dataset is not stored in a world-sized tile, whose
// quantised encodings — quantized-mesh's 15-bit positions, 1.2 km steps at level 0 — would merge
// its points; a 9,003-point LiDAR crop came out as one level-0 tile that CesiumJS read as 5
// positions and 4 triangles); capped by max_level; never below min_level.
//
// Memory: at most about `memory_bytes` (sort buffers + merge buffers), whatever the input size;
// temporary runs go to `tmp_dir` and are removed when done or on failure.
// Threads: subdivide() and a SortedRunBuilder run on the calling thread plus one spill thread
// (sorts and writes a full chunk while the next one fills) and, while merging, a writer thread
// (writes one output buffer while the merge fills the other); with merge_threads = 2 the final
// merge's upper key range is merged on a second thread (with its own writer thread).
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/geo/tile_id.hpp"

namespace tinstream::subdivide {

// One record of the sorted run, as in the file: 40 bytes, host (little-endian) order. The
// temporary runs (spills, merge passes) store kSpillRecordBytes per record: f64 x, f64 y, f64 z,
// f32 weight, u32 reserved, without the key, which is cell_key(x, y), recomputed once per record
// the merge reads (pass 3 reads the sorted run many times over: it keeps its keys).
struct SortedPoint {
  std::uint64_t key = 0;  // Morton code of the level-30 cell
  double x = 0, y = 0;    // normalised Mercator
  double z = 0;           // metres, ellipsoidal
  float weight = 0;       // importance for thinning (the input's weight)
  std::uint32_t reserved = 0;
};
static_assert(sizeof(SortedPoint) == 40);
inline constexpr std::size_t kSpillRecordBytes = 32;

// Morton code of column x and row y within one level: x bits at even positions, y bits at odd
// ones (as quadkey digits 2·ybit + xbit).
std::uint64_t morton_interleave(std::uint32_t x, std::uint32_t y);
// The level-30 cell key of a point (x, y clamped to the map).
std::uint64_t cell_key(double x, double y);
// The tile at `level` containing the level-30 cell `key`.
geo::TileId tile_of_key(std::uint64_t key, std::uint32_t level);
// The deepest level (≤ 30) whose tiles are at least max(width, height) wide (normalised Mercator:
// level l's tiles are 2 / 2^l wide), so a box of that size meets at most 2 × 2 of its tiles;
// 0 for an empty box (one position gives no scale).
std::uint32_t extent_level(double width, double height);

struct TileRange {
  geo::TileId id;
  std::uint64_t first = 0;  // index of the first record in the run
  std::uint64_t count = 0;
};

struct SubdivideOptions {
  std::uint32_t max_points = 16384;       // per finest tile (≤ 65535)
  std::uint32_t max_level = 24;           // cap for L
  std::uint32_t min_level = 0;            // floor for L
  std::size_t memory_bytes = 256u << 20;  // sort + merge buffers
  std::filesystem::path tmp_dir = std::filesystem::temp_directory_path();
  // The sorted run; default: a file in tmp_dir. A file already there is written over in place
  // and cut to size (its page-cache pages are reused instead of new ones allocated).
  std::filesystem::path output;
  // Entries the tile index may take while the final merge tallies it (0: from memory_bytes);
  // beyond that it is built by re-reading the sorted run. The result is the same either way.
  std::size_t index_entries = 0;
  // 2: the final merge runs on two threads, each merging the records on one side of a key into
  // its own part of the output (same result as 1, the single-threaded merge).
  unsigned merge_threads = 2;
};

struct SortedRun {
  std::filesystem::path path;
  std::uint64_t points = 0;                    // records in the run (distinct points)
  std::uint64_t input_points = 0;              // points given
  std::uint64_t duplicates_merged = 0;         // input_points − points
  std::uint32_t finest_level = 0;              // L
  std::vector<TileRange> tiles;                // non-empty tiles of level L, Morton order
  std::vector<std::uint64_t> max_tile_points;  // index z: most points in one tile of level z
};

// Supplies input in batches: appends points (x, y, z) to `batch` and returns how many it appended;
// 0 means the input is exhausted.
struct InputPoint {
  double x = 0, y = 0, z = 0;
  float weight = 0;
};
using PointFeed = std::function<Result<std::size_t>(std::vector<InputPoint>& batch)>;

// Requires: options.max_points ≥ 1, min_level ≤ max_level ≤ 30.
Result<SortedRun> subdivide(const PointFeed& feed, const SubdivideOptions& options,
                            const ProgressSink& progress = {});

// The same pass in push form, for a caller that produces the points itself (the ingest hands
// pass 1's batches over as they are transformed): add() every point in order, then finish().
// The result is identical to subdivide() over the same points. Destroying a builder without a
// successful finish() removes its temporary runs. Thread-compatible: one thread calls it.
class SortedRunBuilder {
 public:
  static Result<SortedRunBuilder> create(const SubdivideOptions& options);
  SortedRunBuilder(SortedRunBuilder&&) noexcept;
  SortedRunBuilder& operator=(SortedRunBuilder&&) noexcept;
  ~SortedRunBuilder();

  // Errors: a point that is not a finite normalised-Mercator position (named by its index among
  // all points added), or a failed spill. After an error the builder is only fit to destroy.
  Status add(std::span<const InputPoint> points);
  std::uint64_t input_points() const;
  // Merges the runs; progress phase "merge" (returning false cancels).
  Result<SortedRun> finish(const ProgressSink& progress = {});

 private:
  struct State;
  explicit SortedRunBuilder(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Random access to a sorted run by record index. Thread-compatible: one reader per thread.
class SortedRunReader {
 public:
  static Result<SortedRunReader> open(const std::filesystem::path& path);
  SortedRunReader(SortedRunReader&&) noexcept;
  SortedRunReader& operator=(SortedRunReader&&) noexcept;
  ~SortedRunReader();

  std::uint64_t size() const { return records_; }
  // Replaces `out` with records [first, first + count). Errors on I/O failure or range overflow.
  Status read(std::uint64_t first, std::uint64_t count, std::vector<SortedPoint>& out);

 private:
  SortedRunReader() = default;
  std::FILE* file_ = nullptr;
  std::uint64_t records_ = 0;
  std::filesystem::path path_;
};

}  // namespace tinstream::subdivide
