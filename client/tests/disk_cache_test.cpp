// The disk tier: round trip, budget, restarts, damaged files, layer versions.
#include "tinstream/client/disk_cache.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "synthetic_store.hpp"

namespace tinstream::client {
namespace {

using testing::TempDir;

TileKey disk_key(std::uint32_t x) { return {TileKind::terrain, 0, {12, x, 1400}}; }

LayerDescription layer(std::int64_t version = 3) {
  LayerDescription l;
  l.name = "dem";
  l.version = version;
  l.created_unix = 1700000000;
  return l;
}

DiskEntry entry(std::size_t size, std::uint8_t fill, std::string etag = "\"abc-1\"") {
  return DiskEntry{std::move(etag), ContentEncoding::deflate,
                   std::vector<std::uint8_t>(size, fill)};
}

TEST(DiskCache, RoundTripsAndCountsHitsAndMisses) {
  TempDir dir("disk_roundtrip");
  auto cache = DiskCache::open(dir.path / "c", 1 << 20);
  ASSERT_TRUE(cache.ok()) << cache.error().message;
  EXPECT_FALSE((*cache)->get(disk_key(1), layer()).has_value());
  (*cache)->put(disk_key(1), layer(), entry(1000, 7, "\"e1\""));
  const auto got = (*cache)->get(disk_key(1), layer());
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(got->etag, "\"e1\"");
  EXPECT_EQ(got->encoding, ContentEncoding::deflate);
  EXPECT_EQ(got->bytes, std::vector<std::uint8_t>(1000, 7));
  const TierCounters c = (*cache)->counters();
  EXPECT_EQ(c.hits, 1u);
  EXPECT_EQ(c.misses, 1u);
  EXPECT_TRUE(std::filesystem::exists(dir.path / "c/terrain/dem/v3-1700000000" /
                                      (disk_key(1).tile.quadkey() + ".tile")));
  // Another version of the layer does not see it.
  EXPECT_FALSE((*cache)->get(disk_key(1), layer(4)).has_value());
}

TEST(DiskCache, EvictsTheLeastRecentlyUsedAndSurvivesARestart) {
  TempDir dir("disk_budget");
  {
    auto cache = DiskCache::open(dir.path, 3500);  // three 1 KB tiles (plus headers)
    ASSERT_TRUE(cache.ok());
    for (std::uint32_t i = 0; i < 3; ++i) {
      (*cache)->put(disk_key(i), layer(), entry(1000, static_cast<std::uint8_t>(i)));
      std::this_thread::sleep_for(std::chrono::milliseconds(15));  // distinct modification times
    }
    ASSERT_TRUE((*cache)->get(disk_key(0), layer()).has_value());  // 0 used: 1 is the oldest now
    (*cache)->touch(disk_key(0), layer());
    (*cache)->put(disk_key(3), layer(), entry(1000, 3));
    EXPECT_FALSE((*cache)->get(disk_key(1), layer()).has_value());
    const TierCounters c = (*cache)->counters();
    EXPECT_LE(c.bytes, c.budget);
    EXPECT_EQ(c.evictions, 1u);
  }
  // A new process finds the three files left, and its budget still holds.
  auto reopened = DiskCache::open(dir.path, 3500);
  ASSERT_TRUE(reopened.ok());
  EXPECT_EQ((*reopened)->counters().entries, 3u);
  for (std::uint32_t i : {0u, 2u, 3u}) {
    const auto e = (*reopened)->get(disk_key(i), layer());
    ASSERT_TRUE(e.has_value()) << i;
    EXPECT_EQ(e->bytes.front(), i);
  }
  // A smaller budget on reopening evicts the oldest at once.
  auto smaller = DiskCache::open(dir.path, 2500);
  ASSERT_TRUE(smaller.ok());
  EXPECT_EQ((*smaller)->counters().entries, 2u);
}

TEST(DiskCache, NeverMoreThanOneTileOverBudget) {
  TempDir dir("disk_over");
  auto cache = DiskCache::open(dir.path, 500);
  ASSERT_TRUE(cache.ok());
  (*cache)->put(disk_key(1), layer(), entry(2000, 1));  // alone larger than the budget: kept
  EXPECT_TRUE((*cache)->get(disk_key(1), layer()).has_value());
  (*cache)->put(disk_key(2), layer(), entry(100, 2));  // the big one goes
  EXPECT_FALSE((*cache)->get(disk_key(1), layer()).has_value());
  EXPECT_LE((*cache)->counters().bytes, 500u);
}

TEST(DiskCache, ADamagedFileIsAMissAndIsRemoved) {
  TempDir dir("disk_damaged");
  auto cache = DiskCache::open(dir.path, 1 << 20);
  ASSERT_TRUE(cache.ok());
  (*cache)->put(disk_key(5), layer(), entry(100, 5));
  const auto file = dir.path / "terrain/dem/v3-1700000000" / (disk_key(5).tile.quadkey() + ".tile");
  std::ofstream(file, std::ios::binary | std::ios::trunc) << "XXXX";
  EXPECT_FALSE((*cache)->get(disk_key(5), layer()).has_value());
  EXPECT_FALSE(std::filesystem::exists(file));
}

TEST(DiskCache, RefusesAPathThatIsAFile) {
  TempDir dir("disk_file");
  std::ofstream(dir.path / "f") << "x";
  auto cache = DiskCache::open(dir.path / "f", 100);
  ASSERT_FALSE(cache.ok());
  EXPECT_NE(cache.error().message.find("disk cache"), std::string::npos);
}

}  // namespace
}  // namespace tinstream::client
