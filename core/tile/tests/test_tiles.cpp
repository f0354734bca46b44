#include "test_tiles.hpp"

#include <algorithm>
#include <bit>
#include <set>

namespace tinstream::tile::testing {

namespace {

// k distinct sorted doubles strictly inside (lo, hi).
std::vector<double> strictly_inside(double lo, double hi, std::uint32_t k, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::set<double> values;
  int attempts = 0;
  while (values.size() < k && attempts < 1000000) {
    ++attempts;
    const double v = lo + (hi - lo) * u(rng);
    if (v > lo && v < hi) values.insert(v);
  }
  return {values.begin(), values.end()};
}

}  // namespace

TinTile make_grid_tile(const geo::TileId& id, std::uint32_t nx, std::uint32_t ny,
                       std::mt19937_64& rng, bool nodata) {
  const geo::MercatorRect r = id.bounds();
  // Column positions west → east, row positions north → south.
  std::vector<double> xs = strictly_inside(r.min_x, r.max_x, nx - 1, rng);
  xs.insert(xs.begin(), r.min_x);
  xs.push_back(r.max_x);
  std::vector<double> ys = strictly_inside(r.min_y, r.max_y, ny - 1, rng);
  std::reverse(ys.begin(), ys.end());
  ys.insert(ys.begin(), r.max_y);
  ys.push_back(r.min_y);
  nx = static_cast<std::uint32_t>(xs.size() - 1);
  ny = static_cast<std::uint32_t>(ys.size() - 1);

  std::uniform_real_distribution<double> height(-430.0, 8848.0);
  std::uniform_real_distribution<double> weight(0.0, 10.0);
  std::bernoulli_distribution coin(0.5);
  std::bernoulli_distribution rare(0.15);
  const auto make = [&](std::uint32_t i, std::uint32_t j) {
    return Vertex{xs[i], ys[j], height(rng), weight(rng)};
  };

  TinTile t;
  t.id = id;
  // index[j][i] = vertex number of grid node (column i, row j).
  std::vector<std::vector<std::uint32_t>> index(ny + 1, std::vector<std::uint32_t>(nx + 1));
  std::uint32_t next = 4;
  t.corners = {make(0, 0), make(nx, 0), make(0, ny), make(nx, ny)};
  index[0][0] = 0, index[0][nx] = 1, index[ny][0] = 2, index[ny][nx] = 3;
  for (std::uint32_t i = 1; i < nx; ++i) t.north.push_back(make(i, 0)), index[0][i] = next++;
  for (std::uint32_t j = 1; j < ny; ++j) t.east.push_back(make(nx, j)), index[j][nx] = next++;
  for (std::uint32_t i = 1; i < nx; ++i) t.south.push_back(make(i, ny)), index[ny][i] = next++;
  for (std::uint32_t j = 1; j < ny; ++j) t.west.push_back(make(0, j)), index[j][0] = next++;
  for (std::uint32_t j = 1; j < ny; ++j) {
    for (std::uint32_t i = 1; i < nx; ++i) t.interior.push_back(make(i, j)), index[j][i] = next++;
  }
  if (nodata) {
    for (std::size_t c = 0; c < 4; ++c) {
      t.corner_nodata[c] = rare(rng);
      if (t.corner_nodata[c]) t.corners[c].z = 0;
    }
  }
  for (std::uint32_t j = 0; j < ny; ++j) {
    for (std::uint32_t i = 0; i < nx; ++i) {
      const std::uint32_t nw = index[j][i], ne = index[j][i + 1];
      const std::uint32_t sw = index[j + 1][i], se = index[j + 1][i + 1];
      if (coin(rng)) {
        t.triangles.push_back({sw, se, ne});
        t.triangles.push_back({sw, ne, nw});
      } else {
        t.triangles.push_back({sw, se, nw});
        t.triangles.push_back({se, ne, nw});
      }
    }
  }
  std::shuffle(t.triangles.begin(), t.triangles.end(), rng);
  for (Triangle& tri : t.triangles) {
    std::rotate(tri.begin(), tri.begin() + static_cast<std::ptrdiff_t>(rng() % 3), tri.end());
  }
  t.update_z_range();
  t.geometric_error = weight(rng);
  t.rms_error = t.geometric_error / 3;
  t.source_points = rng() % 1000000;
  return t;
}

geo::TileId random_tile_id(std::mt19937_64& rng, std::uint32_t max_level) {
  const auto z = static_cast<std::uint32_t>(rng() % (max_level + 1));
  const std::uint64_t n = std::uint64_t{1} << z;
  return {z, static_cast<std::uint32_t>(rng() % n), static_cast<std::uint32_t>(rng() % n)};
}

namespace {
bool same_vertex(const Vertex& a, const Vertex& b) {
  return std::bit_cast<std::uint64_t>(a.x) == std::bit_cast<std::uint64_t>(b.x) &&
         std::bit_cast<std::uint64_t>(a.y) == std::bit_cast<std::uint64_t>(b.y) &&
         std::bit_cast<std::uint64_t>(a.z) == std::bit_cast<std::uint64_t>(b.z) &&
         std::bit_cast<std::uint64_t>(a.weight) == std::bit_cast<std::uint64_t>(b.weight);
}
bool same_list(const std::vector<Vertex>& a, const std::vector<Vertex>& b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), same_vertex);
}
bool same_double(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}
}  // namespace

bool same_tile(const TinTile& a, const TinTile& b) {
  return a.id == b.id && a.corner_nodata == b.corner_nodata &&
         std::equal(a.corners.begin(), a.corners.end(), b.corners.begin(), same_vertex) &&
         same_list(a.north, b.north) && same_list(a.east, b.east) && same_list(a.south, b.south) &&
         same_list(a.west, b.west) && same_list(a.interior, b.interior) &&
         a.triangles == b.triangles && same_double(a.min_z, b.min_z) &&
         same_double(a.max_z, b.max_z) && same_double(a.geometric_error, b.geometric_error) &&
         same_double(a.rms_error, b.rms_error) && a.source_points == b.source_points;
}

}  // namespace tinstream::tile::testing
