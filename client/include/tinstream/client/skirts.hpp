// tinstream/client/skirts.hpp — which tile sides hang a skirt in a frame, and how deep.
//
// A skirt exists to hide a crack, and a crack exists only between two drawn tiles of the same
// layer at different levels (tiles of one level share bit-identical borders, DESIGN.md §3). So,
// for each drawn tile T and each of its sides:
//
//   * a skirt only where a drawn tile N of the same layer and of another level touches the side
//     from beyond it (a coarser N: the quadrant of N there is drawn; a finer N: its quadrants
//     facing T are). Nothing drawn beyond a side — the data end there, a NODATA corner's fan, a
//     neighbour not loaded or culled — means nothing to join: no skirt, so no curtain stands
//     at the data's edge (what users saw from low angles, as in CesiumJS views);
//   * depth: both surfaces lie within their stored geometric errors of the finest surface, so at
//     a border point the crack is at most e_T + e_N: T's skirt hangs e_T + max e_N + a margin
//     against rounding (TileMesh::skirt_margin), per tile and per frame, not per level;
//   * floor: N's drawn triangles are data triangles, so N's surface never lies below N's min_z;
//     T's skirt never hangs below min N.min_z − margin (nor below what its box holds,
//     ResidentTile::skirt_lowest). With the chained errors of today's stores (hundreds of metres
//     at coarse levels, #20) the floor is what bounds most skirts.
//
// Pure geometry on tile ids: testable without OpenGL. Runs on the render thread per frame,
// O(n²) in the tiles drawn per layer (a few hundred).
#pragma once

#include <vector>

#include "tinstream/client/streamer.hpp"

namespace tinstream::client {

// Sides in the order of TileMesh::skirt_index_count.
enum class Side : std::uint8_t { north = 0, east = 1, south = 2, west = 3 };

// Fills skirt_sides, skirt_depth and skirt_floor of every item; the items' tile pointers must be
// valid. The order of draws does not matter.
void plan_skirts(std::vector<DrawItem>& draws);

}  // namespace tinstream::client
