// The camera: poses, projection of known points, screen-space error, the frustum.
#include "tinstream/client/camera.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "test_geo.hpp"

namespace tinstream::client {
namespace {

using testing::ecef;

TEST(CameraPose, ParsesAndRejects) {
  auto p = parse_camera_pose("6.13,49.61,2500,30,-45");
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->lon, 6.13);
  EXPECT_EQ(p->lat, 49.61);
  EXPECT_EQ(p->height, 2500);
  EXPECT_EQ(p->heading, 30);
  EXPECT_EQ(p->pitch, -45);
  auto short_form = parse_camera_pose("1,2,3");
  ASSERT_TRUE(short_form.ok());
  EXPECT_EQ(short_form->pitch, -90);
  for (const char* bad :
       {"1,2", "a,b,c", "1,91,100", "200,0,10", "1,2,3,4,5,6", "1,2,nan", "1,2,3,0,-120", ""}) {
    auto r = parse_camera_pose(bad);
    EXPECT_FALSE(r.ok()) << bad;
    if (!r.ok()) {
      EXPECT_NE(r.error().message.find("camera"), std::string::npos);
    }
  }
}

TEST(Camera, PoseRoundTrips) {
  Camera c(800, 600, 60);
  for (const CameraPose p :
       {CameraPose{6.1, 49.6, 2500, 30, -45}, CameraPose{-123, 44, 10, 200, -5},
        CameraPose{170, -60, 1e6, 359, -80}}) {
    c.set_pose(p);
    const CameraPose q = c.pose();
    EXPECT_NEAR(q.lon, p.lon, 1e-9);
    EXPECT_NEAR(q.lat, p.lat, 1e-9);
    EXPECT_NEAR(q.height, p.height, 1e-6);
    EXPECT_NEAR(q.heading, p.heading, 1e-7);
    EXPECT_NEAR(q.pitch, p.pitch, 1e-7);
  }
}

TEST(Camera, LookingDownSeesThePointBelowAtTheImageCentre) {
  Camera c(640, 480, 60);
  c.set_pose({6.1, 49.6, 1000, 0, -90});
  const auto px = c.project(ecef(6.1, 49.6, 0));
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR((*px)[0], 320, 1e-6);
  EXPECT_NEAR((*px)[1], 240, 1e-6);
  // North is up in the image when heading is 0: a point north of it lies above the centre.
  const auto north = c.project(ecef(6.1, 49.601, 0));
  ASSERT_TRUE(north.has_value());
  EXPECT_LT((*north)[1], 240);
  EXPECT_NEAR((*north)[0], 320, 0.5);
  // Behind the camera there is no pixel.
  EXPECT_FALSE(c.project(ecef(6.1, 49.6, 5000)).has_value());
  // The ray through the centre is the forward direction.
  const Vec3 d = c.ray_direction(320, 240);
  EXPECT_NEAR(dot(d, c.forward()), 1.0, 1e-12);
}

TEST(Camera, ScreenSpaceErrorFollowsTheFormula) {
  Camera c(1000, 720, 60);
  // error × height / (distance × 2·tan(fov/2))
  const double expected = 4.0 * 720 / (1000.0 * 2 * std::tan(30 * std::numbers::pi / 180));
  EXPECT_NEAR(c.screen_space_error(4.0, 1000.0), expected, 1e-12);
  // Ten times the distance gives a tenth of the error.
  const double near_sse = c.screen_space_error(3.5, 250.0);
  const double far_sse = c.screen_space_error(3.5, 2500.0);
  EXPECT_NEAR(far_sse * 10, near_sse, 1e-12 * near_sse);
}

TEST(Camera, FrustumKeepsWhatIsAheadAndCullsWhatIsBehindOrAside) {
  Camera c(800, 600, 60);
  c.set_pose({0, 0, 10000, 0, -90});
  const Frustum f = c.frustum();
  const Obb below = Obb::from_aabb(rectangle_aabb({-0.01, -0.01, 0.01, 0.01}, 0, 10));
  EXPECT_TRUE(f.intersects(below));
  // 10 km up with a 60° field of view sees about ±5.8 km north-south; 1° (111 km) is outside.
  const Obb aside = Obb::from_aabb(rectangle_aabb({-0.01, 1, 0.01, 1.02}, 0, 10));
  EXPECT_FALSE(f.intersects(aside));
  const Obb behind = Obb::from_aabb(rectangle_aabb({-0.01, -0.01, 0.01, 0.01}, 20000, 20010));
  EXPECT_FALSE(f.intersects(behind));
}

TEST(Camera, RaysMeetTheEllipsoid) {
  const Vec3 origin{geo::kWgs84A + 1000, 0, 0};
  const auto hit = intersect_ellipsoid(origin, {-1, 0, 0});
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->x, geo::kWgs84A, 1e-6);
  EXPECT_FALSE(intersect_ellipsoid(origin, {1, 0, 0}).has_value());
  const auto raised = intersect_ellipsoid(origin, {-1, 0, 0}, 500);
  ASSERT_TRUE(raised.has_value());
  EXPECT_NEAR(raised->x, geo::kWgs84A + 500, 1e-6);
}

TEST(Camera, FramingPoseSeesTheRectangle) {
  Camera c(800, 600, 60);
  const geo::LonLatRect rect{6.0, 49.5, 6.2, 49.7};
  c.set_pose(framing_pose(rect, 300, c));
  for (const auto& [lon, lat] :
       {std::pair{6.0, 49.5}, std::pair{6.2, 49.7}, std::pair{6.1, 49.6}}) {
    const auto px = c.project(ecef(lon, lat, 300));
    ASSERT_TRUE(px.has_value());
    EXPECT_GT((*px)[0], 0);
    EXPECT_LT((*px)[0], 800);
    EXPECT_GT((*px)[1], 0);
    EXPECT_LT((*px)[1], 600);
  }
}

}  // namespace
}  // namespace tinstream::client
