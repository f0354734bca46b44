// tinstream/lod/pyramid.hpp — pass 4 driver: levels L-1 … min_level from the finest level L.
//
// For z = L-1 down to min_level, every parent of an existing level z+1 tile is built from its
// children and its sources (build_from_sources) and written to the same unpublished layer
// version. Its sources are its tiles at the finest level s > z where it has at most
// 4^source_depth tiles (its children when no deeper level qualifies) — or its finest tiles
// where they hold at most as many vertices as 4^source_depth full tiles (max_points each) and
// number at most 4 × 4^source_depth (mostly empty tiles along the data's edge): the finest tiles
// themselves for the three levels above the finest, and wherever the data under a parent fit
// that many finest tiles (above the level where the data fit one tile, every level measures
// against the same finest tiles, and a parent with one child takes that child's vertices as its
// candidates rather than thinning them again: Sources::candidates_from_children). Thinning from
// a finer surface than the children's keeps the coarse
// levels closer to greedy insertion from the data, and the chained error bound (error.hpp) runs
// through about (L − z) / source_depth steps instead of L − z, so it stays close to the measured
// error (bench/lod/RESULTS.md). The parent records at least its children's error. The summary's
// per-level max errors are what store::LayerInfo::level_max_error wants.
//
// What a level hands to the coarser ones beside its tiles (lod_tile.hpp: per-triangle error
// bounds, witnesses) is kept in a side file per level under PyramidOptions::scratch (in memory
// when empty), never in the sink, until the pyramid is built (any coarser level may read it).
// A parent whose child k is absent gets its NODATA corner k's height by the rule of
// docs/tile-format.md §2.1: from a tile of the children's level around that corner, else from
// the nearest data vertex of that level (searched in rings of tiles around the corner).
//
// Tiles: read from and written to `sink` (tile_sink.hpp; the ingest's is the store's unpublished
// layer version, ingest/layer_sink.hpp), which starts with the finest level's tiles.
// Threads: the sink is read and written only on the calling thread (reads of children and
// sources, writes of parents); build_from_sources and the sink's codec run on `threads` workers. At
// most `max_in_flight` parents (and their children and sources, at most 4 + 4^source_depth tiles of
// at most max_points each) are in memory at once, so memory is bounded by options, not by the
// layer's size; the tile ids of every level are listed in memory (16 bytes + 16 per tile). The
// largest term is a worker thinning a parent from all of its sources: about 200 bytes per source
// point (≈ 200 MB at 64 sources of 16384 points; bench/lod/RESULTS.md, 2026-11-27 14:35). Beside
// them, decoded tiles that a coarser level reads again (as a source) are kept, shared by the
// workers, up to PyramidOptions::decoded_cache_bytes: the levels above the one where the data fit
// 4^source_depth tiles read the same tiles level after level. Levels whose tiles outnumber the
// budget decode again what did not fit (a level reads all of its sources before the next one
// starts). The tiles stored are the same with or without the cache.
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
#include "tinstream/lod/tile_sink.hpp"

namespace tinstream::lod {

struct PyramidOptions {
  LodOptions lod;                 // for every parent
  std::size_t max_in_flight = 0;  // parents in memory at once; 0 = 2 × threads + 2
  // Thin the finest tiles first (reduce_finest_tile with lod.epsilon / lod.max_points) and
  // rewrite them: the "reduced TIN" for gridded input.
  bool reduce_finest = false;
  // A parent's sources are its tiles at the finest level where they number at most
  // 4^source_depth (at least its children); 1 … 8. Memory per parent in flight grows as
  // 4^source_depth × max_points.
  std::uint32_t source_depth = 3;
  // Decoded tiles that coarser levels read again are kept up to this many bytes (estimated from
  // their vectors) so that they are decoded once; 0: every read decodes. Output is the same.
  std::size_t decoded_cache_bytes = std::size_t{64} << 20;
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
Result<PyramidSummary> build_pyramid(TileSink& sink, std::uint32_t finest_level,
                                     std::uint32_t min_level, const PyramidOptions& options,
                                     unsigned threads, const ProgressSink& progress = {});

}  // namespace tinstream::lod
