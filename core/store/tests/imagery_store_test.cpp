// The imagery tables of the tile store: publish protocol, independence from terrain layers,
// files written before imagery existed.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "store_test_util.hpp"
#include "tinstream/store/etag.hpp"

namespace tinstream::store {
namespace {

using testing::basic_info;
using testing::sql_value;
using testing::TempDir;

TileStore open_store(const std::filesystem::path& p, TileStore::Mode mode) {
  auto s = TileStore::open(p, mode);
  if (!s) throw std::runtime_error(s.error().message);
  return std::move(*s);
}

ImageryInfo imagery_info(const std::string& name, const std::string& format = "png") {
  ImageryInfo info;
  info.name = name;
  info.format = format;
  info.mercator_bounds = {-0.5, -0.25, 0.5, 0.25};
  info.bounds = {-90, -22.0, 90, 22.0};
  info.min_level = 0;
  info.max_level = 3;
  info.options_json = R"({"resampling":"bilinear"})";
  info.attribution = "test imagery";
  return info;
}

// Bytes that stand for an encoded image (the store does not look inside).
StoredImage image(const geo::TileId& id, std::uint8_t seed, std::size_t size = 300) {
  StoredImage out;
  out.id = id;
  out.data.resize(size);
  for (std::size_t i = 0; i < size; ++i) {
    out.data[i] = static_cast<std::uint8_t>(std::size_t{seed} * 31 + i * 7 + std::size_t{id.x} * 3 +
                                            id.y + id.z);
  }
  return out;
}

void publish_imagery(TileStore& store, const ImageryInfo& info, std::uint8_t seed,
                     const std::vector<geo::TileId>& ids) {
  auto writer = store.begin_imagery(info);
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  for (const auto& id : ids) ASSERT_TRUE((*writer)->put(image(id, seed)).ok());
  const Status s = (*writer)->publish(info);
  ASSERT_TRUE(s.ok()) << s.error().message;
}

void publish_terrain(TileStore& store, const std::string& name) {
  auto writer = store.begin_layer(basic_info(name));
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  std::mt19937_64 rng(7);
  for (const geo::TileId id : {geo::TileId{0, 0, 0}, geo::TileId{1, 0, 1}, geo::TileId{1, 1, 1}}) {
    ASSERT_TRUE((*writer)->put(tile::testing::make_grid_tile(id, 3, 4, rng)).ok());
  }
  ASSERT_TRUE((*writer)->publish(basic_info(name)).ok());
}

const std::vector<geo::TileId> kIds = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {2, 1, 1}, {3, 2, 3}};

TEST(ImageryStore, PublishMakesTilesVisibleWithContentEtags) {
  TempDir dir;
  auto store = open_store(dir / "s.db", TileStore::Mode::read_write);
  auto writer = store.begin_imagery(imagery_info("ortho", "webp"));
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  for (const auto& id : kIds) ASSERT_TRUE((*writer)->put(image(id, 1)).ok());
  // Readable through the writer, invisible to readers until publish.
  auto own = (*writer)->get(kIds[3]);
  ASSERT_TRUE(own.ok() && own->has_value());
  EXPECT_EQ((*own)->data, image(kIds[3], 1).data);
  auto other = open_store(dir / "s.db", TileStore::Mode::read_only);
  EXPECT_EQ(other.imagery_layer("ortho").error().code, ErrorCode::not_found);
  EXPECT_TRUE(other.imagery_layers()->empty());
  ImageryInfo published = imagery_info("ortho", "webp");
  // Eight different bounds, so that two columns bound in each other's place are seen.
  published.mercator_bounds = {-0.5, -0.125, 0.375, 0.25};
  published.bounds = {-80.5, -22.0, 90.0, 33.25};
  ASSERT_TRUE((*writer)->publish(published).ok());

  auto layers = other.imagery_layers();
  ASSERT_TRUE(layers.ok()) << layers.error().message;
  ASSERT_EQ(layers->size(), 1u);
  EXPECT_EQ((*layers)[0].name, "ortho");
  EXPECT_EQ((*layers)[0].format, "webp");
  EXPECT_EQ((*layers)[0].tile_count, kIds.size());
  EXPECT_EQ((*layers)[0].max_level, 3u);
  EXPECT_EQ((*layers)[0].attribution, "test imagery");
  EXPECT_GT((*layers)[0].created_unix, 0);
  const geo::MercatorRect& m = (*layers)[0].mercator_bounds;
  const geo::LonLatRect& g = (*layers)[0].bounds;
  EXPECT_TRUE(m.min_x == -0.5 && m.min_y == -0.125 && m.max_x == 0.375 && m.max_y == 0.25);
  EXPECT_TRUE(g.west == -80.5 && g.south == -22.0 && g.east == 90.0 && g.north == 33.25);
  for (const auto& id : kIds) {
    auto t = other.imagery_tile("ortho", id);
    ASSERT_TRUE(t.ok()) << t.error().message;
    ASSERT_TRUE(t->has_value()) << id.to_string();
    EXPECT_EQ((*t)->data, image(id, 1).data);
    EXPECT_EQ((*t)->etag, make_etag(image(id, 1).data));
  }
  auto absent = other.imagery_tile("ortho", {3, 0, 0});
  ASSERT_TRUE(absent.ok());
  EXPECT_FALSE(absent->has_value());
  EXPECT_EQ(other.imagery_tile("nothing", {0, 0, 0}).error().code, ErrorCode::not_found);
  auto ids = other.imagery_tile_ids("ortho", 1);
  ASSERT_TRUE(ids.ok());
  EXPECT_EQ(*ids, (std::vector<geo::TileId>{{1, 0, 0}, {1, 1, 0}}));
  // Visible in the inspection view with the Bing quadkey.
  EXPECT_EQ(
      sql_value(dir / "s.db", "SELECT quadkey || ' ' || format FROM published_imagery WHERE z = 3"),
      "032 webp");
}

TEST(ImageryStore, ReplacingImageryLeavesTerrainUntouchedAndBack) {
  TempDir dir;
  auto store = open_store(dir / "s.db", TileStore::Mode::read_write);
  publish_terrain(store, "dem");
  publish_imagery(store, imagery_info("dem"), 1, kIds);
  const auto terrain_state = [&] {
    return sql_value(dir / "s.db",
                     "SELECT group_concat(version || ':' || z || '/' || x || '/' || y || '=' || "
                     "etag, ' ') FROM (SELECT * FROM tiles ORDER BY version, z, x, y)");
  };
  const auto imagery_state = [&] {
    return sql_value(dir / "s.db",
                     "SELECT group_concat(version || ':' || z || '/' || x || '/' || y || '=' || "
                     "etag, ' ') FROM (SELECT * FROM imagery_tiles ORDER BY version, z, x, y)");
  };
  const std::string terrain_before = terrain_state();
  const auto terrain_version = store.layer("dem")->version;
  ASSERT_NE(terrain_before.find("0/0/0="), std::string::npos) << terrain_before;

  // Replace the imagery (other content, fewer tiles) and delete it: the terrain stays as it was.
  publish_imagery(store, imagery_info("dem"), 2, {kIds[0], kIds[1]});
  EXPECT_EQ(store.imagery_layer("dem")->tile_count, 2u);
  EXPECT_EQ(terrain_state(), terrain_before);
  EXPECT_EQ(store.layer("dem")->version, terrain_version);
  ASSERT_TRUE(store.delete_imagery("dem").ok());
  EXPECT_EQ(terrain_state(), terrain_before);
  EXPECT_EQ(sql_value(dir / "s.db", "SELECT count(*) FROM imagery_tiles"), "0");
  EXPECT_EQ(sql_value(dir / "s.db", "SELECT count(*) FROM imagery_versions"), "0");

  // And back: replacing and deleting the terrain leaves the imagery alone.
  publish_imagery(store, imagery_info("dem"), 3, kIds);
  const std::string imagery_before = imagery_state();
  publish_terrain(store, "dem");
  EXPECT_NE(store.layer("dem")->version, terrain_version);
  EXPECT_EQ(imagery_state(), imagery_before);
  ASSERT_TRUE(store.delete_layer("dem").ok());
  EXPECT_EQ(imagery_state(), imagery_before);
  EXPECT_EQ(store.imagery_layer("dem")->tile_count, kIds.size());
}

TEST(ImageryStore, AbandonedVersionLeavesThePublishedOne) {
  TempDir dir;
  auto store = open_store(dir / "s.db", TileStore::Mode::read_write);
  publish_imagery(store, imagery_info("ortho"), 1, kIds);
  {
    auto writer = store.begin_imagery(imagery_info("ortho"));
    ASSERT_TRUE(writer.ok());
    for (int i = 0; i < 300; ++i) {  // more than one batch: some rows are committed
      const auto id = geo::TileId{9, static_cast<std::uint32_t>(i), 7};
      ASSERT_TRUE((*writer)->put(image(id, 9)).ok());
    }
  }  // destroyed unpublished
  EXPECT_EQ(store.imagery_layer("ortho")->tile_count, kIds.size());
  EXPECT_EQ((*store.imagery_tile("ortho", kIds[2]))->data, image(kIds[2], 1).data);
  EXPECT_EQ(sql_value(dir / "s.db", "SELECT count(*) FROM imagery_versions"), "1");
  EXPECT_EQ(sql_value(dir / "s.db", "SELECT count(*) FROM imagery_tiles"),
            std::to_string(kIds.size()));
}

TEST(ImageryStore, OneWriterPerImageryLayerButTerrainOfTheSameNameMayBeWritten) {
  TempDir dir;
  auto store = open_store(dir / "s.db", TileStore::Mode::read_write);
  auto first = store.begin_imagery(imagery_info("x"));
  ASSERT_TRUE(first.ok());
  auto second = store.begin_imagery(imagery_info("x"));
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.error().code, ErrorCode::invalid_argument);
  EXPECT_NE(second.error().message.find("imagery layer 'x' is being written"), std::string::npos)
      << second.error().message;
  auto terrain = store.begin_layer(basic_info("x"));
  EXPECT_TRUE(terrain.ok()) << terrain.error().message;
}

TEST(ImageryStore, RejectsBadMetadata) {
  TempDir dir;
  auto store = open_store(dir / "s.db", TileStore::Mode::read_write);
  auto info = imagery_info("ok");
  info.format = "gif";
  EXPECT_NE(store.begin_imagery(info).error().message.find("'gif' is not png, jpeg or webp"),
            std::string::npos);
  info = imagery_info("ok");
  info.min_level = 5;
  EXPECT_EQ(store.begin_imagery(info).error().code, ErrorCode::invalid_argument);
  info = imagery_info("ok");
  info.bounds.west = std::nan("");
  EXPECT_EQ(store.begin_imagery(info).error().code, ErrorCode::invalid_argument);
  info = imagery_info("bad name");
  EXPECT_EQ(store.begin_imagery(info).error().code, ErrorCode::invalid_argument);
  auto ro = open_store(dir / "s.db", TileStore::Mode::read_only);
  EXPECT_EQ(ro.begin_imagery(imagery_info("ok")).error().code, ErrorCode::invalid_argument);
  EXPECT_EQ(store.delete_imagery("ok").error().code, ErrorCode::not_found);
}

// A store written before imagery existed (schema version 1 without the imagery tables) is read
// as it is; a read-write open adds the tables; a reader that opened before sees them afterwards.
TEST(ImageryStore, StoreFromBeforeImageryIsReadAndUpgradedInPlace) {
  TempDir dir;
  {
    auto store = open_store(dir / "old.db", TileStore::Mode::read_write);
    publish_terrain(store, "dem");
  }
  for (const char* sql : {"DROP VIEW published_imagery", "DROP TABLE imagery_tiles",
                          "DROP TABLE imagery_layers", "DROP TABLE imagery_versions"}) {
    ASSERT_EQ(sql_value(dir / "old.db", sql, false), "") << sql;
  }
  ASSERT_EQ(
      sql_value(dir / "old.db", "SELECT count(*) FROM sqlite_master WHERE name LIKE '%imagery%'"),
      "0");

  auto reader = open_store(dir / "old.db", TileStore::Mode::read_only);
  auto none = reader.imagery_layers();
  ASSERT_TRUE(none.ok()) << none.error().message;
  EXPECT_TRUE(none->empty());
  EXPECT_EQ(reader.imagery_layer("dem").error().code, ErrorCode::not_found);
  EXPECT_EQ(reader.imagery_tile("dem", {0, 0, 0}).error().code, ErrorCode::not_found);
  EXPECT_EQ(reader.layer("dem")->tile_count, 3u);

  {
    auto writer = open_store(dir / "old.db", TileStore::Mode::read_write);
    EXPECT_EQ(sql_value(dir / "old.db", "SELECT value FROM metadata WHERE name = 'schema_version'"),
              "1");
    publish_imagery(writer, imagery_info("dem"), 4, kIds);
  }
  auto seen = reader.imagery_tile("dem", kIds[4]);
  ASSERT_TRUE(seen.ok()) << seen.error().message;
  ASSERT_TRUE(seen->has_value());
  EXPECT_EQ((*seen)->data, image(kIds[4], 4).data);
  EXPECT_EQ(reader.layer("dem")->tile_count, 3u);
  EXPECT_EQ(sql_value(dir / "old.db", "PRAGMA integrity_check"), "ok");
}

}  // namespace
}  // namespace tinstream::store
