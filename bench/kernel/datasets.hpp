// Data sets shared by the kernel benchmark (kernel_bench.cpp, against CGAL) and the stand-alone
// removal driver (removal_driver.cpp, for callgrind and A/B timing): the same points, the same
// victims, so that instruction counts and benchmark times describe the same work.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::bench {

using kernel::Point3;

inline std::vector<Point3> uniform(std::size_t n) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Point3> p(n);
  for (auto& q : p) q = {u(rng), u(rng), u(rng), 0.0};
  return p;
}

// LiDAR-like: parallel scan lines with along-track spacing, jitter and density changes, coordinates
// quantised to 1 cm like LAS integers (many exactly collinear / cocircular configurations), in
// metres within a few km, normalised to [0, 1] the way tiles are.
inline std::vector<Point3> lidar_like(std::size_t n) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.05);
  const double side = std::sqrt(double(n)) * 0.5;  // ~4 points per m^2
  std::vector<Point3> p;
  p.reserve(n);
  double y = 0.0;
  while (p.size() < n) {
    const double step = 0.4 + 0.2 * std::sin(y * 0.01);
    for (double x = u(rng) * step; x < side && p.size() < n; x += step) {
      const double px = std::round((x + g(rng)) * 100.0) / 100.0;
      const double py = std::round((y + g(rng) + 0.02 * x) * 100.0) / 100.0;
      p.push_back({px / side, py / side, 100.0 + 10.0 * std::sin(px * 0.05) + g(rng), 0.0});
    }
    y += 0.5;
    if (y > side) y = u(rng) * 0.5;  // second pass over the area (overlapping flight lines)
  }
  return p;
}

inline std::vector<Point3> autzen() {
  std::vector<Point3> out;
  std::ifstream f(std::string(TINSTREAM_SHARED_DATA) + "/autzen_trim.las", std::ios::binary);
  if (!f) return out;
  char h[227];
  if (!f.read(h, 227)) return out;
  std::uint32_t off, count;
  std::uint16_t len;
  double s[3], o[3];
  std::memcpy(&off, h + 96, 4);
  std::memcpy(&len, h + 105, 2);
  std::memcpy(&count, h + 107, 4);
  std::memcpy(s, h + 131, 24);
  std::memcpy(o, h + 155, 24);
  f.seekg(off);
  std::vector<char> rec(len);
  for (std::uint32_t i = 0; i < count && f.read(rec.data(), len); ++i) {
    std::int32_t X[3];
    std::memcpy(X, rec.data(), 12);
    out.push_back({X[0] * s[0] + o[0], X[1] * s[1] + o[1], X[2] * s[2] + o[2], 0.0});
  }
  return out;
}

// A square lattice of about n points in random order: every lattice cell is cocircular, so every
// removal resolves ties (removal_driver only; it checks that changes keep the tie resolution).
inline std::vector<Point3> lattice(std::size_t n) {
  const auto side = static_cast<std::size_t>(std::sqrt(double(n)));
  std::vector<Point3> p;
  p.reserve(side * side);
  for (std::size_t i = 0; i < side; ++i) {
    for (std::size_t j = 0; j < side; ++j) p.push_back({double(i), double(j), double(i + j), 0.0});
  }
  std::shuffle(p.begin(), p.end(), std::mt19937_64(11));
  return p;
}

inline const std::vector<Point3>& dataset(int kind, std::size_t n) {
  static std::map<std::pair<int, std::size_t>, std::vector<Point3>> cache;
  auto& v = cache[{kind, n}];
  if (v.empty()) {
    v = kind == 0 ? uniform(n) : kind == 1 ? lidar_like(n) : kind == 2 ? autzen() : lattice(n);
  }
  return v;
}
inline const char* const kKind[] = {"uniform", "lidar_like", "autzen", "lattice"};

// Both sides remove the same points (a fixed random half of the input, by input index) in the
// same order (input order: random for the uniform set, scan order for the LiDAR-like ones).
inline std::vector<std::size_t> removal_victims(std::size_t n) {
  std::vector<std::size_t> v;
  std::mt19937 rng(5);
  for (std::size_t i = 0; i < n; ++i) {
    if (rng() % 2) v.push_back(i);
  }
  return v;
}

}  // namespace tinstream::bench
