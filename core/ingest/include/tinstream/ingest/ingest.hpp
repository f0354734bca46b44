// tinstream/ingest/ingest.hpp — the whole ingest (docs/DESIGN.md §3): sources → sorted runs of
// transformed points (pass 1) → one Morton-sorted run (pass 2) → finest TIN tiles (pass 3) → LOD
// pyramid (pass 4) → SQLite store, published atomically.
//
// Contract
//  * Memory is bounded by `memory_bytes` and the thread count, never by input size: every pass
//    streams through temporary files in `tmp_dir` (removed at the end, also on failure).
//  * Nothing is visible in the store until the very end: the layer version is written with a
//    LayerWriter and published in one transaction. Any error, cancellation, crash or kill leaves
//    the previously published state (if any) untouched; re-running the ingest is always safe.
//  * Errors name the file and record (pass 1), the tile (pass 3/4) or the store.
//  * Progress is reported through the sink (phases "transform", "sort", "merge", "triangulate",
//    "lod", "publish"); returning false cancels.
// Threads: call from one thread; it runs a worker pool of `threads` internally.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/transform/pass1.hpp"

namespace tinstream::ingest {

struct IngestOptions {
  std::filesystem::path store_path;
  std::string layer;
  std::vector<transform::InputSpec> inputs;
  geo::Projection projection = geo::Projection::spherical;
  std::uint32_t max_points = 16384;  // per tile, ≤ 65535
  std::uint32_t max_level = 24;      // cap for the finest level
  std::uint32_t min_level = 0;       // coarsest level of the pyramid
  double epsilon = 0.0;              // metres: thin further while the error stays below
  bool pyramid = true;               // build the LOD levels (pass 4)
  std::size_t memory_bytes = 256u << 20;
  std::filesystem::path tmp_dir;  // default: the system temporary directory
  unsigned threads = 0;           // 0 = all cores
  std::string attribution;
};

struct LevelSummary {
  std::uint32_t level = 0;
  std::uint64_t tiles = 0;
  double max_error = 0;
};

// Wall-clock and process CPU time (all threads) of one pass.
struct PhaseTime {
  std::string name;  // "transform", "sort", "triangulate", "lod", "publish"
  double seconds = 0;
  double cpu_seconds = 0;
};

struct IngestSummary {
  std::string layer;
  std::uint64_t records_read = 0;     // over all inputs
  std::uint64_t points_accepted = 0;  // after class filter / NODATA / invalid
  std::uint64_t points_rejected = 0;  // records_read − points_accepted
  std::uint64_t duplicates_merged = 0;
  std::uint64_t points = 0;  // distinct points at the finest level
  std::uint32_t finest_level = 0;
  std::uint32_t min_level = 0;
  std::uint64_t tiles = 0;  // all levels
  std::vector<LevelSummary> levels;
  // Points in pass 3's halo triangulations / points: below 1 where tiles start from a band along
  // their border (their own points are triangulated once more for the tile itself).
  double halo_overhead = 0;
  double seconds = 0;
  std::vector<PhaseTime> phases;  // in order; their seconds add up to about `seconds`
  std::uint64_t peak_rss_bytes = 0;
  std::vector<transform::InputSummary> inputs;
  store::LayerInfo layer_info;
};

// Requires: options.inputs not empty, layer name valid, 1 ≤ max_points ≤ 65535.
Result<IngestSummary> run_ingest(const IngestOptions& options, const ProgressSink& progress = {});

// Peak resident set size of this process so far, in bytes.
std::uint64_t peak_rss_bytes();

}  // namespace tinstream::ingest
