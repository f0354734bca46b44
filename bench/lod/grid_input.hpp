// The thinning input of a whole grid treated as one tile, shared by the bench/lod tools so that
// they thin exactly the same input.
#pragma once

#include "tinstream/lod/thinning.hpp"

namespace tinstream::bench {

// A w × h grid as a ThinInput: the four corner cells, the cells of the four borders without the
// corners (north = row 0, ordered along the edge) and the interior, each vertex made by
// `vertex(col, row)`. The rectangle spans the corner cells' centres.
template <class VertexAt>
lod::ThinInput grid_thin_input(int w, int h, VertexAt vertex) {
  lod::ThinInput in;
  const int W = w - 1, H = h - 1;
  in.rect = geo::MercatorRect{vertex(0, H).x, vertex(0, H).y, vertex(W, 0).x, vertex(W, 0).y};
  in.corners = {vertex(0, 0), vertex(W, 0), vertex(0, H), vertex(W, H)};
  for (int c = 1; c < W; ++c) in.north.push_back(vertex(c, 0));
  for (int r = 1; r < H; ++r) in.east.push_back(vertex(W, r));
  for (int c = 1; c < W; ++c) in.south.push_back(vertex(c, H));
  for (int r = 1; r < H; ++r) in.west.push_back(vertex(0, r));
  for (int r = 1; r < H; ++r) {
    for (int c = 1; c < W; ++c) in.interior.push_back(vertex(c, r));
  }
  return in;
}

}  // namespace tinstream::bench
