// build_pyramid through a TileSink that is not the store: tiles kept decoded in memory, no SQLite,
// no codec. The pyramid it builds is the one the ingest's sink (a real store) gets.
#include "tinstream/lod/tile_sink.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "lod_test_support.hpp"
#include "temp_store.hpp"
#include "tinstream/lod/pyramid.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::lod {
namespace {

using tile::TinTile;

// Tiles in a map, "encoded" as themselves.
class MemorySink final : public TileSink {
 public:
  std::map<geo::TileId, TinTile> tiles;
  std::size_t puts = 0;

  Result<std::vector<geo::TileId>> tile_ids(std::uint32_t level) override {
    std::vector<geo::TileId> ids;
    for (const auto& [id, t] : tiles) {
      if (id.z == level) ids.push_back(id);
    }
    return ids;
  }
  Result<std::unique_ptr<EncodedTile>> get(const geo::TileId& id) override {
    const auto it = tiles.find(id);
    if (it == tiles.end()) return std::unique_ptr<EncodedTile>{};
    return std::unique_ptr<EncodedTile>(std::make_unique<Held>(it->second));
  }
  Status put(std::unique_ptr<EncodedTile> tile) override {
    auto* held = dynamic_cast<Held*>(tile.get());
    if (held == nullptr) return Error(ErrorCode::internal, "not a MemorySink tile");
    ++puts;
    tiles.insert_or_assign(held->tile.id, std::move(held->tile));
    return {};
  }
  Status flush() override { return {}; }
  Result<std::unique_ptr<EncodedTile>> encode(const TinTile& tile) const override {
    return std::unique_ptr<EncodedTile>(std::make_unique<Held>(tile));
  }
  Result<TinTile> decode(const EncodedTile& tile) const override {
    const auto* held = dynamic_cast<const Held*>(&tile);
    if (held == nullptr) return Error(ErrorCode::internal, "not a MemorySink tile");
    return held->tile;
  }

 private:
  struct Held final : EncodedTile {
    explicit Held(TinTile t) : tile(std::move(t)) {}
    const geo::TileId& id() const override { return tile.id; }
    double geometric_error() const override { return tile.geometric_error; }
    std::uint32_t vertex_count() const override {
      return static_cast<std::uint32_t>(tile.vertex_count());
    }
    TinTile tile;
  };
};

double sink_hills(double x, double y) {
  return 100.0 + 50.0 * std::sin(3.0 * x) * std::cos(2.0 * y) + 20.0 * std::sin(17.0 * x * y);
}

// 4 × 4 level-2 tiles less two (absent children: corners and sides from the tiles across),
// reduced, thinned to level 0 in memory and through a real store: the same tiles, level by level.
TEST(TileSink, PyramidInMemoryIsThePyramidThroughTheStore) {
  MemorySink memory;
  testing::TempStore ts("sink");
  auto w = ts.writer("sink");
  ASSERT_TRUE(w);
  for (std::uint32_t y = 0; y < 4; ++y) {
    for (std::uint32_t x = 0; x < 4; ++x) {
      if ((x == 3 && y == 3) || (x == 0 && y == 2)) continue;
      const TinTile t = testing::grid_tile({2, x, y}, 16, sink_hills);
      memory.tiles.emplace(t.id, t);
      ASSERT_TRUE(w->put(t).ok());
    }
  }
  PyramidOptions o;
  o.lod.max_points = 40;
  o.lod.epsilon = 0.5;
  o.reduce_finest = true;
  auto in_memory = build_pyramid(memory, 2, 0, o, 2);
  ASSERT_TRUE(in_memory.ok()) << in_memory.error().message;
  auto stored = testing::build_stored_pyramid(*w, 2, 0, o, 2);
  ASSERT_TRUE(stored.ok()) << stored.error().message;

  EXPECT_EQ(memory.puts, 14u + 4u + 1u);  // 14 reduced finest tiles, 4 + 1 parents
  EXPECT_EQ(in_memory->tiles_built, 5u);
  EXPECT_EQ(in_memory->level_tiles, stored->level_tiles);
  EXPECT_EQ(in_memory->level_vertices, stored->level_vertices);
  EXPECT_EQ(in_memory->level_max_error, stored->level_max_error);
  for (std::uint32_t z = 0; z <= 2; ++z) {
    auto ids = w->tile_ids(z);
    ASSERT_TRUE(ids.ok());
    auto memory_ids = memory.tile_ids(z);
    ASSERT_TRUE(memory_ids.ok());
    ASSERT_EQ(ids->size(), memory_ids->size()) << "level " << z;
    for (const auto& id : *ids) {
      auto t = w->get(id);
      ASSERT_TRUE(t.ok() && t->has_value()) << id.to_string();
      const auto it = memory.tiles.find(id);
      ASSERT_NE(it, memory.tiles.end()) << id.to_string();
      EXPECT_EQ(tile::encode(it->second), tile::encode(**t)) << id.to_string();
    }
  }
}

}  // namespace
}  // namespace tinstream::lod
