// filler_tile: the tiles Cesium needs where nothing is stored, joined to the stored ones.
#include <algorithm>
#include <functional>
#include <optional>
#include <vector>

#include "tinstream/terrain/quantized_mesh.hpp"

namespace tinstream::terrain {

namespace {

// The vertices of stored tile `n`, moved by `shift` in x, that lie on the border of rectangle `r`
// (exactly: shared borders of one level have the same coordinates in every tile, and the map's
// ends −1 and 1 move onto each other exactly).
void collect_shared(const tile::TinTile& n, double shift, const geo::MercatorRect& r,
                    std::vector<tile::Vertex>& out) {
  for (std::size_t i = 0; i < n.vertex_count(); ++i) {
    const tile::VertexRole role = n.role(i);
    if (role == tile::VertexRole::interior) continue;
    tile::Vertex v = n.vertex(i);
    v.x += shift;
    const bool on_ns = (v.y == r.min_y || v.y == r.max_y) && v.x >= r.min_x && v.x <= r.max_x;
    const bool on_we = (v.x == r.min_x || v.x == r.max_x) && v.y >= r.min_y && v.y <= r.max_y;
    if (on_ns || on_we) out.push_back({v.x, v.y, v.z, 0.0});
  }
}

// The position of a border point along the tile's border walked counter-clockwise from NW:
// west side down, south side east, east side up, north side west (0 … 4).
double ccw_position(const tile::Vertex& v, const geo::MercatorRect& r) {
  if (v.x == r.min_x && v.y < r.max_y) return (r.max_y - v.y) / r.height();
  if (v.y == r.min_y && v.x < r.max_x) return 1.0 + (v.x - r.min_x) / r.width();
  if (v.x == r.max_x && v.y > r.min_y) return 2.0 + (v.y - r.min_y) / r.height();
  return 3.0 + (r.max_x - v.x) / r.width();
}

}  // namespace

Result<tile::TinTile> filler_tile(const geo::TileId& id, std::uint32_t min_level,
                                  const StoredTileLookup& stored) {
  // Above the coarsest stored level the same-level neighbours are all absent: no lookup.
  if (id.z < min_level) return flat_tile(id);
  const geo::MercatorRect r = id.bounds();
  const std::int64_t n = std::int64_t{1} << id.z;
  std::vector<tile::Vertex> shared;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const std::int64_t x = std::int64_t{id.x} + dx, y = std::int64_t{id.y} + dy;
      if ((dx == 0 && dy == 0) || y < 0 || y >= n) continue;
      // Across the antimeridian the neighbour's shared side is at the other end of the map:
      // its vertices are moved by one map width.
      const double width = geo::tile_x_edge(0, 1) - geo::tile_x_edge(0, 0);
      const double shift = x < 0 ? -width : x >= n ? width : 0.0;
      auto nb_id = geo::TileId::from_zxy(id.z, (x + n) % n, y);
      if (!nb_id) return nb_id.error();
      if (*nb_id == id) continue;  // level 0 is its own neighbour
      auto nb = stored(*nb_id);
      if (!nb) return nb.error();
      if (nb->has_value()) collect_shared(**nb, shift, r, shared);
    }
  }
  if (shared.empty()) return flat_tile(id);

  tile::TinTile t = flat_tile(id);
  t.triangles.clear();
  auto same_place = [](const tile::Vertex& a, const tile::Vertex& b) {
    return a.x == b.x && a.y == b.y;
  };
  for (tile::Vertex& c : t.corners) {
    auto it = std::find_if(shared.begin(), shared.end(),
                           [&](const tile::Vertex& v) { return same_place(v, c); });
    if (it != shared.end()) c.z = it->z;
  }
  // Edge points: the shared vertices strictly between corners, one per place, in the tile's
  // edge order (tin_tile.hpp).
  std::sort(shared.begin(), shared.end(), [&](const tile::Vertex& a, const tile::Vertex& b) {
    return ccw_position(a, r) < ccw_position(b, r);
  });
  shared.erase(std::unique(shared.begin(), shared.end(), same_place), shared.end());
  for (const tile::Vertex& v : shared) {
    const bool corner = (v.x == r.min_x || v.x == r.max_x) && (v.y == r.min_y || v.y == r.max_y);
    if (corner) continue;
    if (v.x == r.min_x)
      t.west.push_back(v);  // north → south (ccw order)
    else if (v.y == r.min_y)
      t.south.push_back(v);  // west → east
    else if (v.x == r.max_x)
      t.east.push_back(v);  // south → north: reversed below
    else
      t.north.push_back(v);  // east → west: reversed below
  }
  std::reverse(t.east.begin(), t.east.end());
  std::reverse(t.north.begin(), t.north.end());
  double mean = 0;
  for (const tile::Vertex& c : t.corners) mean += c.z / 4.0;
  t.interior.push_back({(r.min_x + r.max_x) / 2, (r.min_y + r.max_y) / 2, mean, 0.0});

  // The border counter-clockwise (NW, west, SW, south, SE, east up, NE, north westwards), each
  // consecutive pair fanned to the centre.
  const auto base = [&](std::size_t before) { return static_cast<std::uint32_t>(4 + before); };
  const std::uint32_t north0 = base(0), east0 = base(t.north.size()),
                      south0 = base(t.north.size() + t.east.size()),
                      west0 = base(t.north.size() + t.east.size() + t.south.size()),
                      centre =
                          base(t.north.size() + t.east.size() + t.south.size() + t.west.size());
  std::vector<std::uint32_t> ring{0};
  for (std::uint32_t i = 0; i < t.west.size(); ++i) ring.push_back(west0 + i);
  ring.push_back(2);
  for (std::uint32_t i = 0; i < t.south.size(); ++i) ring.push_back(south0 + i);
  ring.push_back(3);
  for (std::uint32_t i = static_cast<std::uint32_t>(t.east.size()); i-- > 0;)
    ring.push_back(east0 + i);
  ring.push_back(1);
  for (std::uint32_t i = static_cast<std::uint32_t>(t.north.size()); i-- > 0;)
    ring.push_back(north0 + i);
  for (std::size_t i = 0; i < ring.size(); ++i)
    t.triangles.push_back({centre, ring[i], ring[(i + 1) % ring.size()]});
  t.update_z_range();
  return t;
}

}  // namespace tinstream::terrain
