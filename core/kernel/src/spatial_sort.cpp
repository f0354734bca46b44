#include "spatial_sort.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace tinstream::kernel::detail {
namespace {

// Hilbert index of (x, y) on a 2^16 x 2^16 grid.
std::uint32_t hilbert_index(std::uint32_t x, std::uint32_t y) {
  std::uint32_t d = 0;
  for (std::uint32_t s = 1u << 15; s > 0; s >>= 1) {
    const std::uint32_t rx = (x & s) ? 1u : 0u;
    const std::uint32_t ry = (y & s) ? 1u : 0u;
    d += s * s * ((3u * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) {
        x = 65535u - x;  // flips the bits still to be read; higher ones no longer matter
        y = 65535u - y;
      }
      std::swap(x, y);
    }
  }
  return d;
}

std::uint64_t splitmix(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

std::vector<std::uint32_t> brio_hilbert_order(std::span<const Point3> points,
                                              const std::vector<std::uint32_t>& indices) {
  const std::size_t n = indices.size();
  if (n == 0) return {};
  double xmin = points[indices[0]].x, xmax = xmin, ymin = points[indices[0]].y, ymax = ymin;
  for (std::uint32_t i : indices) {
    xmin = std::min(xmin, points[i].x);
    xmax = std::max(xmax, points[i].x);
    ymin = std::min(ymin, points[i].y);
    ymax = std::max(ymax, points[i].y);
  }
  const double span = std::max(xmax - xmin, ymax - ymin);
  const double scale = span > 0.0 ? 65535.0 / span : 0.0;

  // Random round per point: the shuffled position k lands in round bit_width(k) - 6 (the last
  // round holds about half of the points, the one before a quarter, ...).
  std::vector<std::uint32_t> shuffled(indices);
  std::uint64_t state = 0x5EEDu;
  for (std::size_t k = n; k > 1; --k) {
    const std::size_t r = static_cast<std::size_t>(splitmix(state) % k);
    std::swap(shuffled[k - 1], shuffled[r]);
  }
  struct Keyed {
    std::uint64_t key;
    std::uint32_t index;
  };
  std::vector<Keyed> keyed(n), tmp(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t i = shuffled[k];
    const auto gx = static_cast<std::uint32_t>((points[i].x - xmin) * scale);
    const auto gy = static_cast<std::uint32_t>((points[i].y - ymin) * scale);
    const auto bw = static_cast<int>(std::bit_width(static_cast<std::uint64_t>(k)));
    const std::uint64_t round = bw > 6 ? static_cast<std::uint64_t>(bw - 6) : 0u;
    keyed[k] = {(round << 32) | hilbert_index(std::min(gx, 65535u), std::min(gy, 65535u)), i};
  }
  // LSD radix sort on the 40 significant key bits, 8 bits per pass.
  for (int shift = 0; shift < 40; shift += 8) {
    std::size_t count[257] = {};
    for (const Keyed& e : keyed) ++count[((e.key >> shift) & 0xFFu) + 1];
    for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
    for (const Keyed& e : keyed) tmp[count[(e.key >> shift) & 0xFFu]++] = e;
    keyed.swap(tmp);
  }
  std::vector<std::uint32_t> order(n);
  for (std::size_t k = 0; k < n; ++k) order[k] = keyed[k].index;
  return order;
}

}  // namespace tinstream::kernel::detail
