// tinstream/ingest/verify.hpp — `tinstream verify`: checks a published layer tile by tile.
//
// Checks (DESIGN.md §8): every tile decodes and passes tile::check_structure (exact
// orientation, border geometry); every tile is Delaunay across each interior edge (exact
// incircle; the tile border is the only constraint); same-level neighbours share bit-identical
// borders (watertight); every tile above the finest level has all its present children's data
// covered (its children exist only under it) and a geometric error ≥ each child's (monotone);
// the per-tile point budget holds above the finest level; the finest level's tiles account for
// every distinct input point (Σ source points = the layer's point count, and each tile holds at
// least as many interior vertices as... see verify.cpp).
// Threads: call from one thread; it owns its TileStore reads.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::ingest {

struct VerifyOptions {
  bool delaunay = true;           // the O(triangles) empty-circle check
  std::size_t max_problems = 50;  // stop listing after this many (counting goes on)
};

struct VerifyReport {
  std::uint64_t tiles = 0;
  std::uint64_t triangles = 0;
  std::uint64_t shared_borders = 0;  // neighbour pairs compared
  std::uint64_t problems = 0;
  std::vector<std::string> messages;  // the first max_problems problems, each naming the tile
  bool ok() const { return problems == 0; }
};

Result<VerifyReport> verify_layer(store::TileStore& store, const std::string& layer,
                                  const VerifyOptions& options = {},
                                  const ProgressSink& progress = {});

}  // namespace tinstream::ingest
