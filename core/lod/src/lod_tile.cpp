// The nearest data vertex (lod_tile.hpp).
#include "tinstream/lod/lod_tile.hpp"

#include <algorithm>
#include <cmath>

namespace tinstream::lod {

std::optional<NearestVertex> nearest_data_vertex(const tile::TinTile& tile, double x, double y) {
  std::optional<NearestVertex> best;
  const std::size_t n = tile.vertex_count();
  for (std::size_t i = 0; i < n; ++i) {
    if (tile.is_nodata_vertex(i)) continue;
    const tile::Vertex& v = tile.vertex(i);
    const NearestVertex c{(v.x - x) * (v.x - x) + (v.y - y) * (v.y - y), v.x, v.y, v.z};
    if (!best || c.closer_than(*best)) best = c;
  }
  return best;
}

}  // namespace tinstream::lod
