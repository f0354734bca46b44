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

// One layer object that both readers take: a terrain layer's document (GET /layers/{layer}) and
// an imagery entry of GET /layers carry the same shared metadata, plus what only their kind has.
std::string layer_object(const std::string& field, const std::string& value) {
  std::vector<std::pair<std::string, std::string>> fields{
      {"name", R"("ortho")"},
      {"projection", R"("spherical")"},
      {"bounds", R"({"west": 6.0, "south": 49.0, "east": 7.0, "north": 50.0})"},
      {"min_level", "8"},
      {"max_level", "15"},
      {"tile_count", "12"},
      {"version", "3"},
      {"created_unix", "1700000000"},
      {"attribution", R"("test")"},
      {"format", R"("webp")"},
      {"mercator_bounds", R"({"min_x": 0.03, "min_y": 0.31, "max_x": 0.04, "max_y": 0.32})"},
      {"min_z", "1"},
      {"max_z", "2"},
      {"level_max_error", "[1, 2]"}};
  std::string out = "{";
  for (const auto& [k, v] : fields) {
    if (k == field && value.empty()) continue;  // the field left out
    out += (out.size() > 1 ? ", \"" : "\"") + k + "\": " + (k == field ? value : v);
  }
  return out + "}";
}

TEST(ServerLayerJson, AMalformedSharedFieldIsTheSameErrorForTerrainAndImagery) {
  // Both readers take the object as it is; each broken shared field (left out where value is
  // empty) gives one message from both, naming the field and the layer.
  const std::vector<std::pair<std::string, std::string>> broken{{"projection", R"("conical")"},
                                                                {"projection", ""},
                                                                {"bounds", R"({"west": 6.0})"},
                                                                {"bounds", R"("everywhere")"},
                                                                {"min_level", R"("eight")"},
                                                                {"max_level", ""},
                                                                {"max_level", "3"},
                                                                {"tile_count", R"("many")"},
                                                                {"version", "[]"},
                                                                {"created_unix", R"("today")"},
                                                                {"attribution", "7"}};
  for (const auto& [field, value] : broken) {
    const std::string object = layer_object(field, value);
    auto terrain = parse_layers_json(R"({"layers": [)" + object + "]}");
    auto imagery = parse_imagery_json(R"({"layers": [], "imagery": [)" + object + "]}", "ortho");
    ASSERT_FALSE(terrain) << object;
    ASSERT_FALSE(imagery) << object;
    EXPECT_EQ(terrain.error().message, imagery.error().message) << object;
    EXPECT_EQ(terrain.error().code, imagery.error().code) << object;
    EXPECT_NE(terrain.error().message.find("\"ortho\""), std::string::npos)
        << terrain.error().message;
    // The field, or (max_level 3 < min_level 8) the levels.
    EXPECT_NE(
        terrain.error().message.find(field == "max_level" && !value.empty() ? "levels 8…3" : field),
        std::string::npos)
        << terrain.error().message;
  }
  // A name that is not a string: no layer to name, the same message still.
  const std::string nameless = layer_object("name", "5");
  auto terrain = parse_layers_json(R"({"layers": [)" + nameless + "]}");
  auto imagery = parse_imagery_json(R"({"imagery": [)" + nameless + "]}", "ortho");
  ASSERT_FALSE(terrain);
  ASSERT_FALSE(imagery);
  EXPECT_EQ(terrain.error().message, imagery.error().message);
  EXPECT_NE(terrain.error().message.find("\"name\""), std::string::npos);
  // The object itself still reads on both sides.
  EXPECT_TRUE(parse_layers_json(R"({"layers": [)" + layer_object("", "") + "]}"));
  EXPECT_TRUE(parse_imagery_json(R"({"imagery": [)" + layer_object("", "") + "]}", "ortho"));
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
