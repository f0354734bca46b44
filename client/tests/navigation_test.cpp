// Camera navigation: what stays fixed under the cursor while panning, orbiting and zooming.
#include "tinstream/client/navigation.hpp"

#include <gtest/gtest.h>

#include "test_geo.hpp"

namespace tinstream::client {
namespace {

using testing::ecef;

Camera oblique() {
  Camera c(800, 600, 60);
  c.set_pose({6.1, 49.6, 3000, 20, -40});
  return c;
}

TEST(Navigation, ZoomKeepsTheTargetUnderTheCursor) {
  Camera c = oblique();
  const auto target = intersect_ellipsoid(c.position(), c.ray_direction(250, 400), 300);
  ASSERT_TRUE(target.has_value());
  const double before = length(*target - c.position());
  zoom_towards(c, *target, 0.5);
  const auto px = c.project(*target);
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR((*px)[0], 250, 1e-6);
  EXPECT_NEAR((*px)[1], 400, 1e-6);
  EXPECT_NEAR(length(*target - c.position()), before / 2, 1e-6);
}

TEST(Navigation, PanKeepsTheGrabbedPointUnderTheCursor) {
  Camera c = oblique();
  const auto grabbed = intersect_ellipsoid(c.position(), c.ray_direction(300, 350), 250);
  ASSERT_TRUE(grabbed.has_value());
  pan(c, *grabbed, 420, 300);
  const auto px = c.project(*grabbed);
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR((*px)[0], 420, 1e-3);
  EXPECT_NEAR((*px)[1], 300, 1e-3);
}

TEST(Navigation, OrbitTurnsAroundThePivotAndStaysAboveIt) {
  Camera c = oblique();
  const auto pivot = intersect_ellipsoid(c.position(), c.ray_direction(400, 300), 300);
  ASSERT_TRUE(pivot.has_value());
  const double distance = length(*pivot - c.position());
  const double heading = c.pose().heading;
  orbit(c, *pivot, 0.5, 0.2);
  EXPECT_NEAR(length(*pivot - c.position()), distance, 1e-6);
  const auto px = c.project(*pivot);
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR((*px)[0], 400, 1e-6);
  EXPECT_NEAR((*px)[1], 300, 1e-6);
  EXPECT_GT(std::abs(c.pose().heading - heading), 20);
  // Tilting far down to the pivot's horizon is refused: the camera stays above it.
  orbit(c, *pivot, 0, -2.0);
  const Vec3 up = enu_frame(6.1, 49.6)[2];
  EXPECT_GT(dot(c.position() - *pivot, up), 0);
}

TEST(Navigation, FlyKeepsHeadingAndPitchAndLookTurns) {
  Camera c(800, 600, 60);
  c.set_pose({6.1, 49.6, 3000, 90, -30});
  fly(c, 1000, 0, 0);
  const CameraPose p = c.pose();
  EXPECT_GT(p.lon, 6.1 + 0.01);
  EXPECT_NEAR(p.lat, 49.6, 1e-3);
  EXPECT_NEAR(p.heading, 90, 0.05);
  EXPECT_NEAR(p.pitch, -30, 1e-6);
  EXPECT_NEAR(p.height, 3000, 0.2);
  look(c, 30, -100);
  EXPECT_NEAR(c.pose().heading, 120, 0.05);
  EXPECT_NEAR(c.pose().pitch, -90, 1e-6);
}

TEST(Navigation, FlyToArrivesAndArcsOverLongDistances) {
  const CameraPose from{-120, 40, 5000, 0, -60}, to{6, 49, 5000, 0, -60};
  FlyTo flight(from, to, 2.0);
  ASSERT_TRUE(flight.active());
  const CameraPose mid = flight.advance(1.0);
  EXPECT_GT(mid.height, 1e6);  // up and over for an ocean crossing
  const CameraPose end = flight.advance(1.5);
  EXPECT_FALSE(flight.active());
  EXPECT_EQ(end.lon, 6);
  EXPECT_EQ(end.height, 5000);
}

}  // namespace
}  // namespace tinstream::client
