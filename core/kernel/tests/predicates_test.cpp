#include "tinstream/kernel/predicates.hpp"

#include <gmpxx.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace tinstream::kernel {
namespace {

int exact_orient(const XY& a, const XY& b, const XY& c) {
  const mpq_class ax(a.x), ay(a.y), bx(b.x), by(b.y), cx(c.x), cy(c.y);
  const mpq_class det = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx);
  return sgn(det);
}

int exact_incircle(const XY& a, const XY& b, const XY& c, const XY& d) {
  const mpq_class adx = mpq_class(a.x) - d.x, ady = mpq_class(a.y) - d.y;
  const mpq_class bdx = mpq_class(b.x) - d.x, bdy = mpq_class(b.y) - d.y;
  const mpq_class cdx = mpq_class(c.x) - d.x, cdy = mpq_class(c.y) - d.y;
  const mpq_class det = (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy) +
                        (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy) +
                        (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady);
  return sgn(det);
}

int naive_orient(const XY& a, const XY& b, const XY& c) {
  return sign((a.x - c.x) * (b.y - c.y) - (a.y - c.y) * (b.x - c.x));
}

// Shewchuk's classic picture: a 256 x 256 grid of ulp steps around (0.5, 0.5) tested against the
// line through (12, 12) and (24, 24). The naive formula gets many signs wrong.
TEST(Predicates, Orient2dNearCollinearUlpGridMatchesExactSign) {
  int naive_wrong = 0;
  for (int i = 0; i < 256; ++i) {
    for (int j = 0; j < 256; ++j) {
      const XY a{0.5 + i * 0x1p-53, 0.5 + j * 0x1p-53};
      const XY b{12.0, 12.0}, c{24.0, 24.0};
      const int ex = exact_orient(a, b, c);
      ASSERT_EQ(sign(orient2d(a, b, c)), ex) << i << "," << j;
      ASSERT_EQ(sign(orient2d(b, c, a)), ex);
      ASSERT_EQ(sign(orient2d(c, a, b)), ex);
      ASSERT_EQ(sign(orient2d(b, a, c)), -ex);
      if (naive_orient(a, b, c) != ex) ++naive_wrong;
    }
  }
  EXPECT_GT(naive_wrong, 0) << "the input was not adversarial enough to need the exact path";
}

TEST(Predicates, Orient2dMercatorTileScaleMatchesExactSign) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 20000; ++k) {
    const XY a{0.73 + 1e-9 * u(rng), 0.41 + 1e-9 * u(rng)};
    const XY b{0.73 + 1e-9 * u(rng), 0.41 + 1e-9 * u(rng)};
    const double t = u(rng);
    // c nearly on a-b, then nudged by 0..3 ulps
    XY c{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
    for (int s = 0; s < k % 4; ++s) c.x = std::nextafter(c.x, 2.0);
    ASSERT_EQ(sign(orient2d(a, b, c)), exact_orient(a, b, c)) << k;
  }
}

TEST(Predicates, Orient2dHugeAndTinyCoordinatesMatchExactSign) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double scale : {1e-40, 1e-12, 1e12, 1e40}) {
    for (int k = 0; k < 5000; ++k) {
      const XY a{scale * u(rng), scale * u(rng)}, b{scale * u(rng), scale * u(rng)};
      const double t = u(rng);
      XY c{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
      if (k % 2) c.y = std::nextafter(c.y, 0.0);
      ASSERT_EQ(sign(orient2d(a, b, c)), exact_orient(a, b, c)) << scale << " " << k;
    }
  }
}

TEST(Predicates, Orient2dPointsOneUlpApart) {
  const double x = 1.0, x1 = std::nextafter(1.0, 2.0), x2 = std::nextafter(x1, 2.0);
  EXPECT_EQ(sign(orient2d({x, x}, {x1, x1}, {x2, x2})), 0);
  EXPECT_EQ(sign(orient2d({x, x}, {x1, x}, {x, x1})), 1);
  EXPECT_EQ(sign(orient2d({x, x}, {x, x1}, {x1, x})), -1);
  EXPECT_EQ(sign(orient2d({x, x}, {x2, x1}, {x1, x1})), exact_orient({x, x}, {x2, x1}, {x1, x1}));
}

TEST(Predicates, IncircleExactlyCocircularLatticeIsZero) {
  EXPECT_EQ(incircle({0, 0}, {1, 0}, {1, 1}, {0, 1}), 0.0);
  EXPECT_EQ(incircle({5, 0}, {4, 3}, {-3, 4}, {0, -5}), 0.0);
  EXPECT_GT(incircle({0, 0}, {2, 0}, {0, 2}, {1, 1}), 0.0);
  EXPECT_LT(incircle({0, 0}, {2, 0}, {0, 2}, {3, 3}), 0.0);
}

TEST(Predicates, IncircleNearCocircularMatchesExactSign) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 2.0 * 3.141592653589793);
  for (double r : {1e-9, 1.0, 1e9}) {
    for (double off : {0.0, 0.75, 1e6}) {
      for (int k = 0; k < 3000; ++k) {
        XY p[4];
        for (auto& q : p) {
          const double a = u(rng);
          q = {off + r * std::cos(a), off + r * std::sin(a)};
        }
        for (int s = 0; s < k % 3; ++s) p[3].x = std::nextafter(p[3].x, 1e300);
        const int ex = exact_incircle(p[0], p[1], p[2], p[3]);
        ASSERT_EQ(sign(incircle(p[0], p[1], p[2], p[3])), ex) << r << " " << off << " " << k;
        ASSERT_EQ(sign(incircle(p[1], p[0], p[2], p[3])), -ex);
      }
    }
  }
}

TEST(Predicates, IncircleMercatorTileScaleMatchesExactSign) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 20000; ++k) {
    XY p[4];
    for (auto& q : p)
      q = {0.3 + 1e-9 * std::floor(u(rng) * 16.0), -0.2 + 1e-9 * std::floor(u(rng) * 16.0)};
    p[3].y = std::nextafter(p[3].y, double(k % 2));
    ASSERT_EQ(sign(incircle(p[0], p[1], p[2], p[3])), exact_incircle(p[0], p[1], p[2], p[3])) << k;
  }
}

TEST(Predicates, IncircleHugeAndTinyCoordinatesMatchExactSign) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double scale : {1e-30, 1e30}) {
    for (int k = 0; k < 3000; ++k) {
      XY p[4];
      // lattice points (cocircular quadruples are common) kept away from 0 so that a one-ulp
      // nudge stays a normal number
      for (auto& q : p)
        q = {scale * (20.0 + std::round(u(rng) * 8.0)), scale * (20.0 + std::round(u(rng) * 8.0))};
      p[3].x = std::nextafter(p[3].x, (k % 2) ? 1e300 : -1e300);
      ASSERT_EQ(sign(incircle(p[0], p[1], p[2], p[3])), exact_incircle(p[0], p[1], p[2], p[3]));
    }
  }
}

TEST(Predicates, IncircleOneUlpApartMatchesExactSign) {
  const double e = std::nextafter(1.0, 2.0) - 1.0;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      const XY a{1.0, 1.0}, b{1.0 + 4 * e, 1.0}, c{1.0 + 4 * e, 1.0 + 4 * e};
      const XY d{1.0 + i * e, 1.0 + j * e};
      ASSERT_EQ(sign(incircle(a, b, c, d)), exact_incircle(a, b, c, d)) << i << "," << j;
    }
  }
}

// The exact stages themselves (not only through the filter), on lattices whose coordinate
// differences are exact — the short path of incircle_exact / orient2d_exact — and on the same
// points nudged by one ulp so that some differences are inexact (the general path). Lattice steps
// of 2^-k at Mercator tile scale, big offsets, and integer lattices: many exactly cocircular and
// collinear tuples, all against GMP.
TEST(Predicates, ExactStagesOnLatticesMatchGmp) {
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> cell(-6, 6);
  std::uniform_int_distribution<int> coin(0, 3);
  struct Lattice {
    double ox, oy, step;
  };
  const Lattice lattices[] = {{0.3, -0.2, 0x1p-30},
                              {0.0, 0.0, 1.0},
                              {1e6, -3e5, 0.25},
                              {-0.75, 0.5, 0x1p-40},
                              {12345.0, 678.0, 3.0}};
  int cocircular = 0, collinear = 0;
  for (const auto& l : lattices) {
    for (int k = 0; k < 6000; ++k) {
      XY p[4];
      for (auto& q : p) q = {l.ox + l.step * cell(rng), l.oy + l.step * cell(rng)};
      if (coin(rng) == 0) p[3].x = std::nextafter(p[3].x, 1e300);  // an inexact difference
      if (coin(rng) == 0) p[0].y = std::nextafter(p[0].y, -1e300);
      const int in = exact_incircle(p[0], p[1], p[2], p[3]);
      ASSERT_EQ(sign(detail::incircle_exact(p[0], p[1], p[2], p[3])), in) << k;
      ASSERT_EQ(sign(detail::incircle_exact(p[1], p[0], p[2], p[3])), -in) << k;
      const int on = exact_orient(p[0], p[1], p[2]);
      ASSERT_EQ(sign(detail::orient2d_exact(p[0], p[1], p[2])), on) << k;
      ASSERT_EQ(sign(detail::orient2d_exact(p[1], p[0], p[2])), -on) << k;
      cocircular += in == 0 && on != 0;
      collinear += on == 0;
    }
  }
  // Axis-parallel rectangles (cocircular by comparisons alone) with uneven sides, as the rows of
  // a DEM in Mercator, in every vertex order; and near-rectangles one ulp off, which are not.
  for (int k = 0; k < 2000; ++k) {
    const double x0 = 0.3 + 0x1p-30 * cell(rng), y0 = -0.2 + 0x1p-31 * cell(rng);
    const double x1 = x0 + 0x1p-30 * (1 + coin(rng)), y1 = y0 + 1e-9 * (1 + coin(rng));
    XY p[4] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
    if (k % 3 == 1) p[2].x = std::nextafter(p[2].x, 1e300);
    if (k % 3 == 2) p[3].y = std::nextafter(p[3].y, -1e300);
    std::shuffle(std::begin(p), std::end(p), rng);
    ASSERT_EQ(sign(detail::incircle_exact(p[0], p[1], p[2], p[3])),
              exact_incircle(p[0], p[1], p[2], p[3]))
        << k;
    if (k % 3 == 0) {
      ASSERT_EQ(exact_incircle(p[0], p[1], p[2], p[3]), 0);
    }
  }
  // The inputs really are degenerate often (the reason the exact stages exist).
  EXPECT_GT(cocircular, 300);
  EXPECT_GT(collinear, 500);
}

}  // namespace
}  // namespace tinstream::kernel
