#include "tinstream/geo/ecef.hpp"

#include <gtest/gtest.h>

#include <random>

namespace tinstream::geo {
namespace {

TEST(Ecef, EquatorAndPoleKnownValues) {
  const Ecef origin = to_ecef({0, 0, 0});
  EXPECT_NEAR(origin.x, kWgs84A, 1e-9);
  EXPECT_NEAR(origin.y, 0, 1e-9);
  EXPECT_NEAR(origin.z, 0, 1e-9);
  const Ecef pole = to_ecef({0, 90, 0});
  EXPECT_NEAR(pole.z, 6356752.314245179, 1e-6);  // b = a(1 − f)
  const Ecef east = to_ecef({90, 0, 100});
  EXPECT_NEAR(east.y, kWgs84A + 100, 1e-9);
}

TEST(Ecef, RoundTripRandomPoints) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90), h(-500, 9000);
  for (int i = 0; i < 100000; ++i) {
    const Geodetic g{lon(rng), lat(rng), h(rng)};
    const Geodetic back = from_ecef(to_ecef(g));
    ASSERT_NEAR(back.lat, g.lat, 1e-11);
    if (std::abs(g.lat) < 89.9) {
      ASSERT_NEAR(back.lon, g.lon, 1e-11);
    }
    ASSERT_NEAR(back.height, g.height, 1e-6);
  }
}

}  // namespace
}  // namespace tinstream::geo
