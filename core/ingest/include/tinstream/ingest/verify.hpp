// tinstream/ingest/verify.hpp — `tinstream verify`: checks a published layer tile by tile.
//
// Checks (docs/DESIGN.md §6): every tile decodes and passes tile::check_structure (exact
// orientation, border geometry); every tile is Delaunay across each interior edge (exact
// incircle; the tile border is the only constraint); same-level neighbours share bit-identical
// borders (watertight); every tile above the finest level has children under it, a geometric
// error ≥ each child's (monotone), at most the layer's max_points vertices (the budget), and a
// stored geometric error ≥ the error measured against the finest surface by sampling: the
// vertices of up to `error_samples` finest tiles under it (spread evenly over its descendants in
// Morton order) located in it, and its vertices located in them (lod::measured_max_error); the
// with --surface-error (VerifyOptions::surface_error) also a stored error ≥ the exact maximum of
// |tile − finest surface| over those sampled tiles' data triangles (lod::surface_difference: the
// overlay, edge crossings included), less error_rounding_allowance — off by default, since the
// LOD's stored errors bound the finest *data points* (lod/error.hpp), not the surface between
// them; the finest level's tiles account for every distinct input point (Σ source points = the
// layer's point count, and no finest tile holds more interior vertices than source points); no tile
// has, in a spherical layer, a zero-area triangle in its quantized-mesh encoding (what CesiumJS
// would draw), and no two vertices of a tile are closer than 1e-12 (near_duplicate_pairs). Threads:
// call from one thread; it owns its TileStore reads.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::ingest {

struct VerifyOptions {
  bool delaunay = true;  // the O(triangles) empty-circle check
  // Quantised encodings: no two vertices of a tile closer than 1e-12, no zero-area triangle in a
  // tile's quantized-mesh encoding (spherical layers).
  bool quantisation = true;
  // Finest tiles sampled under each coarser tile for the geometric-error check; 0 = no check,
  // SIZE_MAX = all of them (exhaustive: every level then reads the whole finest level).
  std::size_t error_samples = 4;
  // Also check the stored errors against the finest surface between its points (see above).
  bool surface_error = false;
  std::size_t max_problems = 50;  // stop listing after this many (counting goes on)
};

struct VerifyReport {
  std::uint64_t tiles = 0;
  std::uint64_t triangles = 0;
  std::uint64_t shared_borders = 0;  // neighbour pairs compared
  std::uint64_t error_checks = 0;    // coarse tiles whose stored error was checked by sampling
  double worst_error_ratio = 0;      // largest measured / stored geometric error seen (≤ 1 ok)
  // With surface_error: the largest overlay maximum / stored geometric error seen.
  double worst_surface_ratio = 0;
  // Pairs of a tile's vertices closer than 1e-12 (normalised units); each tile with any is a
  // problem (pass 3 moves a data point within 1e-12 of a tile side onto it, so none are made).
  std::uint64_t near_duplicate_pairs = 0;
  std::uint64_t problems = 0;
  std::vector<std::string> messages;  // the first max_problems problems, each naming the tile
  bool ok() const { return problems == 0; }
};

Result<VerifyReport> verify_layer(store::TileStore& store, const std::string& layer,
                                  const VerifyOptions& options = {},
                                  const ProgressSink& progress = {});

}  // namespace tinstream::ingest
