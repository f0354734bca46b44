// tinstream/lod/lod_tile.hpp — a tile as pass 4 carries it from one level to the next.
//
// Beside the tile itself, the next coarser level needs what the tile knows about the finest data
// under it that is not one of its vertices (error.hpp, "Chaining"): its witnesses — the finest
// data points where it deviates most, carried exactly, at most LodOptions::witnesses of them —
// and per-triangle bounds of the rest. Neither is published: they only serve the pyramid's
// construction (PyramidOptions::scratch keeps them on disk between levels). The parent takes the
// witnesses as candidates beside its children's vertices, so its thinning sees the full-resolution
// surface where the children left it, not only the children's surviving vertices.
//
// Value type; no invariants enforced (bounds.size() == tile.triangles.size() when not empty).
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include "tinstream/lod/error.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

struct LodTile {
  tile::TinTile tile;
  DeviationBounds bounds;  // residual, one per triangle; empty: none (an unreduced finest tile)
  std::vector<ResidualReach> reaches;  // where the residual points of its NODATA triangles lie
  std::vector<tile::Vertex> witnesses;

  ChainInput as_chain_input() const { return {&tile, &bounds, witnesses, reaches}; }
};

// The data vertex (any vertex but a NODATA corner) of `tile` nearest to (x, y): squared distance
// dx² + dy² in doubles, ties to the smaller x, then y (docs/tile-format.md §2.1).
struct NearestVertex {
  double d2 = 0, x = 0, y = 0, z = 0;
  bool closer_than(const NearestVertex& o) const {
    return d2 < o.d2 || (d2 == o.d2 && (x < o.x || (x == o.x && y < o.y)));
  }
};
std::optional<NearestVertex> nearest_data_vertex(const tile::TinTile& tile, double x, double y);

}  // namespace tinstream::lod
