// Scripted camera paths: parsing, interpolation, playback with waits.
#include "tinstream/client/camera_path.hpp"

#include <gtest/gtest.h>

namespace tinstream::client {
namespace {

constexpr const char* kPath = R"(# a flight
0   6.0,49.0,100000,0,-90
10  6.2,49.2,1000,90,-45   # down and turning
wait complete
5   6.4,49.2,1000,90,-30
)";

TEST(CameraPath, ParsesKeyframesWaitsAndComments) {
  auto p = parse_camera_path(kPath);
  ASSERT_TRUE(p.ok()) << p.error().message;
  ASSERT_EQ(p->steps.size(), 4u);
  EXPECT_TRUE(p->steps[2].wait_complete);
  EXPECT_EQ(p->steps[1].seconds, 10);
  EXPECT_EQ(p->steps[1].pose.heading, 90);
  EXPECT_EQ(p->duration(), 15);
}

TEST(CameraPath, ErrorsNameTheLine) {
  for (const auto& [text, line] :
       {std::pair{"0 1,2,3\nten 1,2,3\n", "line 2"}, std::pair{"wait complete\n", "line 1"},
        std::pair{"0 1,2,3\n\n1 1,2\n", "line 3"}, std::pair{"0 1,2,3\nwait forever\n", "line 2"},
        std::pair{"0 1,2,3 extra\n", "line 1"}}) {
    auto p = parse_camera_path(text);
    ASSERT_FALSE(p.ok()) << text;
    EXPECT_NE(p.error().message.find(line), std::string::npos) << p.error().message;
  }
  EXPECT_FALSE(parse_camera_path("# nothing\n").ok());
  EXPECT_FALSE(load_camera_path("/nonexistent/path.txt").ok());
}

TEST(CameraPath, InterpolatesTheShortWayAndHeightGeometrically) {
  const CameraPose a{179, 10, 1000, 350, -90}, b{-179, 20, 100000, 10, -30};
  const CameraPose mid = interpolate(a, b, 0.5);
  EXPECT_NEAR(std::abs(mid.lon), 180, 1e-9);
  EXPECT_NEAR(mid.lat, 15, 1e-12);
  EXPECT_NEAR(mid.height, 10000, 1e-6);
  EXPECT_NEAR(mid.heading, 0, 1e-9);
  EXPECT_NEAR(mid.pitch, -60, 1e-12);
  const CameraPose end = interpolate(a, b, 1.0);
  EXPECT_NEAR(end.lon, -179, 1e-9);
  EXPECT_NEAR(end.height, 100000, 1e-6);
}

TEST(PathPlayer, FliesWaitsForACompleteViewAndFinishes) {
  PathPlayer player(*parse_camera_path(kPath));
  EXPECT_EQ(player.advance(0, false).height, 100000);
  EXPECT_NEAR(player.advance(5, false).height, 10000, 1e-6);  // half way, geometrically
  EXPECT_EQ(player.advance(5, false).lon, 6.2);               // at the keyframe: waiting
  EXPECT_TRUE(player.waiting());
  EXPECT_EQ(player.advance(100, false).lon, 6.2);  // still waiting, however long
  EXPECT_EQ(player.advance(1, true).lon, 6.2);     // complete: the next segment starts now
  EXPECT_FALSE(player.waiting());
  EXPECT_NEAR(player.advance(2.5, false).lon, 6.3, 1e-12);
  EXPECT_FALSE(player.finished());
  EXPECT_EQ(player.advance(10, false).lon, 6.4);
  EXPECT_TRUE(player.finished());
}

}  // namespace
}  // namespace tinstream::client
