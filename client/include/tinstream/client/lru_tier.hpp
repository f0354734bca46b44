// tinstream/client/lru_tier.hpp — one tier of the layered cache: least recently used entries
// under a byte budget (the paper's Fig. 8: the most recently needed data in the fastest layer).
//
// The GPU tier (resident meshes) and the RAM tier (decoded meshes) are both an LruTier owned by
// the render thread; the disk tier (disk_cache.hpp) has its own thread-safe index.
//
// Budget: insert() evicts least recently used entries until the new one fits. Entries pinned at or
// after the `protect_from` frame are never evicted (the tiles drawn, or on the path to a drawn
// tile, in the current frame). When only protected entries are left, an insert is still accepted
// while the tier is within its budget, so the bytes never exceed budget + the size of one entry;
// beyond that it is refused (and counted). find() counts a hit or a miss and promotes; pin()
// promotes and protects; peek() does neither. Single-threaded (the owner's thread).
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <list>
#include <unordered_map>
#include <utility>

#include "tinstream/client/tile_key.hpp"

namespace tinstream::client {

struct TierCounters {
  std::uint64_t hits = 0, misses = 0, evictions = 0, inserts = 0, refused = 0;
  std::uint64_t bytes = 0, peak_bytes = 0, budget = 0, largest_entry = 0;
  std::uint64_t entries = 0;
};

template <typename Value>
class LruTier {
 public:
  using EvictFn = std::function<void(const TileKey&, Value&)>;

  explicit LruTier(std::uint64_t budget_bytes) { counters_.budget = budget_bytes; }

  Value* find(const TileKey& key) {
    const auto it = index_.find(key);
    if (it == index_.end()) {
      ++counters_.misses;
      return nullptr;
    }
    ++counters_.hits;
    entries_.splice(entries_.begin(), entries_, it->second);
    return &it->second->value;
  }
  Value* peek(const TileKey& key) {
    const auto it = index_.find(key);
    return it == index_.end() ? nullptr : &it->second->value;
  }
  bool contains(const TileKey& key) const { return index_.contains(key); }

  // Promotes the entry and protects it from eviction while protect_from ≤ frame.
  void pin(const TileKey& key, std::uint64_t frame) {
    const auto it = index_.find(key);
    if (it == index_.end()) return;
    it->second->pinned = frame;
    entries_.splice(entries_.begin(), entries_, it->second);
  }

  // Inserts or replaces `key`, pinned at `frame`; see the header comment for the budget rule.
  // Returns false (and leaves `value` to the caller through on_refused) when refused.
  bool insert(const TileKey& key, Value value, std::uint64_t bytes, std::uint64_t frame,
              std::uint64_t protect_from, const EvictFn& on_evict = {}) {
    erase(key, on_evict, /*count=*/false);
    for (auto it = entries_.end();
         counters_.bytes + bytes > counters_.budget && it != entries_.begin();) {
      --it;
      if (it->pinned >= protect_from) continue;
      if (on_evict) on_evict(it->key, it->value);
      counters_.bytes -= it->bytes;
      ++counters_.evictions;
      index_.erase(it->key);
      it = entries_.erase(it);
    }
    if (counters_.bytes + bytes > counters_.budget && counters_.bytes > counters_.budget) {
      ++counters_.refused;
      if (on_evict) on_evict(key, value);
      return false;
    }
    entries_.push_front(Entry{key, std::move(value), bytes, frame});
    index_[key] = entries_.begin();
    counters_.bytes += bytes;
    counters_.peak_bytes = std::max(counters_.peak_bytes, counters_.bytes);
    counters_.largest_entry = std::max(counters_.largest_entry, bytes);
    ++counters_.inserts;
    counters_.entries = entries_.size();
    return true;
  }

  void erase(const TileKey& key, const EvictFn& on_evict = {}, bool count = true) {
    const auto it = index_.find(key);
    if (it == index_.end()) return;
    if (on_evict) on_evict(key, it->second->value);
    counters_.bytes -= it->second->bytes;
    if (count) ++counters_.evictions;
    entries_.erase(it->second);
    index_.erase(it);
    counters_.entries = entries_.size();
  }

  // Removes everything (e.g. before the GL context goes away).
  void clear(const EvictFn& on_evict = {}) {
    for (Entry& e : entries_)
      if (on_evict) on_evict(e.key, e.value);
    entries_.clear();
    index_.clear();
    counters_.bytes = 0;
    counters_.entries = 0;
  }

  const TierCounters& counters() const {
    counters_.entries = entries_.size();
    return counters_;
  }
  std::size_t size() const { return entries_.size(); }

  // Visits entries from the most to the least recently used: f(key, value, bytes, pinned_frame).
  template <typename F>
  void for_each(F&& f) const {
    for (const Entry& e : entries_) f(e.key, e.value, e.bytes, e.pinned);
  }

 private:
  struct Entry {
    TileKey key;
    Value value;
    std::uint64_t bytes;
    std::uint64_t pinned;  // the last frame that pinned it
  };
  std::list<Entry> entries_;  // front = most recently used
  std::unordered_map<TileKey, typename std::list<Entry>::iterator, TileKeyHash> index_;
  mutable TierCounters counters_;
};

}  // namespace tinstream::client
