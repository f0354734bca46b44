// tinstream/lod/pyramid.hpp — pass 4 driver: levels L-1 … min_level from the finest level L.
//
// For z = L-1 down to min_level, every parent of an existing level z+1 tile is built from its
// four children (build_parent) and written to the same unpublished layer version. The summary's
// per-level max errors are what store::LayerInfo::level_max_error wants.
//
// What a level hands to the next beside its tiles (lod_tile.hpp: per-triangle error bounds,
// witnesses) is kept in a side file under PyramidOptions::scratch (in memory when empty), never
// in the store. A parent whose child k is absent gets its NODATA corner k's height by the rule of
// docs/tile-format.md §2.1: from a tile of the children's level around that corner, else from
// the nearest data vertex of that level (searched in rings of tiles around the corner).
//
// Threads: the LayerWriter is used only on the calling thread (reads of children, writes of
// parents); build_parent runs on `threads` workers. At most `max_in_flight` parents (and their
// children) are in memory at once, so memory is bounded by options, not by the layer's size.
// The progress sink is called on the calling thread (phase "lod", unit "tiles"); returning false
// cancels (ErrorCode::cancelled).
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/lod/parent.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::lod {

struct PyramidOptions {
  LodOptions lod;                 // for every parent
  std::size_t max_in_flight = 0;  // parents in memory at once; 0 = 2 × threads + 2
  // Thin the finest tiles first (reduce_finest_tile with lod.epsilon / lod.max_points) and
  // rewrite them: the "reduced TIN" for gridded input.
  bool reduce_finest = false;
  // Directory for the side file (bounds and witnesses between levels); empty: kept in memory.
  std::filesystem::path scratch;
};

struct PyramidSummary {
  // Index z = level, for 0 … finest_level (levels below min_level stay 0).
  std::vector<double> level_max_error;
  std::vector<std::uint64_t> level_tiles;
  std::vector<std::uint64_t> level_vertices;
  std::uint64_t tiles_built = 0;  // parents written (reduced finest tiles not counted)
};

// Requires: min_level ≤ finest_level ≤ geo::kMaxLevel, threads ≥ 1 (0 is taken as 1).
Result<PyramidSummary> build_pyramid(store::LayerWriter& writer, std::uint32_t finest_level,
                                     std::uint32_t min_level, const PyramidOptions& options,
                                     unsigned threads, const ProgressSink& progress = {});

}  // namespace tinstream::lod
