#include "tinstream/terrain/layer_json.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

namespace tinstream::terrain {
namespace {

TEST(LayerJson, MergedRangesCoverExactlyTheTiles) {
  std::mt19937 rng(7);
  for (int round = 0; round < 50; ++round) {
    const std::uint32_t z = 5;
    std::set<std::pair<std::uint32_t, std::uint32_t>> want;  // (x, y_tms)
    std::vector<geo::TileId> ids;
    std::uniform_int_distribution<std::uint32_t> coord(3, 12);
    for (int k = 0; k < 60; ++k) {
      auto id = *geo::TileId::from_zxy(z, coord(rng), coord(rng));
      ids.push_back(id);
      want.insert({id.x, id.tms_row()});
    }
    const auto ranges = merge_ranges(ids);
    std::set<std::pair<std::uint32_t, std::uint32_t>> got;
    std::size_t area = 0;
    for (const auto& r : ranges) {
      ASSERT_LE(r.start_x, r.end_x);
      ASSERT_LE(r.start_y, r.end_y);
      for (auto x = r.start_x; x <= r.end_x; ++x)
        for (auto y = r.start_y; y <= r.end_y; ++y) got.insert({x, y}), ++area;
    }
    EXPECT_EQ(got, want);
    EXPECT_EQ(area, want.size()) << "rectangles overlap";
    EXPECT_LT(ranges.size(), want.size() + 1);
  }
}

TEST(LayerJson, ABlockOfTilesIsOneRectangle) {
  std::vector<geo::TileId> ids;
  for (std::uint32_t x = 10; x < 14; ++x)
    for (std::uint32_t y = 20; y < 23; ++y) ids.push_back(*geo::TileId::from_zxy(6, x, y));
  const auto r = merge_ranges(ids);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0], (TileRange{10, 63 - 22, 13, 63 - 20}));
}

TEST(LayerJson, DocumentHasTheCesiumKeys) {
  LayerJsonInput in;
  in.name = "lux";
  in.attribution = "© test";
  in.bounds = {5.7, 49.4, 6.5, 50.2};
  in.min_level = 2;
  in.max_level = 3;
  in.tile_ids = {*geo::TileId::from_zxy(2, 2, 1), *geo::TileId::from_zxy(3, 4, 2),
                 *geo::TileId::from_zxy(3, 5, 2)};
  const auto j = nlohmann::json::parse(layer_json(in));
  EXPECT_EQ(j["tilejson"], "2.1.0");
  EXPECT_EQ(j["format"], "quantized-mesh-1.0");
  EXPECT_EQ(j["scheme"], "tms");
  EXPECT_EQ(j["projection"], "EPSG:3857");
  EXPECT_EQ(j["tiles"][0], "{z}/{x}/{y}.terrain?v={version}");
  EXPECT_EQ(j["extensions"][0], "octvertexnormals");
  EXPECT_EQ(j["maxzoom"], 3);
  ASSERT_EQ(j["available"].size(), 4u);
  EXPECT_EQ(j["available"][0][0]["endX"], 0);
  ASSERT_EQ(j["available"][1].size(), 1u);  // every level-1 tile (kWholeLevels): one rectangle
  EXPECT_EQ(j["available"][1][0],
            nlohmann::json({{"startX", 0}, {"startY", 0}, {"endX", 1}, {"endY", 1}}));
  EXPECT_EQ(j["available"][2].size(), 1u);
  EXPECT_EQ(j["available"][2][0]["startY"], 2);  // TMS row of y = 1 at z = 2
  EXPECT_EQ(j["available"][3].size(), 1u);
  EXPECT_EQ(j["available"][3][0]["startX"], 4);
  EXPECT_EQ(j["available"][3][0]["endX"], 5);
  EXPECT_EQ(j["bounds"][2], 6.5);
}

TEST(LayerJson, SyntheticTilesAreTheAncestorsAndEveryTileOfLevelsZeroAndOne) {
  const auto ids =
      std::vector<geo::TileId>{*geo::TileId::from_zxy(3, 4, 2), *geo::TileId::from_zxy(3, 5, 2),
                               *geo::TileId::from_zxy(4, 8, 4)};
  const auto a = synthetic_tiles(ids, 3);
  const std::vector<geo::TileId> expected{
      *geo::TileId::from_zxy(0, 0, 0), *geo::TileId::from_zxy(1, 0, 0),
      *geo::TileId::from_zxy(1, 0, 1), *geo::TileId::from_zxy(1, 1, 0),
      *geo::TileId::from_zxy(1, 1, 1), *geo::TileId::from_zxy(2, 2, 1)};
  std::vector<geo::TileId> sorted = a;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted, expected);
  EXPECT_EQ(a, sorted);  // sorted as returned
  // A stored tile is never synthesised, even on the whole levels.
  const auto b =
      synthetic_tiles({*geo::TileId::from_zxy(1, 1, 0), *geo::TileId::from_zxy(2, 2, 1)}, 1);
  EXPECT_EQ(b, (std::vector<geo::TileId>{
                   *geo::TileId::from_zxy(0, 0, 0), *geo::TileId::from_zxy(1, 0, 0),
                   *geo::TileId::from_zxy(1, 0, 1), *geo::TileId::from_zxy(1, 1, 1)}));
}

// The listing (synthetic_tiles, from the stored tiles) and the server's admission
// (may_be_filler, from the layer's row) are one rule: over the levels up to min_level they agree
// tile by tile, for layers whose data covers its stored tiles of min_level and whose bounds lie
// strictly inside them (a quarter tile in: no tile edge of a coarser level touches them).
TEST(LayerJson, SyntheticTilesAreExactlyTheFillersTheServerAccepts) {
  struct Layer {
    std::uint32_t min_level;
    std::vector<geo::TileId> min_tiles;  // the stored tiles of min_level: a block
  };
  const auto block = [](std::uint32_t z, std::uint32_t x0, std::uint32_t y0, std::uint32_t w,
                        std::uint32_t h) {
    std::vector<geo::TileId> ids;
    for (std::uint32_t y = y0; y < y0 + h; ++y) {
      for (std::uint32_t x = x0; x < x0 + w; ++x) ids.push_back(*geo::TileId::from_zxy(z, x, y));
    }
    return ids;
  };
  for (const Layer& layer : {Layer{4, block(4, 5, 6, 3, 2)}, Layer{1, block(1, 1, 0, 1, 1)},
                             Layer{0, block(0, 0, 0, 1, 1)}, Layer{3, block(3, 0, 7, 1, 1)}}) {
    std::vector<geo::TileId> stored = layer.min_tiles;
    geo::MercatorRect extent = layer.min_tiles.front().bounds();
    for (const geo::TileId& id : layer.min_tiles) {
      const geo::MercatorRect r = id.bounds();
      extent = {std::min(extent.min_x, r.min_x), std::min(extent.min_y, r.min_y),
                std::max(extent.max_x, r.max_x), std::max(extent.max_y, r.max_y)};
      // A finer stored tile under each (its first child): stored tiles below min_level change
      // nothing.
      stored.push_back(id.children()[0]);
    }
    const double inset = layer.min_tiles.front().bounds().width() / 4;
    const geo::MercatorRect data_bounds{extent.min_x + inset, extent.min_y + inset,
                                        extent.max_x - inset, extent.max_y - inset};
    const std::vector<geo::TileId> listed = synthetic_tiles(stored, layer.min_level);
    std::size_t accepted = 0;
    for (std::uint32_t z = 0; z <= std::max(layer.min_level, kWholeLevels); ++z) {
      for (std::uint32_t y = 0; y < (1u << z); ++y) {
        for (std::uint32_t x = 0; x < (1u << z); ++x) {
          const geo::TileId id = *geo::TileId::from_zxy(z, x, y);
          const bool is_stored = std::find(stored.begin(), stored.end(), id) != stored.end();
          const bool admits = !is_stored && may_be_filler(id, layer.min_level, data_bounds);
          const bool lists = std::binary_search(listed.begin(), listed.end(), id);
          EXPECT_EQ(lists, admits)
              << "min_level " << layer.min_level << ", tile " << id.to_string();
          accepted += admits ? 1 : 0;
        }
      }
    }
    EXPECT_EQ(accepted, listed.size()) << "min_level " << layer.min_level;
  }
}

TEST(LayerJson, ALayerOfLevelZeroOnlyStillListsLevelOne) {
  LayerJsonInput in;
  in.name = "tiny";
  in.max_level = 0;
  in.tile_ids = {*geo::TileId::from_zxy(0, 0, 0)};
  const auto j = nlohmann::json::parse(layer_json(in));
  EXPECT_EQ(j["maxzoom"], 1);
  ASSERT_EQ(j["available"].size(), 2u);
  EXPECT_EQ(j["available"][1][0],
            nlohmann::json({{"startX", 0}, {"startY", 0}, {"endX", 1}, {"endY", 1}}));
}

}  // namespace
}  // namespace tinstream::terrain
