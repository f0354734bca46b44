// Helpers shared by the lod tests: synthetic grid tiles and an independent (brute-force)
// evaluation of a tile's surface.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <optional>
#include <vector>

#include "tinstream/geo/tile_id.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod::testing {

// The tile the thinning, greedy and lattice suites build their grids in.
inline const geo::TileId kTile{10, 300, 200};

using Surface = std::function<double(double, double)>;

// Options that keep every point: nothing is above budget and nothing is below epsilon 0.
inline LodOptions keep_everything() {
  LodOptions o;
  o.max_points = std::size_t{1} << 30;
  o.border_points_per_side = std::size_t{1} << 30;
  o.epsilon = 0.0;
  return o;
}

// A finest-like tile sampling `f` on an (n+1)×(n+1) lattice over the tile (n a power of two, so
// lattice points on a border are exactly on it and neighbours share them bit for bit); with
// interior_n, its interior samples the (interior_n − 1)² inner points of an interior_n lattice
// instead (neighbours still share their borders whatever the density of their interiors).
inline tile::TinTile grid_tile(const geo::TileId& id, int n, const Surface& f,
                               const std::function<double(double, double)>& weight = {},
                               int interior_n = 0) {
  const geo::MercatorRect r = id.bounds();
  const double h = r.width() / n;
  const int m = interior_n > 0 ? interior_n : n;
  const double g = r.width() / m;
  ThinInput in;
  in.id = id;
  auto v = [&](double x, double y) {
    return tile::Vertex{x, y, f(x, y), weight ? weight(x, y) : 0.0};
  };
  in.corners = {v(r.min_x, r.max_y), v(r.max_x, r.max_y), v(r.min_x, r.min_y), v(r.max_x, r.min_y)};
  for (int i = 1; i < n; ++i) {
    in.north.push_back(v(r.min_x + i * h, r.max_y));
    in.south.push_back(v(r.min_x + i * h, r.min_y));
    in.east.push_back(v(r.max_x, r.max_y - i * h));
    in.west.push_back(v(r.min_x, r.max_y - i * h));
  }
  for (int j = 1; j < m; ++j) {
    for (int i = 1; i < m; ++i) in.interior.push_back(v(r.min_x + i * g, r.max_y - j * g));
  }
  auto t = thin_tile(in, keep_everything());
  EXPECT_TRUE(t.ok()) << (t.ok() ? "" : t.error().message);
  return t.ok() ? *t : tile::TinTile{};
}

// Barycentric interpolation by brute force over the tile's triangles (written independently of
// the library). Triangles at NODATA corners are skipped when skip_nodata. nullopt: not covered.
inline std::optional<double> brute_height(const tile::TinTile& t, double x, double y,
                                          bool skip_nodata) {
  const auto v = t.vertices();
  std::optional<double> best;
  double best_w = -1e-9;
  for (const auto& tr : t.triangles) {
    if (skip_nodata) {
      bool nd = false;
      for (auto i : tr) nd = nd || (i < 4 && t.corner_nodata[i]);
      if (nd) continue;
    }
    const auto &a = v[tr[0]], &b = v[tr[1]], &c = v[tr[2]];
    const double det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    const double la = ((b.x - x) * (c.y - y) - (b.y - y) * (c.x - x)) / det;
    const double lb = ((c.x - x) * (a.y - y) - (c.y - y) * (a.x - x)) / det;
    const double lc = 1.0 - la - lb;
    const double w = std::min({la, lb, lc});
    if (w > best_w) {
      best_w = w;
      best = la * a.z + lb * b.z + lc * c.z;
    }
  }
  return best;
}

// Max |coarse − z| over the finest data points under `coarse`: the vertices of the fine tiles'
// data triangles (error.hpp: what is measured), the coarse surface evaluated on any of its
// triangles by brute force.
inline double data_point_max_difference(const tile::TinTile& coarse,
                                        const std::vector<tile::TinTile>& fines) {
  double worst = 0;
  for (const auto& f : fines) {
    const auto v = f.vertices();
    std::vector<std::uint8_t> data(v.size(), 0);
    for (std::size_t t = 0; t < f.triangles.size(); ++t) {
      if (f.is_nodata_triangle(t)) continue;
      for (auto i : f.triangles[t]) data[i] = 1;
    }
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!data[i]) continue;
      const auto zc = brute_height(coarse, v[i].x, v[i].y, false);
      if (zc) worst = std::max(worst, std::abs(*zc - v[i].z));
    }
  }
  return worst;
}

}  // namespace tinstream::lod::testing
