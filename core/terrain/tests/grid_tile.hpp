// Test helper: a TinTile over a regular n×n grid of a height function of (lon, lat), numbered as
// tin_tile.hpp says. Neighbouring tiles built from the same function share their border vertices.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "tinstream/geo/mercator.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::testing {

using HeightFn = std::function<double(double lon, double lat)>;

inline tile::TinTile make_grid_tile(const geo::TileId& id, int n, const HeightFn& height) {
  const geo::MercatorRect r = id.bounds();
  const geo::NormalisedMercator merc(geo::Projection::spherical);
  auto coord = [&](int i, int j) {
    const double x = i == n - 1 ? r.max_x : r.min_x + r.width() * i / (n - 1);
    const double y = j == n - 1 ? r.min_y : r.max_y - r.height() * j / (n - 1);
    const geo::LonLat ll = merc.inverse({x, y});
    return tile::Vertex{x, y, height(ll.lon, ll.lat), 1.0};
  };
  tile::TinTile t;
  t.id = id;
  const auto side = static_cast<std::size_t>(n);
  std::vector<std::uint32_t> cells(side * side);
  auto index = [&](int i, int j) -> std::uint32_t& {
    return cells[static_cast<std::size_t>(i) * side + static_cast<std::size_t>(j)];
  };
  t.corners = {coord(0, 0), coord(n - 1, 0), coord(0, n - 1), coord(n - 1, n - 1)};
  index(0, 0) = 0;
  index(n - 1, 0) = 1;
  index(0, n - 1) = 2;
  index(n - 1, n - 1) = 3;
  std::uint32_t next = 4;
  for (int i = 1; i < n - 1; ++i) t.north.push_back(coord(i, 0)), index(i, 0) = next++;
  for (int j = 1; j < n - 1; ++j) t.east.push_back(coord(n - 1, j)), index(n - 1, j) = next++;
  for (int i = 1; i < n - 1; ++i) t.south.push_back(coord(i, n - 1)), index(i, n - 1) = next++;
  for (int j = 1; j < n - 1; ++j) t.west.push_back(coord(0, j)), index(0, j) = next++;
  for (int j = 1; j < n - 1; ++j) {
    for (int i = 1; i < n - 1; ++i) t.interior.push_back(coord(i, j)), index(i, j) = next++;
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const std::uint32_t a = index(i, j), b = index(i + 1, j), c = index(i, j + 1),
                          d = index(i + 1, j + 1);
      t.triangles.push_back({a, c, d});
      t.triangles.push_back({a, d, b});
    }
  }
  t.min_z = t.max_z = t.corners[0].z;
  for (const auto* list : {&t.north, &t.east, &t.south, &t.west, &t.interior}) {
    for (const auto& v : *list) t.min_z = std::min(t.min_z, v.z), t.max_z = std::max(t.max_z, v.z);
  }
  for (const auto& v : t.corners)
    t.min_z = std::min(t.min_z, v.z), t.max_z = std::max(t.max_z, v.z);
  return t;
}

// A smooth synthetic surface (metres): hills of a few hundred metres.
inline double synthetic_height(double lon, double lat) {
  return 300.0 + 120.0 * std::sin(lon * 7.0) * std::cos(lat * 5.0) + 0.37 * lat;
}

}  // namespace tinstream::testing
