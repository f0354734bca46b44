// Imagery in the client without OpenGL (imagery.hpp): the ancestor sub-rectangle transform, the
// imagery entry of GET /layers, and the decoding of imagery payloads.
#include "tinstream/client/imagery.hpp"

#include <gtest/gtest.h>

#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {
namespace {

TEST(AncestorUv, TheSameTileIsTheIdentity) {
  const std::array<float, 4> uv = ancestor_uv({12, 2121, 1401}, {12, 2121, 1401});
  EXPECT_EQ(uv, (std::array<float, 4>{1, 1, 0, 0}));
}

TEST(AncestorUv, AChildIsAQuadrantAndAGrandchildASixteenth) {
  // 12/2121/1401 is the south-east child of 11/1060/700: x and y both odd.
  EXPECT_EQ(ancestor_uv({12, 2121, 1401}, {11, 1060, 700}),
            (std::array<float, 4>{0.5f, 0.5f, 0.5f, 0.5f}));
  // Two levels up (10/530/350): column 2121 − 4·530 = 1, row 1401 − 4·350 = 1.
  EXPECT_EQ(ancestor_uv({12, 2121, 1401}, {10, 530, 350}),
            (std::array<float, 4>{0.25f, 0.25f, 0.25f, 0.25f}));
  EXPECT_EQ(ancestor_uv({12, 2123, 1400}, {10, 530, 350}),
            (std::array<float, 4>{0.25f, 0.25f, 0.75f, 0.0f}));
}

const char* kLayers = R"({"layers": [], "imagery": [
  {"name": "ortho", "format": "webp", "projection": "spherical", "tile_size": 256,
   "bounds": {"west": 6.0, "south": 49.0, "east": 7.0, "north": 50.0},
   "min_level": 8, "max_level": 15, "tile_count": 12, "version": 3, "created_unix": 1700000000,
   "attribution": "test"}]})";

TEST(ImageryJson, TheNamedLayerIsReadWithMercatorBounds) {
  auto l = parse_imagery_json(kLayers, "ortho");
  ASSERT_TRUE(l) << l.error().message;
  EXPECT_EQ(l->kind, TileKind::imagery);
  EXPECT_EQ(l->image_format, "webp");
  EXPECT_EQ(l->min_level, 8u);
  EXPECT_EQ(l->max_level, 15u);
  EXPECT_EQ(l->version, 3);
  EXPECT_EQ(l->mercator_bounds.min_x, geo::NormalisedMercator::x_from_lon(6.0));
  EXPECT_LT(l->mercator_bounds.min_y, l->mercator_bounds.max_y);
}

TEST(ImageryDescription, FromAStoreRowKeepsEveryField) {
  store::ImageryInfo info;
  info.name = "ortho";
  info.projection = geo::Projection::ellipsoidal;
  info.format = "webp";
  info.mercator_bounds = {0.0333, 0.3131, 0.0389, 0.3205};
  info.bounds = {6.0, 49.0, 7.0, 50.0};
  info.min_level = 8;
  info.max_level = 15;
  info.tile_count = 12;
  info.version = 3;
  info.created_unix = 1700000000;
  info.attribution = "test";
  const LayerDescription l = from_imagery_info(info);
  EXPECT_EQ(l.kind, TileKind::imagery);
  EXPECT_EQ(l.name, "ortho");
  EXPECT_EQ(l.image_format, "webp");
  EXPECT_EQ(l.projection, geo::Projection::ellipsoidal);
  EXPECT_EQ(l.mercator_bounds.min_x, 0.0333);
  EXPECT_EQ(l.mercator_bounds.max_y, 0.3205);
  EXPECT_EQ(l.bounds.south, 49.0);
  EXPECT_EQ(l.bounds.east, 7.0);
  EXPECT_EQ(l.min_level, 8u);
  EXPECT_EQ(l.max_level, 15u);
  EXPECT_EQ(l.tile_count, 12u);
  EXPECT_EQ(l.cache_version(), "v3-1700000000");
  EXPECT_EQ(l.attribution, "test");
  EXPECT_TRUE(l.level_max_error.empty());  // imagery has no heights nor errors
}

TEST(ImageryJson, AnUnknownNameListsTheLayersThereAre) {
  auto l = parse_imagery_json(kLayers, "aerial");
  ASSERT_FALSE(l);
  EXPECT_EQ(l.error().code, ErrorCode::not_found);
  EXPECT_NE(l.error().message.find("ortho"), std::string::npos) << l.error().message;
  EXPECT_FALSE(parse_imagery_json(R"({"layers": []})", "ortho"));
  EXPECT_FALSE(parse_imagery_json("not json", "ortho"));
}

TEST(ImageryDecode, BadBytesAndNonSquareImagesNameTheTile) {
  LayerDescription layer;
  layer.name = "ortho";
  const TileKey key{TileKind::imagery, 0, {12, 2121, 1401}};
  const std::vector<std::uint8_t> junk{'n', 'o', 'p', 'e'};
  auto bad = decode_imagery_tile(junk, ContentEncoding::identity, layer, key);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("imagery tile 12/2121/1401"), std::string::npos);
  EXPECT_NE(bad.error().message.find("\"ortho\""), std::string::npos);

  auto png = imagery::encode(imagery::RgbaImage(8, 4), imagery::ImageFormat::png);
  ASSERT_TRUE(png);
  auto wide = decode_imagery_tile(*png, ContentEncoding::identity, layer, key);
  ASSERT_FALSE(wide);
  EXPECT_NE(wide.error().message.find("not square"), std::string::npos);

  auto square = imagery::encode(imagery::RgbaImage(4, 4), imagery::ImageFormat::png);
  ASSERT_TRUE(square);
  auto ok = decode_imagery_tile(*square, ContentEncoding::identity, layer, key);
  ASSERT_TRUE(ok) << ok.error().message;
  EXPECT_EQ(ok->width, 4u);
}

}  // namespace
}  // namespace tinstream::client
