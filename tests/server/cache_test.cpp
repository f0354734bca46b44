// The terrain cache's budget and LRU order, and the per-thread layer cache.
#include <gtest/gtest.h>

#include <string>
#include <thread>

#include "tinstream/server/handler.hpp"

namespace tinstream::server {
namespace {

// A cached tile as handle_terrain builds one: gzip bytes, an ETag, and the shared header block of
// its 200 (the fields a real terrain answer carries, ≈ 380 bytes on the wire).
std::shared_ptr<const CachedBody> tile_body(std::size_t bytes, char fill = 'x') {
  std::vector<std::pair<std::string, std::string>> fields = {
      {"Cache-Control", "public, max-age=86400"},
      {"Vary", "Accept, Accept-Encoding"},
      {"ETag", "\"qm-0123456789abcdef0123456789abcdef-n\""},
      {"Content-Type", "application/vnd.quantized-mesh;extensions=octvertexnormals"},
      {"Content-Encoding", "gzip"},
      {"Access-Control-Allow-Origin", "*"},
      {"Access-Control-Expose-Headers", "ETag, Content-Encoding, Content-Length, Location"}};
  return std::make_shared<const CachedBody>(
      CachedBody{"\"qm-0123456789abcdef0123456789abcdef-n\"", std::string(bytes, fill),
                 std::make_shared<const HeaderBlock>(std::move(fields), bytes)});
}

std::string key_of(int i) { return "qm|lux|1|03112" + std::to_string(i) + "|n"; }

// The shared header block is held for as long as its tile is cached: once as fields, once as
// `wire` and once more in its keep-alive head (HeaderBlock::keep_alive_head). The budget counts it.
TEST(TerrainCache, ChargesTheSharedHeaderBlockOfEachTile) {
  TerrainCache cache(1 << 20);
  const auto body = tile_body(1000);
  cache.put(key_of(0), body);
  const std::size_t wire = body->head->wire.size();
  ASSERT_GT(wire, 300u);
  // At least: the bytes, the ETag, the key, the header fields, `wire` and the keep-alive head.
  std::size_t fields = 0;
  for (const auto& [k, v] : body->head->fields) fields += k.size() + v.size();
  EXPECT_GE(cache.bytes(),
            body->bytes.size() + body->etag.size() + key_of(0).size() + fields + 2 * wire);
}

// A budget that holds six such tiles counting bytes, ETag and key only holds two once their
// header blocks count too: putting a third evicts the least recently used one.
TEST(TerrainCache, HeaderBlocksCountTowardsEviction) {
  const auto body = tile_body(1000);
  const std::size_t without_head = body->bytes.size() + body->etag.size() + key_of(0).size() + 96;
  TerrainCache cache(6 * without_head);
  ASSERT_EQ(cache.partitions(), 1u);
  cache.put(key_of(0), tile_body(1000, 'a'));
  cache.put(key_of(1), tile_body(1000, 'b'));
  EXPECT_NE(cache.get(key_of(0)), nullptr);  // 0 is now more recent than 1
  cache.put(key_of(2), tile_body(1000, 'c'));
  EXPECT_EQ(cache.get(key_of(1)), nullptr);
  ASSERT_NE(cache.get(key_of(0)), nullptr);
  EXPECT_EQ(cache.get(key_of(0))->bytes, std::string(1000, 'a'));
  ASSERT_NE(cache.get(key_of(2)), nullptr);
  EXPECT_EQ(cache.get(key_of(2))->bytes, std::string(1000, 'c'));
  EXPECT_LE(cache.bytes(), 6 * without_head);
}

TEST(TerrainCache, ReplacingAKeyChargesItOnce) {
  TerrainCache cache(1 << 20);
  cache.put(key_of(0), tile_body(1000));
  const auto once = cache.bytes();
  cache.put(key_of(0), tile_body(1000));
  EXPECT_EQ(cache.bytes(), once);
  cache.put(key_of(0), tile_body(3000));
  EXPECT_EQ(cache.bytes(), once + 2000);
}

// Large budgets are split over partitions; the total stays within the budget however the keys
// fall, every partition keeps its most recent entry, and an entry larger than a partition's share
// is not stored.
TEST(TerrainCache, PartitionsStayWithinTheBudget) {
  const std::uint64_t budget = 64ull << 20;
  TerrainCache cache(budget);
  ASSERT_GT(cache.partitions(), 1u);
  const auto big = tile_body(200000);
  for (int i = 0; i < 1500; ++i) {  // ≈ 300 MB offered
    cache.put(key_of(i), big);
    ASSERT_LE(cache.bytes(), budget) << i;
    ASSERT_NE(cache.get(key_of(i)), nullptr) << i;
  }
  EXPECT_GT(cache.bytes(), budget / 2);
  EXPECT_EQ(cache.get(key_of(0)), nullptr);
  cache.put("too-big", tile_body(budget / cache.partitions() + 1));
  EXPECT_EQ(cache.get("too-big"), nullptr);
  EXPECT_LE(cache.bytes(), budget);
}

// A layer row read before an ingest published (or a delete committed) and put after the clear()
// that followed must not be served for the next ttl: put() drops rows of an older generation.
TEST(LayerCache, RowReadBeforeAClearIsNotCachedAfterIt) {
  LayerCache cache(60000);
  store::LayerInfo old_row;
  old_row.name = "lux";
  old_row.version = 5;
  const std::uint64_t before = cache.generation();  // a reader starts reading the row
  cache.clear();                                    // the ingest publishes version 6
  cache.put(old_row, before);                       // the reader caches what it read
  EXPECT_EQ(cache.get("lux"), nullptr);

  store::LayerInfo new_row = old_row;
  new_row.version = 6;
  cache.put(new_row, cache.generation());
  const auto hit = cache.get("lux");
  ASSERT_NE(hit, nullptr);
  EXPECT_EQ(hit->version, 6);
  cache.clear();
  EXPECT_EQ(cache.get("lux"), nullptr);
}

}  // namespace
}  // namespace tinstream::server
