// tinstream/lod/parent.hpp — one coarse tile from the finer tiles under it (docs/DESIGN.md §3.5,
// pass 4): its four children, and optionally its "sources", the tiles several levels below it
// (build_from_sources), so that a coarse level is thinned from a finer surface than its
// children's already thinned one and its chained error bound (error.hpp) runs through fewer
// levels (pyramid.hpp chooses the sources).
//
// Merge rule. Corners and outer border come from the children, always: the parent's corner k is
// child k's corner k (NODATA flag and height); its sides are the children's edge points on them
// plus the children's corners at the midpoints of its sides (unless NODATA). A neighbour builds
// its side from the same children's sides, so same-level tiles stay watertight whatever their
// sources. The interior candidates are the sources' interior points (depth 1: the children's),
// plus the sources' witnesses (lod_tile.hpp: finest data points where a source deviates most)
// where the sources' points exceed the budget. The sources' points on the inner grid lines
// (depth 1: the internal cross, the two lines that split the parent) and the inner grid vertices
// are candidates too: they are points of the finer surface, and where the sources' interior points
// near a seam are sparse (the sources' sides carried the detail there) nothing else can bring the
// parent close to it (until 2026-11-28 they were cut artefacts, orphans only: the 250 m Luxembourg
// DEM's level 9 measured 22.4 m instead of 6.5 m). For depth > 1 the sources' points on the outer
// border feed the thinning's error estimate as orphans, since they are part of the surface (the
// border's candidates are the children's).
//
// An absent child (no data) gives a corner whose height and NODATA flag the caller supplies
// (Children::absent_corners; NODATA unless told): docs/tile-format.md
// §2.1 takes them from the tiles of the children's level around that corner, which the pyramid
// reads; deciding them from the children alone could disagree with the tile across the corner,
// whose children are different tiles (a flag that differs thins the shared side differently).
// Likewise its stretch of the parent's outer border (Children::absent_border): the parent across
// builds that stretch of their shared side from its own child there, so this parent takes the
// same points, the side of that tile (and the side's midpoint, where both children along it are
// absent); the caller reads them, as the pyramid does (docs/tile-format.md §2.1). Left empty, the
// stretch has no points (until 2026-11-28 always: the 250 m Luxembourg DEM at --max-points 2048
// had two level-11 tiles with different points on their shared side, issue #20).
//
// Budget (README "How it works", LOD thinning). A parent keeps at most
// coverage_budget(covered, options) vertices plus its border points, where `covered` is the share
// of the parent's area that its children's data footprints (tin_tile.hpp) cover: max_points × 4 ×
// covered (no more than the data would hold in full tiles one level finer), at least the outline
// budget ⌈√max_points⌉ (about one side's worth, for the data's outline), at most max_points. A
// level thus keeps at most the vertex density of full tiles one level finer instead of
// max_points per tile wherever its tiles are larger than the data (until 2026-11-28 a small LiDAR
// crop kept ~9,000 vertices at every level 0–13, Big Tujunga's level-0 tile 16,384 vertices at
// 1,228 distinct quantized-mesh positions). The outline budget is not cut further (say, to the
// candidates' distinct quantized-mesh positions, tried 2026-11-28): a client that draws the data
// footprint only (tinstream-viewer) then saw a coarse tile of a small dataset as a sliver of it,
// its few vertices' triangles all touching NODATA corners, while the recorded error, measured
// over the data, let it stop there. The border keeps the per-side budget of max_points
// (thinning.hpp side_budget), which the tile across computes too, so same-level tiles stay
// watertight; a tile holds more than its budget only where its corners and kept border points alone
// exceed it. A parent whose budget is the outline floor (the area share asks for no more) is
// thinned with exchange steps (thinning.hpp LodOptions::exchange_steps, as many as the floor):
// there the greedy stage's last error was the tile's (N00E010's and Jacksboro's one-tile levels at
// 64 vertices 1.02× and 1.06× Delatin's max error, autzen's at 128 0.95× greedy insertion's; with
// them 0.84×, 0.78×, 0.81×, bench/lod/RESULTS.md 2026-11-28). Larger budgets keep the greedy and
// drop stages alone (their error is already below the peers', and the steps cost CPU per point).
// A parent that would take its one child's vertices as candidates
// (Sources::candidates_from_children) but keeps fewer than those is thinned from its sources
// instead, and so is one whose error with them comes out above its finer tiles' (its farther
// corners can turn nearly collinear outline vertices into a flat data triangle; the better of
// the two tiles stays; bench/lod/RESULTS.md 2026-11-28 15:00). The error is chained and recorded as
// before, so a smaller budget records the larger error it makes.
//
// Error (error.hpp): per-triangle bounds chained over the overlay with the sources and their
// bounds, measured over the finest level's data against every triangle of the parent (NODATA
// triangles included); geometric_error is their largest (and at least every child's and
// source's), rms_error by Minkowski. Both are upper bounds of the error against the finest data,
// monotone non-decreasing towards the root. Witnesses: among the candidates and the orphans, the
// ones the parent deviates most from.
//
// Threads: pure function on values.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/lod/lod_tile.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

// The parent's outer border where children are absent, as the tiles of the children's level across
// it have it (what the parents across take from their children there).
struct AbsentBorder {
  // [side d (geo::Direction)][half h (0: the side's west or north half)]: where the child along
  // that half of side d is absent, the side points of the tile across (its side facing the child,
  // in the parent's edge order: west to east, north to south); empty where that tile is absent.
  std::array<std::array<std::vector<tile::Vertex>, 2>, 4> sides;
  // [side d]: where both children along side d are absent, the midpoint of side d as the tiles
  // across have it, when it is a data corner there (else nullopt).
  std::array<std::optional<tile::Vertex>, 4> midpoints;
};

// The parent's corner k where child k is absent: its height, and whether it is NODATA (as the
// tiles of the children's level around it have it; none there: NODATA).
struct AbsentCorner {
  double z = 0;
  bool nodata = true;
};

struct Children {
  std::array<std::optional<LodTile>, 4> tiles;  // parent.children()[i]: NW, NE, SW, SE
  std::array<AbsentCorner, 4> absent_corners;   // [k]: read where tiles[k] is absent
  AbsentBorder absent_border;                   // nothing across absent children unless told
};

// A coarse tile's sources beside its children: the tiles `depth` levels below it that exist
// (any order). depth 1: the children themselves (tiles empty).
struct Sources {
  std::uint32_t depth = 1;
  std::vector<LodTile> tiles;
  // The interior candidates (and orphans, witnesses) come from the children as for depth 1, the
  // chained error from the sources: for a parent whose data all lie under one child that was
  // thinned from these same sources, where thinning them again would mostly repeat its choice.
  bool candidates_from_children = false;
};

// The same inputs held elsewhere (the pyramid's cache of decoded tiles, pyramid.cpp), not copied:
// tiles[k] null where child k is absent; the sources in the order given.
struct ChildViews {
  std::array<const LodTile*, 4> tiles{};
  std::array<AbsentCorner, 4> absent_corners;
  const AbsentBorder* absent_border = nullptr;  // null: nothing across absent children
};
struct SourceViews {
  std::uint32_t depth = 1;
  std::vector<const LodTile*> tiles;  // not null
  bool candidates_from_children = false;
};

// The budget of a parent whose children's data footprints cover the share `covered` (0 … 1) of
// its area, border points aside: max(outline_budget, ⌈4 × max_points × covered⌉), at most
// max_points (the rule above).
std::size_t coverage_budget(double covered, const LodOptions& options);
// ⌈√max_points⌉, at least 4: the least a parent with data keeps by area.
std::size_t outline_budget(const LodOptions& options);

// The parent's corners and outer border come from `children` (which its neighbours share, so
// same-level tiles stay watertight whatever depth each one's sources have), its interior
// candidates, orphans, witnesses and chained error from the sources; it records at least every
// child's and every source's error. Errors: no child, a child with the wrong id, no source (depth
// > 1), a source that is not `depth` levels under `parent` or is given twice, a broken
// triangulation.
Result<LodTile> build_from_sources(const geo::TileId& parent, const Children& children,
                                   const Sources& sources, const LodOptions& options = {},
                                   ThinStats* stats = nullptr);

// build_from_sources on views; the same result as on copies of the tiles.
Result<LodTile> build_from_sources(const geo::TileId& parent, const ChildViews& children,
                                   const SourceViews& sources, const LodOptions& options = {},
                                   ThinStats* stats = nullptr);

// build_from_sources with the four children (depth 1).
// Errors: every child missing, a child with the wrong id, a broken triangulation.
Result<LodTile> build_parent(const geo::TileId& parent, const Children& children,
                             const LodOptions& options = {}, ThinStats* stats = nullptr);

// The same for unreduced finest children (their bounds are exact), the parent's tile only; an
// absent child's corner takes the height of the data vertex of the present children nearest to
// it (a stand-alone rule: the pyramid applies the one of docs/tile-format.md §2.1).
Result<tile::TinTile> build_parent(const geo::TileId& parent,
                                   std::array<std::optional<tile::TinTile>, 4> children,
                                   const LodOptions& options = {}, ThinStats* stats = nullptr);

}  // namespace tinstream::lod
