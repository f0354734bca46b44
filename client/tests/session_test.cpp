// open_session (viewer.hpp) on a real store: what it tells the user beside the layers.
#include <gtest/gtest.h>

#include "synthetic_store.hpp"
#include "tinstream/client/viewer.hpp"
#include "tinstream/imagery/image.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {
namespace {

using testing::SyntheticLayer;
using testing::TempDir;

// A terrain layer "synth" in `terrain` projection and an imagery layer "ortho" in `imagery`
// projection over the same ground (one plain tile at each level of the terrain's root).
std::filesystem::path write_store(const TempDir& dir, geo::Projection terrain,
                                  geo::Projection imagery) {
  std::filesystem::path path = dir.path / "s.db";
  SyntheticLayer layer = testing::default_layer();
  layer.projection = terrain;
  testing::write_layer(path, layer);
  store::ImageryInfo info;
  info.name = "ortho";
  info.projection = imagery;
  info.format = "png";
  info.min_level = info.max_level = 10;
  auto png = imagery::encode(imagery::RgbaImage(256, 256), imagery::ImageFormat::png);
  if (!png) throw std::runtime_error(png.error().message);
  testing::write_imagery(path, "synth", info, {{10, 530, 350}},
                         [&](const geo::TileId&) { return std::optional{*png}; });
  return path;
}

Result<Session> open(const std::filesystem::path& store) {
  ViewerOptions o;
  o.store = store;
  o.layers = {"synth"};
  o.imagery = "ortho";
  o.threads = 1;
  return open_session(o);
}

// Imagery is draped tile for tile on its own quadtree: an ellipsoidal terrain layer under
// spherical imagery shows the colour ramp, which the user is told instead of finding it out.
TEST(Session, ImageryOnAnotherMercatorThanTheTerrainIsAWarningNamingBoth) {
  TempDir dir("session_projection");
  auto s = open(write_store(dir, geo::Projection::ellipsoidal, geo::Projection::spherical));
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(s->warnings.size(), 1u);
  const std::string& w = s->warnings.front();
  for (const char* word : {"\"ortho\"", "\"synth\"", "spherical", "ellipsoidal", "colour ramp",
                           "--projection ellipsoidal"})
    EXPECT_NE(w.find(word), std::string::npos) << "'" << word << "' missing from: " << w;
  EXPECT_NE(s->legend.footer.find("not over synth"), std::string::npos) << s->legend.footer;
}

TEST(Session, ImageryOnTheTerrainsMercatorGivesNoWarning) {
  for (const geo::Projection p : {geo::Projection::spherical, geo::Projection::ellipsoidal}) {
    TempDir dir(std::string("session_same_") + std::string(geo::to_string(p)));
    auto s = open(write_store(dir, p, p));
    ASSERT_TRUE(s.ok()) << s.error().message;
    EXPECT_TRUE(s->warnings.empty()) << s->warnings.front();
    EXPECT_EQ(s->legend.footer.find("not over"), std::string::npos) << s->legend.footer;
  }
}

}  // namespace
}  // namespace tinstream::client
