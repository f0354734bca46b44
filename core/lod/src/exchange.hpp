// Exchange steps after the drop stage (thinning.hpp, LodOptions::exchange_steps): the point of
// largest vertical error goes in, the vertex whose removal then leaves the smallest largest
// error goes out, while that lowers the tile's largest error. Internal to core/lod.
//
// One step tries k = 1, 2, … 8: the k points of largest error go in, one at a time (each the
// worst against the surface with the ones before), then k vertices go out, each the one whose
// removal leaves the smallest largest error over all points; the first k that lowers the largest
// error is kept, the others are undone (the points out, the vertices back: the same constrained
// Delaunay triangulation up to cocircular ties). No step lowers it: done. The work is bounded by
// 8 × max_steps vertex choices (each judges every removable vertex on its removal preview).
//
// Why: at a small budget the greedy stage leaves its largest error to the point it stopped
// before, and the drop stage, which removes the cheapest vertices down to the budget, never
// looks at it again (bench/lod/RESULTS.md 2026-11-28, "the outline floor": N00E010's, Jacksboro's
// and autzen's one-tile levels at 64 or 128 vertices kept exactly the greedy stage's error).
//
// Coverage (greedy.hpp): a vertex next to a NODATA corner may go only when no point of its star
// then lies beyond the data edge of a fan (a triangle at a NODATA corner) by more than the
// outline tolerance: the footprint still covers the data, as after the greedy stage, but an
// outline vertex that the exchange made redundant (a straight or flat outline) can pay for an
// interior one.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/kernel/triangulation.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod::detail {

struct ExchangeInput {
  // The points that may go in (a tile's interior candidates) and, by candidate, its vertex in the
  // triangulation or kernel::kNone (updated as vertices are exchanged).
  std::span<const tile::Vertex> candidates;
  std::vector<kernel::VertexId>* candidate_vertex = nullptr;
  // More points of the surface, measured but never inserted (orphans, dropped border points).
  std::vector<std::span<const tile::Vertex>> others;
  std::span<const kernel::VertexId> nodata_corners;
  double outline_tolerance = 0;  // greedy.hpp: within it of a fan's data edge is covered
};

struct ExchangeResult {
  std::size_t steps = 0;  // exchanges made (each lowered the largest error)
  double before = 0;      // the largest vertical error over the points before
  double after = 0;       // and after
};

// At most `max_steps` exchanges; the vertex count stays, and the largest vertical error over the
// candidates and the others only falls. Only candidates that are vertices go out; corners and
// border points stay. Errors: a kernel failure (internal).
Result<ExchangeResult> exchange_steps(kernel::Triangulation& tri, const ExchangeInput& in,
                                      std::size_t max_steps);

}  // namespace tinstream::lod::detail
