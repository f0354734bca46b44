// Layer metadata as the server sends it (README "Endpoints", GET /layers/{layer}).
#include "tinstream/client/layer.hpp"

#include <gtest/gtest.h>

#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {
namespace {

constexpr const char* kLayer = R"({
  "name": "dem", "projection": "ellipsoidal", "vertical_datum": "ellipsoidal",
  "bounds": {"west": -118.35, "south": 34.23, "east": -117.95, "north": 34.41},
  "mercator_bounds": {"min_x": -0.6575, "min_y": 0.2020, "max_x": -0.6553, "max_y": 0.2035},
  "min_level": 0, "max_level": 13, "max_points": 16384, "tile_count": 120, "point_count": 1,
  "source_points": 1, "min_z": 300.5, "max_z": 2100.25,
  "level_max_error": [900, 800, 700, 600, 500, 400, 300, 200, 100, 50, 25, 12, 6, 0],
  "attribution": "SRTM", "created_unix": 1764000000, "version": 7,
  "options": {}, "tiles": "/tiles/dem/{quadkey}", "terrain": null})";

TEST(LayerJson, ParsesTheServersLayerDocument) {
  auto l = parse_layer_json(kLayer);
  ASSERT_TRUE(l.ok()) << l.error().message;
  EXPECT_EQ(l->name, "dem");
  EXPECT_EQ(l->projection, geo::Projection::ellipsoidal);
  EXPECT_EQ(l->max_level, 13u);
  EXPECT_EQ(l->level_error(12), 6.0);
  EXPECT_EQ(l->level_error(40), 0.0);
  EXPECT_EQ(l->min_z, 300.5);
  EXPECT_EQ(l->bounds.north, 34.41);
  EXPECT_EQ(l->mercator_bounds.min_x, -0.6575);
  EXPECT_EQ(l->cache_version(), "v7-1764000000");
  auto list = parse_layers_json(std::string(R"({"layers": [)") + kLayer + "," + kLayer + "]}");
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->size(), 2u);
}

TEST(LayerJson, NamesWhatIsMissingOrWrong) {
  std::string missing = kLayer;
  missing.replace(missing.find("\"max_level\""), 11, "\"maxi_level\"");
  auto a = parse_layer_json(missing);
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.error().message.find("max_level"), std::string::npos);
  EXPECT_FALSE(parse_layer_json("not json").ok());
  EXPECT_FALSE(parse_layers_json(R"({"layer": []})").ok());
  std::string bad_projection = kLayer;
  bad_projection.replace(bad_projection.find("ellipsoidal"), 11, "conical");
  EXPECT_FALSE(parse_layer_json(bad_projection).ok());
}

TEST(LayerDescription, FromAStoreRowKeepsEveryField) {
  store::LayerInfo info;
  info.name = "dem";
  info.projection = geo::Projection::ellipsoidal;
  info.mercator_bounds = {-0.6575, 0.2020, -0.6553, 0.2035};
  info.bounds = {-118.35, 34.23, -117.95, 34.41};
  info.min_level = 2;
  info.max_level = 13;
  info.min_z = 300.5;
  info.max_z = 2100.25;
  info.level_max_error = {900, 800, 6};
  info.tile_count = 120;
  info.version = 7;
  info.created_unix = 1764000000;
  info.attribution = "SRTM";
  const LayerDescription l = from_store_info(info);
  EXPECT_EQ(l.kind, TileKind::terrain);
  EXPECT_EQ(l.name, "dem");
  EXPECT_EQ(l.projection, geo::Projection::ellipsoidal);
  EXPECT_EQ(l.mercator_bounds.min_x, -0.6575);
  EXPECT_EQ(l.mercator_bounds.max_y, 0.2035);
  EXPECT_EQ(l.bounds.west, -118.35);
  EXPECT_EQ(l.bounds.north, 34.41);
  EXPECT_EQ(l.min_level, 2u);
  EXPECT_EQ(l.max_level, 13u);
  EXPECT_EQ(l.min_z, 300.5);
  EXPECT_EQ(l.max_z, 2100.25);
  EXPECT_EQ(l.level_max_error, (std::vector<double>{900, 800, 6}));
  EXPECT_EQ(l.tile_count, 120u);
  EXPECT_EQ(l.cache_version(), "v7-1764000000");
  EXPECT_EQ(l.attribution, "SRTM");
}

TEST(LayerDescription, MayContainOnlyTilesOverItsDataAndLevels) {
  LayerDescription l;
  l.min_level = 3;
  l.max_level = 12;
  l.mercator_bounds = geo::TileId{12, 2121, 1401}.bounds();
  EXPECT_TRUE(l.may_contain({12, 2121, 1401}));
  EXPECT_TRUE(l.may_contain({12, 2122, 1401}));  // shares the east border: closed rectangles
  EXPECT_FALSE(l.may_contain({12, 2123, 1401}));
  EXPECT_TRUE(l.may_contain(geo::TileId{12, 2121, 1401}.parent()));
  EXPECT_FALSE(l.may_contain({13, 4242, 2802}));  // below the finest level
  EXPECT_FALSE(l.may_contain({2, 2, 1}));         // above the coarsest
}

}  // namespace
}  // namespace tinstream::client
