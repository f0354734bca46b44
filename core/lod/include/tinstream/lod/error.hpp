// tinstream/lod/error.hpp — how far a coarse tile is from the surface it approximates, and the
// checks `tinstream verify` runs on a pyramid.
//
// Both surfaces are piecewise linear, so their difference is linear on every cell of the overlay
// of the two triangulations, and its maximum is reached at an overlay vertex: a vertex of either
// mesh or a point where a coarse edge crosses a fine edge. surface_difference() visits all of
// them without building the overlay: it walks every fine edge through the coarse mesh (exact
// orientation tests decide which coarse triangle holds each fine vertex and which coarse edges a
// fine edge crosses), evaluates the difference at each fine vertex and at each crossing, and
// evaluates the fine surface at any coarse vertex that is not also a fine vertex. The maximum is
// therefore exact up to the rounding of those evaluations (error_rounding_allowance). Cost:
// O(fine vertices + crossings), with short walks since consecutive fine triangles are near.
//
// RMS: the root mean square of the difference at the fine vertices, each weighted by a third of
// the area of its data triangles (the fine surface's samples, area-weighted; for evenly spread
// samples this is their plain RMS, and it approximates the area RMS of the difference).
//
// NODATA: triangles incident to a NODATA corner (z = 0 by convention, no data there) are not
// surface, at any level and on both sides: the error is measured where both surfaces have data.
// (Measuring the coarse tile's NODATA triangles — slopes down to z = 0 at the data's edge — made
// the bound grow by the terrain's full height at every level and meant nothing to a client.) The
// overlay is exact (up to rounding) where both have data; in the thin band at the data's outer
// edge where a finer tile has NODATA triangles over finest data it sees nothing, which
// build_parent covers with its NODATA-band term (parent.hpp).
// Areas without fine tiles (missing children) are not measured.
//
// Threads: pure functions on values.
#pragma once

#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

struct SurfaceDifference {
  double max_abs = 0;         // max |coarse − fine| over the measured area
  double sum_sq_area = 0;     // Σ (coarse − fine)² × vertex area (a third of its triangles')
  double area = 0;            // measured area (normalised Mercator units²)
  std::size_t crossings = 0;  // coarse-edge / fine-edge crossings evaluated
  double rms() const;
};

// Requires: every fine tile lies inside `coarse`'s rectangle, and each is a valid triangulation
// covering its own rectangle (tile::check_structure); `coarse` covers its rectangle.
SurfaceDifference surface_difference(const tile::TinTile& coarse,
                                     std::span<const tile::TinTile* const> fines);
// The same, one result per fine tile (in order), the coarse mesh prepared once.
std::vector<SurfaceDifference> surface_differences(const tile::TinTile& coarse,
                                                   std::span<const tile::TinTile* const> fines);

// Rounding allowance added to every stored bound (metres): the overlay is evaluated in floating
// point, so the exact maximum may exceed the computed one by a few ulps of the heights involved.
// 1 µm + 1e-9 × the tile's height range.
double error_rounding_allowance(const tile::TinTile& coarse);

// Shared borders of same-level neighbours are identical: for every pair of tiles in the list that
// are east/west or north/south neighbours, the two border() lists match exactly (x, y, z bits).
// Pairs across the antimeridian are not compared. Errors name the pair and the first differing
// point. Requires: all tiles of one level.
Status check_level_watertight(const std::vector<tile::TinTile>& tiles_of_one_level);

// The largest |coarse − finest| found by sampling: every vertex of the finest tiles located in
// the coarse tile, and every coarse vertex located in the finest tiles (an independent lower
// bound of the true maximum; verify checks stored geometric_error ≥ this). Finest triangles at
// NODATA corners are skipped. Errors: a finest tile outside the coarse tile, an empty list.
Result<double> measured_max_error(const tile::TinTile& coarse,
                                  const std::vector<tile::TinTile>& finest_tiles_under_it);

// The tile holds at most max_points vertices (corners and edge points included).
Status check_budget(const tile::TinTile& tile, std::size_t max_points);

}  // namespace tinstream::lod
