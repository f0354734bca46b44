// One cache tier: byte budget, eviction order, pinned (drawn) entries, promotion, counters.
#include "tinstream/client/lru_tier.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace tinstream::client {
namespace {

TileKey lru_key(std::uint32_t x) { return {TileKind::terrain, 0, {10, x, 7}}; }

TEST(LruTier, EvictsLeastRecentlyUsedToStayWithinBudget) {
  LruTier<int> tier(100);
  std::vector<std::uint32_t> evicted;
  const auto on_evict = [&](const TileKey& k, int&) { evicted.push_back(k.tile.x); };
  for (std::uint32_t i = 0; i < 4; ++i)
    ASSERT_TRUE(tier.insert(lru_key(i), 0, 30, 1, 99, on_evict));
  // 4 × 30 > 100: the oldest (0) went out when 3 came in.
  EXPECT_EQ(evicted, std::vector<std::uint32_t>{0});
  EXPECT_EQ(tier.counters().bytes, 90u);
  EXPECT_LE(tier.counters().peak_bytes, 100u);
  EXPECT_FALSE(tier.contains(lru_key(0)));
  EXPECT_TRUE(tier.contains(lru_key(3)));
  EXPECT_EQ(tier.counters().evictions, 1u);
}

TEST(LruTier, UseProtectsAnEntryFromEviction) {
  LruTier<int> tier(90);
  for (std::uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(tier.insert(lru_key(i), 0, 30, 1, 99));
  ASSERT_NE(tier.find(lru_key(0)), nullptr);  // promoted: 1 is now the least recently used
  ASSERT_TRUE(tier.insert(lru_key(3), 0, 30, 1, 99));
  EXPECT_TRUE(tier.contains(lru_key(0)));
  EXPECT_FALSE(tier.contains(lru_key(1)));
  EXPECT_EQ(tier.counters().hits, 1u);
  EXPECT_EQ(tier.find(lru_key(1)), nullptr);
  EXPECT_EQ(tier.counters().misses, 1u);
  // peek neither counts nor promotes.
  ASSERT_NE(tier.peek(lru_key(2)), nullptr);
  ASSERT_TRUE(tier.insert(lru_key(4), 0, 30, 1, 99));
  EXPECT_FALSE(tier.contains(lru_key(2)));
  EXPECT_EQ(tier.counters().hits, 1u);
}

TEST(LruTier, DrawnEntriesAreNeverEvictedAndTheBudgetHoldsWithinOneEntry) {
  LruTier<int> tier(100);
  const std::uint64_t frame = 7;
  for (std::uint32_t i = 0; i < 3; ++i)
    ASSERT_TRUE(tier.insert(lru_key(i), 0, 30, frame - 1, frame));
  for (std::uint32_t i = 0; i < 3; ++i) tier.pin(lru_key(i), frame);  // drawn this frame
  // Nothing may go: the fourth is accepted once (90 ≤ 100, so at most one entry over)…
  ASSERT_TRUE(tier.insert(lru_key(3), 0, 40, frame, frame));
  EXPECT_EQ(tier.counters().bytes, 130u);
  // …and a fifth is refused: the tier is already over its budget.
  EXPECT_FALSE(tier.insert(lru_key(4), 0, 10, frame, frame));
  EXPECT_EQ(tier.counters().refused, 1u);
  for (std::uint32_t i = 0; i < 4; ++i) EXPECT_TRUE(tier.contains(lru_key(i)));
  EXPECT_LE(tier.counters().peak_bytes, tier.counters().budget + tier.counters().largest_entry);
  // Next frame only 1 and 3 are drawn: inserting evicts the unpinned 0 and 2, oldest first.
  tier.pin(lru_key(1), frame + 1);
  tier.pin(lru_key(3), frame + 1);
  ASSERT_TRUE(tier.insert(lru_key(5), 0, 30, frame + 1, frame + 1));
  EXPECT_FALSE(tier.contains(lru_key(0)));
  EXPECT_FALSE(tier.contains(lru_key(2)));
  EXPECT_TRUE(tier.contains(lru_key(1)));
  EXPECT_TRUE(tier.contains(lru_key(3)));
  EXPECT_EQ(tier.counters().bytes, 100u);
}

TEST(LruTier, ReplacingAKeyDoesNotCountTwice) {
  LruTier<int> tier(100);
  ASSERT_TRUE(tier.insert(lru_key(1), 1, 40, 1, 1));
  ASSERT_TRUE(tier.insert(lru_key(1), 2, 50, 1, 1));
  EXPECT_EQ(tier.counters().bytes, 50u);
  EXPECT_EQ(tier.size(), 1u);
  EXPECT_EQ(*tier.peek(lru_key(1)), 2);
  int released = 0;
  tier.clear([&](const TileKey&, int&) { ++released; });
  EXPECT_EQ(released, 1);
  EXPECT_EQ(tier.counters().bytes, 0u);
}

}  // namespace
}  // namespace tinstream::client
