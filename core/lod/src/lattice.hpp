// A tile's interior points when they form a complete rectilinear lattice (gridded input: a DEM's
// cells, in any projection that keeps rows and columns straight, e.g. geographic → Web
// Mercator). Both thinning stages then scan a triangle's lattice cells row by row, like a
// rasteriser (Delatin does the same on its grid), instead of keeping every point filed under the
// triangle that contains it: no per-point bucket memory, no re-filing when triangles change.
// Internal to core/lod.
//
//   ys[H-1] ┬  ·   ·   ·   ·      cell (i, j) = point at (xs[i], ys[j]), index j × W + i;
//           │  ·   ·  /·\  ·      the triangle's cells are visited as one run of columns
//   ys[j]   ┼  ·   · / · \ ·  ←   [i0, i1] per row j (closed triangle, plus a millionth of a
//           │  ·   ·/__·__\·      cell: a point on an edge is visited from both sides)
//   ys[0]   ┴──┴───┴───┴───┴──
//             xs[0]        xs[W-1]
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "tinstream/kernel/mesh.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod::detail {

struct Lattice {
  std::vector<double> xs, ys;        // strictly ascending
  std::vector<double> z;             // by cell
  std::vector<double> weight;        // by cell; empty when every weight is 0
  std::vector<std::uint32_t> point;  // by cell: index into the list the lattice was found in

  std::size_t width() const { return xs.size(); }
  std::size_t cells() const { return z.size(); }
  double weight_of(std::size_t cell) const { return weight.empty() ? 0.0 : weight[cell]; }

  // First index of `axis` whose value is ≥ v (`axis.size()` when none); `scale` = 1 / the mean
  // spacing, for a first guess that is exact on a uniform lattice. (The guess truncates a
  // clamped non-negative value: std::floor is a library call on the baseline x86-64 target.)
  static std::size_t first_at_or_after(const std::vector<double>& axis, double scale, double v) {
    const auto n = static_cast<std::ptrdiff_t>(axis.size());
    auto i = guess(axis, scale, v) + 1;
    if (i > n) i = n;
    while (i > 0 && axis[static_cast<std::size_t>(i - 1)] >= v) --i;
    while (i < n && axis[static_cast<std::size_t>(i)] < v) ++i;
    return static_cast<std::size_t>(i);
  }
  // First index of `axis` whose value is > v.
  static std::size_t first_after(const std::vector<double>& axis, double scale, double v) {
    const auto n = static_cast<std::ptrdiff_t>(axis.size());
    auto i = guess(axis, scale, v) + 1;
    if (i > n) i = n;
    while (i > 0 && axis[static_cast<std::size_t>(i - 1)] > v) --i;
    while (i < n && axis[static_cast<std::size_t>(i)] <= v) ++i;
    return static_cast<std::size_t>(i);
  }
  // ⌊(v − axis[0]) · scale⌋ clamped to [0, axis.size()] (the index of the last value ≤ v on a
  // uniform lattice; 0 for NaN).
  static std::ptrdiff_t guess(const std::vector<double>& axis, double scale, double v) {
    const double x = (v - axis.front()) * scale;
    const auto n = static_cast<double>(axis.size());
    return static_cast<std::ptrdiff_t>(x > 0 ? (x < n ? x : n) : 0.0);
  }

  // Calls row(j, i0, i1) for every row j that meets the closed triangle (a, b, c) (any
  // orientation), with [i0, i1] its columns inside (i0 ≤ i1). Rows in ascending order.
  template <typename F>
  void for_each_run(const kernel::XY& a, kernel::XY b, kernel::XY c, F&& row,
                    const double* prefetch = nullptr) const {
    if ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x) < 0) std::swap(b, c);
    const kernel::XY v[3] = {a, b, c};
    const double y_lo = std::min({a.y, b.y, c.y}) - tol_y_;
    const double y_hi = std::max({a.y, b.y, c.y}) + tol_y_;
    const std::size_t j0 = first_at_or_after(ys, scale_y_, y_lo);
    const std::size_t j1 = first_after(ys, scale_y_, y_hi);
    // Counter-clockwise: the inside is left of every edge p → q, i.e. x ≤ the edge's x at y on
    // an upward edge and x ≥ it on a downward one (horizontal edges bound the rows only). A
    // triangle has one or two edges of each kind; the single one is taken twice, so that every
    // row is two evaluations per side without branches.
    double lx[2], ly[2], ls[2], rx[2], ry[2], rs[2];
    int nl = 0, nr = 0;
    for (int k = 0; k < 3; ++k) {
      const kernel::XY& p = v[k];
      const kernel::XY& q = v[k == 2 ? 0 : k + 1];
      const double dy = q.y - p.y;
      if (dy > 0) {
        rx[nr] = p.x, ry[nr] = p.y, rs[nr] = (q.x - p.x) / dy, ++nr;
      } else if (dy < 0) {
        lx[nl] = p.x, ly[nl] = p.y, ls[nl] = (q.x - p.x) / dy, ++nl;
      }
    }
    // (None of a kind: all three on one row, a degenerate triangle; that side is unbounded.)
    constexpr double kInf = std::numeric_limits<double>::infinity();
    if (nl == 0) lx[0] = -kInf, ly[0] = 0, ls[0] = 0, nl = 1;
    if (nr == 0) rx[0] = kInf, ry[0] = 0, rs[0] = 0, nr = 1;
    if (nl == 1) lx[1] = lx[0], ly[1] = ly[0], ls[1] = ls[0];
    if (nr == 1) rx[1] = rx[0], ry[1] = ry[0], rs[1] = rs[0];
    // The runs are found first, in batches, and their first cells in `prefetch` (the array the
    // caller reads by cell) requested together: the rows of a triangle lie far apart in memory,
    // and scanning them one by one waits for one cache miss after the other.
    constexpr std::size_t kBatch = 16;
    std::size_t run_j[kBatch], run_i0[kBatch], run_i1[kBatch], runs = 0;
    auto flush = [&] {
      if (prefetch) {
        for (std::size_t k = 0; k < runs; ++k) {
          __builtin_prefetch(prefetch + run_j[k] * xs.size() + run_i0[k]);
        }
      }
      for (std::size_t k = 0; k < runs; ++k) row(run_j[k], run_i0[k], run_i1[k]);
      runs = 0;
    };
    for (std::size_t j = j0; j < j1; ++j) {
      const double y = ys[j];
      const double lo = std::max(lx[0] + ls[0] * (y - ly[0]), lx[1] + ls[1] * (y - ly[1]));
      const double hi = std::min(rx[0] + rs[0] * (y - ry[0]), rx[1] + rs[1] * (y - ry[1]));
      if (!(lo <= hi + 2 * tol_x_)) continue;  // no column can be in [lo − tol, hi + tol]
      const std::size_t i0 = first_at_or_after(xs, scale_x_, lo - tol_x_);
      const std::size_t i1 = first_after(xs, scale_x_, hi + tol_x_);
      if (i0 < i1) {
        run_j[runs] = j, run_i0[runs] = i0, run_i1[runs] = i1 - 1;
        if (++runs == kBatch) flush();
      }
    }
    flush();
  }

  // First column whose x is ≥ x, first row whose y is ≥ y (width() / rows when none).
  std::size_t first_column_at_or_after(double x) const {
    return first_at_or_after(xs, scale_x_, x);
  }
  std::size_t first_row_at_or_after(double y) const { return first_at_or_after(ys, scale_y_, y); }

  // Sets the guesses and tolerances from xs and ys (find_lattice does it).
  void finish() {
    const auto mean = [](const std::vector<double>& a) {
      return a.size() > 1 ? (a.back() - a.front()) / static_cast<double>(a.size() - 1) : 1.0;
    };
    const double dx = mean(xs), dy = mean(ys);
    scale_x_ = 1.0 / dx, scale_y_ = 1.0 / dy;
    tol_x_ = 1e-6 * dx, tol_y_ = 1e-6 * dy;
  }

 private:
  double scale_x_ = 1, scale_y_ = 1, tol_x_ = 0, tol_y_ = 0;
};

// The lattice that `points` fill exactly once each (every column × row position present, no
// duplicate, finite), or nullopt. O(n) plus sorting one row and one column.
std::optional<Lattice> find_lattice(std::span<const tile::Vertex> points);

// The height of the triangle (a, b, c) as a + gx·(x − a.x) + gy·(y − a.y), for scanning.
struct Gradient {
  double ax, ay, az, gx, gy;
  Gradient(const kernel::XY& a, const kernel::XY& b, const kernel::XY& c, double za, double zb,
           double zc) {
    const double bx = b.x - a.x, by = b.y - a.y, cx = c.x - a.x, cy = c.y - a.y;
    const double dzb = zb - za, dzc = zc - za;
    const double inv = 1.0 / (bx * cy - by * cx);
    ax = a.x, ay = a.y, az = za;
    gx = (cy * dzb - by * dzc) * inv;
    gy = (bx * dzc - cx * dzb) * inv;
  }
};

// Largest |z − surface| over the lattice cells of the closed triangle (a, b, c) (0 when none).
inline double max_deviation(const Lattice& l, const kernel::XY& a, const kernel::XY& b,
                            const kernel::XY& c, double za, double zb, double zc) {
  const Gradient g(a, b, c, za, zb, zc);
  double worst = 0;
  const std::size_t w = l.width();
  auto scan_row = [&](std::size_t j, std::size_t i0, std::size_t i1) {
    const double gx = g.gx, ax = g.ax;
    const double base = g.az + g.gy * (l.ys[j] - g.ay);
    const double* z = l.z.data() + j * w;
    const double* x = l.xs.data();
    double row_worst = worst;
    for (std::size_t i = i0; i <= i1; ++i) {
      row_worst = std::max(row_worst, std::abs(z[i] - (base + gx * (x[i] - ax))));
    }
    worst = row_worst;
  };
  l.for_each_run(a, b, c, scan_row, l.z.data());
  return worst;
}

}  // namespace tinstream::lod::detail
