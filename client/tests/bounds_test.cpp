// Bounding volumes and the horizon: the exact rectangle box, fitted boxes, ellipsoid occlusion.
#include "tinstream/client/bounds.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "test_geo.hpp"

namespace tinstream::client {
namespace {

using testing::ecef;

TEST(RectangleAabb, ExtremesAtTheEquatorAndPrimeMeridianAreTheSemiMajorAxis) {
  // Spanning lon 0 and lat 0: the largest x is the equatorial radius plus the top height.
  const Aabb box = rectangle_aabb({-10, -5, 10, 5}, -50, 100);
  EXPECT_GE(box.max.x, geo::kWgs84A + 100);
  EXPECT_LE(box.max.x, geo::kWgs84A + 100 + 0.01);
  // The smallest x is at a corner with the lowest height: (lon ±10, lat ±5, h −50).
  EXPECT_LE(box.min.x, ecef(10, 5, -50).x);
  EXPECT_GE(box.min.x, ecef(10, 5, -50).x - 0.01);
  // Symmetric in y and z.
  EXPECT_NEAR(box.max.y, -box.min.y, 1e-6);
  EXPECT_NEAR(box.max.z, -box.min.z, 1e-6);
}

TEST(RectangleAabb, ContainsEveryPointOfRandomRectangles) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-85, 85), size(1e-6, 60), frac(0, 1);
  for (int trial = 0; trial < 300; ++trial) {
    double w = lon(rng), s = lat(rng);
    const double e = std::min(180.0, w + size(rng)), n = std::min(85.0, s + size(rng) / 2);
    const double h0 = -100 + 50 * frac(rng), h1 = h0 + 3000 * frac(rng);
    const Aabb box = rectangle_aabb({w, s, e, n}, h0, h1);
    // Corners, edge midpoints, the special longitudes and latitudes, and random points.
    std::vector<double> lons{w, e, (w + e) / 2}, lats{s, n, (s + n) / 2};
    for (double special : {-180.0, -90.0, 0.0, 90.0, 180.0})
      if (special >= w && special <= e) lons.push_back(special);
    if (s <= 0 && n >= 0) lats.push_back(0);
    for (int i = 0; i < 20; ++i) {
      lons.push_back(w + (e - w) * frac(rng));
      lats.push_back(s + (n - s) * frac(rng));
    }
    double extreme_x = -1e300;
    for (double lo : lons)
      for (double la : lats)
        for (double h : {h0, h1, (h0 + h1) / 2}) {
          const Vec3 p = ecef(lo, la, h);
          ASSERT_TRUE(box.contains(p)) << "rect " << w << "," << s << "," << e << "," << n
                                       << " point " << lo << "," << la << "," << h;
          extreme_x = std::max(extreme_x, p.x);
        }
    // Tight: the sampled points reach the box's largest x (to within the padding and sampling).
    EXPECT_LE(box.max.x - extreme_x, 1e-3 + 1e-6 * std::abs(extreme_x) + 1.0);
  }
}

TEST(RectangleObb, ContainsRandomPointsAndIsTighterThanTheAabb) {
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> lon(-180, 170), lat(-84, 84), frac(0, 1);
  std::uniform_real_distribution<double> log_size(-5, std::log10(29.0));
  for (int trial = 0; trial < 300; ++trial) {
    const double w = lon(rng), s = lat(rng);
    const double e = std::min(180.0, w + std::pow(10.0, log_size(rng)));
    const double n = std::min(85.0, s + std::pow(10.0, log_size(rng)));
    const double h0 = -400 + 300 * frac(rng), h1 = h0 + 4000 * frac(rng);
    const Obb box = rectangle_obb({w, s, e, n}, h0, h1);
    for (int i = 0; i < 400; ++i) {
      // Uniform inside, and on the edges and corners where the surface is farthest out.
      double lo = w + (e - w) * frac(rng), la = s + (n - s) * frac(rng);
      if (i % 4 == 1) lo = (i % 8 == 1) ? w : e;
      if (i % 4 == 2) la = (i % 8 == 2) ? s : n;
      const double h = i % 3 == 0 ? h0 : i % 3 == 1 ? h1 : h0 + (h1 - h0) * frac(rng);
      ASSERT_TRUE(box.contains(ecef(lo, la, h))) << "rect " << w << "," << s << "," << e << "," << n
                                                 << " point " << lo << "," << la << "," << h;
    }
  }
  // A level-14 sized tile (≈ 2.4 km): its box is the height range plus a few centimetres thick,
  // where the ECEF-aligned box of the same tile is kilometres thick.
  const geo::LonLatRect small{6.10, 49.60, 6.122, 49.614};
  const Obb tight = rectangle_obb(small, 200, 300);
  EXPECT_LT(tight.half[2], 50 + 0.5 + 0.2);  // 50 m of heights + the curvature drop (≈ 0.3 m)
  const Aabb loose = rectangle_aabb(small, 200, 300);
  EXPECT_GT(loose.max.z - loose.min.z, 1000);
}

TEST(Obb, FitContainsItsPointsAndMeasuresDistance) {
  const auto frame = enu_frame(6.1, 49.6);
  const Vec3 origin = ecef(6.1, 49.6, 300);
  std::vector<Vec3> pts;
  for (int i = -5; i <= 5; ++i)
    for (int j = -5; j <= 5; ++j)
      pts.push_back(origin + frame[0] * (i * 10.0) + frame[1] * (j * 7.0) +
                    frame[2] * (i * j * 0.5));
  const Obb box = fit_obb(pts, origin, frame);
  for (const Vec3& p : pts) EXPECT_TRUE(box.contains(p));
  EXPECT_NEAR(box.half[0], 50.0, 0.01);
  EXPECT_NEAR(box.half[1], 35.0, 0.01);
  EXPECT_NEAR(box.half[2], 12.5, 0.01);
  // 100 m straight above the box's top face.
  const Vec3 above = box.centre + frame[2] * (box.half[2] + 100.0);
  EXPECT_NEAR(box.distance_to(above), 100.0, 1e-6);
  EXPECT_EQ(box.distance_to(box.centre), 0.0);
  EXPECT_FALSE(box.contains(above));
}

TEST(HorizonOccluder, HidesWhatIsBeyondTheHorizonOnTheEquator) {
  // On the equator the ellipsoid's section is the circle of radius a: from height H the horizon
  // is at the central angle acos(a / (a + H)).
  const double H = 1e6;
  const double horizon = std::acos(geo::kWgs84A / (geo::kWgs84A + H)) * 180 / std::numbers::pi;
  const HorizonOccluder occluder(0.0);
  const Vec3 camera = ecef(0, 0, H);
  EXPECT_FALSE(occluder.hides(camera, ecef(0, 0, 1)));
  EXPECT_FALSE(occluder.hides(camera, ecef(horizon - 1, 0, 1)));
  EXPECT_TRUE(occluder.hides(camera, ecef(horizon + 1, 0, 0)));
  EXPECT_TRUE(occluder.hides(camera, ecef(180, 0, 0)));
  // A satellite high above a hidden point is visible over the horizon.
  EXPECT_FALSE(occluder.hides(camera, ecef(horizon + 1, 0, 1e7)));
  // Points inside the Earth are hidden; a camera inside hides nothing.
  EXPECT_TRUE(occluder.hides(camera, {0, 0, 0}));
  EXPECT_FALSE(occluder.hides({0, 0, 0}, ecef(180, 0, 0)));
}

TEST(HorizonOccluder, TileBeyondTheHorizonIsCulledAsABox) {
  const HorizonOccluder occluder(0.0);
  const Vec3 camera = ecef(0, 0, 1e6);
  const Obb behind = Obb::from_aabb(rectangle_aabb({40, -1, 41, 1}, 0, 500));
  const Obb near = Obb::from_aabb(rectangle_aabb({1, -1, 2, 1}, 0, 500));
  EXPECT_TRUE(occluder.hides_all(camera, behind.corners()));
  EXPECT_FALSE(occluder.hides_all(camera, near.corners()));
  // An occluder lowered by 2000 m (below deep terrain) no longer hides a point 1° past the
  // horizon of the unlowered ellipsoid at −1000 m... but does hide the far side.
  const HorizonOccluder lowered(2000.0);
  const double H = 1e6;
  const double horizon = std::acos(geo::kWgs84A / (geo::kWgs84A + H)) * 180 / std::numbers::pi;
  EXPECT_TRUE(occluder.hides(camera, ecef(horizon + 0.2, 0, -1000)));
  EXPECT_FALSE(lowered.hides(camera, ecef(horizon + 0.2, 0, -1000)));
  EXPECT_TRUE(lowered.hides(camera, ecef(180, 0, 0)));
}

}  // namespace
}  // namespace tinstream::client
