// Shared fixtures for the kernel tests: point generators (fixed seeds) and independent checks.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel::test {

// A named point set for the parameterised property suites.
struct Generator {
  const char* name;
  std::vector<Point3> (*make)();
};

// A gtest failure (fatal in the calling helper) when `t` fails check_valid at `level`.
inline void expect_valid(const Triangulation& t, CheckLevel level = CheckLevel::expensive) {
  const Status s = t.check_valid(level);
  ASSERT_TRUE(s.ok()) << s.error().message;
}

inline std::vector<Point3> uniform_points(std::size_t n, std::uint32_t seed, double lo = 0.0,
                                          double hi = 1.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<Point3> pts(n);
  for (auto& p : pts) {
    p.x = u(rng);
    p.y = u(rng);
    p.z = u(rng) * 100.0;
  }
  return pts;
}

inline std::vector<Point3> clustered_points(std::size_t n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.01);
  std::vector<Point3> centres(20);
  for (auto& c : centres) c = {u(rng), u(rng), 0.0, 0.0};
  std::vector<Point3> pts(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Point3& c = centres[i % centres.size()];
    pts[i] = {c.x + g(rng), c.y + g(rng), u(rng), 0.0};
  }
  return pts;
}

// A square lattice: every four neighbours are cocircular.
inline std::vector<Point3> lattice_points(int side, double step = 1.0) {
  std::vector<Point3> pts;
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) pts.push_back({i * step, j * step, double(i + j), 0.0});
  }
  return pts;
}

// Points on a circle (cocircular up to rounding) plus the exact lattice circle points.
inline std::vector<Point3> circle_points(std::size_t n) {
  std::vector<Point3> pts;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 2.0 * std::numbers::pi * double(i) / double(n);
    pts.push_back({std::cos(a), std::sin(a), double(i), 0.0});
  }
  // exactly cocircular: radius 5 circle through integer points
  const int c[][2] = {{5, 0},  {4, 3},   {3, 4},   {0, 5},  {-3, 4}, {-4, 3},
                      {-5, 0}, {-4, -3}, {-3, -4}, {0, -5}, {3, -4}, {4, -3}};
  for (auto& q : c) pts.push_back({double(q[0]) + 10.0, double(q[1]), 0.0, 0.0});
  return pts;
}

inline std::vector<Point3> collinear_points(std::size_t n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> u(0, 1 << 20);
  std::vector<Point3> pts(n);
  for (auto& p : pts) {
    const double t = u(rng);
    p = {0.25 + t * 0x1p-20, 0.5 + 3.0 * t * 0x1p-20, t, 0.0};  // exactly on y = 3x - 0.25
  }
  return pts;
}

inline std::vector<Point3> duplicate_heavy_points(std::size_t n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> u(0, 12);
  std::vector<Point3> pts(n);
  for (auto& p : pts) p = {u(rng) / 12.0, u(rng) / 12.0, double(u(rng)), 0.0};
  return pts;
}

// Points a few ulps apart around (1, 1) — normalised Mercator-like precision limits.
inline std::vector<Point3> ulp_points(std::size_t n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> u(0, 40);
  std::vector<Point3> pts(n);
  const double ulp = std::nextafter(1.0, 2.0) - 1.0;
  for (auto& p : pts) p = {1.0 + u(rng) * ulp, 1.0 + u(rng) * ulp, 1.0, 0.0};
  return pts;
}

// Coordinates ~0.6 with spacing ~1e-9 (a finest normalised-Mercator tile).
inline std::vector<Point3> mercator_tile_points(std::size_t n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Point3> pts(n);
  for (auto& p : pts) p = {0.6 + 1e-7 * u(rng), -0.3 + 1e-7 * u(rng), 100.0 * u(rng), 0.0};
  return pts;
}

inline std::vector<Point3> scaled(std::vector<Point3> pts, double s, double off) {
  for (auto& p : pts) {
    p.x = p.x * s + off;
    p.y = p.y * s + off;
  }
  return pts;
}

inline VertexTriple sorted(VertexTriple t) {
  std::sort(t.begin(), t.end());
  return t;
}

// Area of the convex hull of the distinct points (monotone chain, long double).
inline long double hull_area(std::vector<Point3> pts) {
  std::sort(pts.begin(), pts.end(), [](const Point3& a, const Point3& b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
  });
  auto cross = [](const Point3& o, const Point3& a, const Point3& b) {
    return (long double)(a.x - o.x) * (b.y - o.y) - (long double)(a.y - o.y) * (b.x - o.x);
  };
  std::vector<Point3> h(2 * pts.size() + 1);
  std::size_t k = 0;
  for (const Point3& p : pts) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p) <= 0) --k;
    h[k++] = p;
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(h[k - 2], h[k - 1], pts[i]) <= 0) --k;
    h[k++] = pts[i];
  }
  long double a = 0;  // shoelace relative to h[0] (no cancellation for tiny extents)
  for (std::size_t i = 1; i + 1 < k; ++i) a += cross(h[0], h[i], h[i + 1]);
  return a / 2;
}

inline long double triangle_area_sum(const Triangulation& tri) {
  long double a = 0;
  tri.for_each_finite_triangle([&](TriangleId, const Triangle& t) {
    const XY &p = tri.xy(t.v[0]), &q = tri.xy(t.v[1]), &r = tri.xy(t.v[2]);
    a += ((long double)(q.x - p.x) * (r.y - p.y) - (long double)(q.y - p.y) * (r.x - p.x)) / 2;
  });
  return a;
}

inline std::size_t distinct_count(const std::vector<Point3>& pts) {
  std::set<std::pair<double, double>> s;
  for (const auto& p : pts) s.insert({p.x, p.y});
  return s.size();
}

// Minimal LAS 1.x reader (x, y, z only) for the real-data tests.
inline bool read_las_xyz(const std::string& path, std::vector<Point3>& out) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  std::vector<char> head(227);
  if (!f.read(head.data(), 227)) return false;
  auto u32 = [&](std::size_t o) {
    std::uint32_t v;
    std::memcpy(&v, head.data() + o, 4);
    return v;
  };
  auto u16 = [&](std::size_t o) {
    std::uint16_t v;
    std::memcpy(&v, head.data() + o, 2);
    return v;
  };
  auto f64 = [&](std::size_t o) {
    double v;
    std::memcpy(&v, head.data() + o, 8);
    return v;
  };
  const std::uint32_t offset = u32(96), count = u32(107);
  const std::uint16_t reclen = u16(105);
  const double sx = f64(131), sy = f64(139), sz = f64(147), ox = f64(155), oy = f64(163),
               oz = f64(171);
  f.seekg(offset);
  std::vector<char> rec(reclen);
  out.clear();
  out.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    if (!f.read(rec.data(), reclen)) return false;
    std::int32_t X, Y, Z;
    std::memcpy(&X, rec.data(), 4);
    std::memcpy(&Y, rec.data() + 4, 4);
    std::memcpy(&Z, rec.data() + 8, 4);
    out.push_back({X * sx + ox, Y * sy + oy, Z * sz + oz, 0.0});
  }
  return true;
}

inline std::string autzen_path() { return std::string(TINSTREAM_SHARED_DATA) + "/autzen_trim.las"; }

}  // namespace tinstream::kernel::test
