// tinstream/client/skirts.hpp — which tile sides hang a skirt in a frame, and how deep.
//
// A skirt exists to hide a crack, and a crack exists only between two drawn tiles of the same
// layer at different levels (tiles of one level share bit-identical borders, docs/DESIGN.md §3.3,
// §3.5). So, for each drawn tile T and each skirt quad along each of its sides:
//
//   * the quad hangs only where a drawn tile N of the same layer and of another level touches
//     the side from beyond it (a coarser N: the quadrant of N there is drawn; a finer N: its
//     quadrants facing T are) AND N has data over part of the quad's stretch of the border (N's
//     own skirt quads on the facing side are its data's border segments; TileMesh::skirt_spans,
//     compared exactly, positive overlap). Nothing drawn beyond — the data end there, a NODATA
//     corner's fan, a neighbour not loaded or culled — means nothing to join: no skirt, so no
//     curtain stands at the data's edge; and where the data edge crosses a level border, only
//     the quads beside the neighbour's data hang, not the whole side (the fins of #17);
//   * cuts: a tile drawn with a quadrant mask is cut by the fragment shader along a mid line
//     where one quadrant is drawn and its neighbour quadrant is not (a child is drawn there).
//     Its cut quads (the surface's cross-section, TileMesh::cut_index_count) hang the same way,
//     the drawn quadrant's cell and its side facing the child standing in for T and its side:
//     they close the opening between the cut edge and a lower child (#17, "gap above
//     children"). A child beside its parent's drawn quadrant meets the parent's cut, not a side;
//   * depth: both surfaces lie within their stored geometric errors of the finest surface, so at
//     a border point the crack is at most e_T + e_N: T's skirt hangs e_T + max e_N + a margin
//     against rounding (TileMesh::skirt_margin), per tile and per frame, not per level;
//   * floor: N's drawn triangles are data triangles, so N's surface never lies below N's min_z;
//     T's skirt never hangs below min N.min_z − margin (nor below what its box holds,
//     ResidentTile::skirt_lowest). With the chained errors of today's stores (hundreds of metres
//     at coarse levels, #20) the floor is what bounds most skirts.
//
// Pure geometry on tile ids and spans: testable without OpenGL. Runs on the render thread per
// frame, O(n²) in the tiles drawn per layer (a few hundred) for the touching test; the quads of
// touching pairs cost O(q log q).
#pragma once

#include <vector>

#include "tinstream/client/streamer.hpp"

namespace tinstream::client {

// Sides in the order of TileMesh::skirt_index_count.
enum class Side : std::uint8_t { north = 0, east = 1, south = 2, west = 3 };

// Fills skirt_runs, skirt_sides, skirt_depth and skirt_floor of every item; the items' tile
// pointers must be valid. The order of draws does not matter.
void plan_skirts(std::vector<DrawItem>& draws);

}  // namespace tinstream::client
