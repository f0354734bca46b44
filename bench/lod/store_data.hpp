// bench/lod: what the lod benchmarks read off a stored pyramid — the finest level's data points
// and a point locator over a tile's triangles. Header-only, benchmarks only.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "tinstream/geo/tile_id.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::bench {

struct Point3 {
  double x, y, z;
};

// A triangle mesh with a bucket grid for point location (largest smallest barycentric weight).
class Locator {
 public:
  Locator(std::vector<Point3> p, std::vector<std::array<std::uint32_t, 3>> t) : p_(std::move(p)) {
    t_ = std::move(t);
    // The grid spans the small triangles (data that covers a corner of a coarse tile would
    // otherwise fall into one cell); big triangles are clamped into the cells they reach.
    std::vector<std::array<double, 4>> box(t_.size());
    double all_x0 = std::numeric_limits<double>::infinity(), all_y0 = all_x0, all_x1 = -all_x0,
           all_y1 = -all_x0;
    for (std::uint32_t i = 0; i < t_.size(); ++i) {
      double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
      for (auto v : t_[i]) {
        x0 = std::min(x0, p_[v].x), x1 = std::max(x1, p_[v].x);
        y0 = std::min(y0, p_[v].y), y1 = std::max(y1, p_[v].y);
      }
      box[i] = {x0, y0, x1, y1};
      all_x0 = std::min(all_x0, x0), all_x1 = std::max(all_x1, x1);
      all_y0 = std::min(all_y0, y0), all_y1 = std::max(all_y1, y1);
    }
    lo_x_ = lo_y_ = std::numeric_limits<double>::infinity();
    hi_x_ = hi_y_ = -lo_x_;
    const double limit = (all_x1 - all_x0) * (all_y1 - all_y0) / 4096.0;
    for (const auto& b : box) {
      if ((b[2] - b[0]) * (b[3] - b[1]) > limit) continue;
      lo_x_ = std::min(lo_x_, b[0]), hi_x_ = std::max(hi_x_, b[2]);
      lo_y_ = std::min(lo_y_, b[1]), hi_y_ = std::max(hi_y_, b[3]);
    }
    if (!(lo_x_ < hi_x_ && lo_y_ < hi_y_))
      lo_x_ = all_x0, hi_x_ = all_x1, lo_y_ = all_y0, hi_y_ = all_y1;
    g_ = static_cast<int>(std::clamp(std::sqrt(static_cast<double>(t_.size()) / 2.0), 1.0, 512.0));
    cells_.assign(static_cast<std::size_t>(g_) * static_cast<std::size_t>(g_), {});
    for (std::uint32_t i = 0; i < t_.size(); ++i) {
      const double x0 = box[i][0], y0 = box[i][1], x1 = box[i][2], y1 = box[i][3];
      for (int cy = cell(y0, lo_y_, hi_y_); cy <= cell(y1, lo_y_, hi_y_); ++cy) {
        for (int cx = cell(x0, lo_x_, hi_x_); cx <= cell(x1, lo_x_, hi_x_); ++cx) {
          cells_[static_cast<std::size_t>(cy * g_ + cx)].push_back(i);
        }
      }
    }
  }
  // Interpolated height at (x, y), and the smallest barycentric weight of the best triangle.
  double height(double x, double y, double* weight) const {
    double best_w = -std::numeric_limits<double>::infinity(), best_h = 0;
    const int cx = cell(x, lo_x_, hi_x_), cy = cell(y, lo_y_, hi_y_);
    for (std::uint32_t i : cells_[static_cast<std::size_t>(cy * g_ + cx)]) {
      const Point3 &a = p_[t_[i][0]], &b = p_[t_[i][1]], &c = p_[t_[i][2]];
      const double det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
      if (det == 0) continue;
      const double wb = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
      const double wc = ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) / det;
      const double wa = 1 - wb - wc;
      const double w = std::min({wa, wb, wc});
      if (w > best_w) best_w = w, best_h = wa * a.z + wb * b.z + wc * c.z;
    }
    *weight = best_w;
    return best_h;
  }
  // Whether a triangle with data[i] set holds (x, y), its sides included up to rounding.
  bool covered(double x, double y, const std::vector<bool>& data) const {
    const int cx = cell(x, lo_x_, hi_x_), cy = cell(y, lo_y_, hi_y_);
    for (std::uint32_t i : cells_[static_cast<std::size_t>(cy * g_ + cx)]) {
      if (!data[i]) continue;
      const Point3 &a = p_[t_[i][0]], &b = p_[t_[i][1]], &c = p_[t_[i][2]];
      const double det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
      if (det == 0) continue;
      const double wb = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
      const double wc = ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) / det;
      if (std::min({1 - wb - wc, wb, wc}) >= -1e-9) return true;
    }
    return false;
  }

 private:
  int cell(double v, double lo, double hi) const {
    const double f = hi > lo ? (v - lo) / (hi - lo) : 0.0;
    return std::clamp(static_cast<int>(std::floor(f * g_)), 0, g_ - 1);
  }
  std::vector<Point3> p_;
  std::vector<std::array<std::uint32_t, 3>> t_;
  std::vector<std::vector<std::uint32_t>> cells_;
  double lo_x_, lo_y_, hi_x_, hi_y_;
  int g_ = 1;
};

inline Locator tile_locator(const tile::TinTile& t) {
  std::vector<Point3> p;
  for (const auto& v : t.vertices()) p.push_back({v.x, v.y, v.z});
  return Locator(std::move(p), {t.triangles.begin(), t.triangles.end()});
}

// The finest level's data: the vertices of its data triangles (the input points, and the edge
// points and corners on the data), by finest tile, and their height range.
struct FinestData {
  std::map<geo::TileId, std::vector<Point3>> points;
  double lo = std::numeric_limits<double>::infinity(),
         hi = -std::numeric_limits<double>::infinity();
};

inline FinestData finest_data(store::TileStore& store, const std::string& layer,
                              std::uint32_t finest) {
  FinestData d;
  auto ids = store.tile_ids(layer, finest);
  if (!ids) {
    std::fprintf(stderr, "%s\n", ids.error().message.c_str());
    std::exit(1);
  }
  for (const auto& id : *ids) {
    auto read = store.read_tile(layer, id);
    if (!read || !*read) {
      std::fprintf(stderr, "cannot read %s\n", id.to_string().c_str());
      std::exit(1);
    }
    const tile::TinTile& t = **read;
    const auto mask = t.footprint_mask();
    std::vector<std::uint8_t> used(t.vertex_count(), 0);
    for (std::size_t k = 0; k < t.triangles.size(); ++k) {
      if (mask[k]) {
        for (auto i : t.triangles[k]) used[i] = 1;
      }
    }
    auto& pts = d.points[id];
    for (std::size_t i = 0; i < used.size(); ++i) {
      if (!used[i]) continue;
      const auto& v = t.vertex(i);
      pts.push_back({v.x, v.y, v.z});
      d.lo = std::min(d.lo, v.z), d.hi = std::max(d.hi, v.z);
    }
  }
  return d;
}

}  // namespace tinstream::bench
