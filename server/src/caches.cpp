// The terrain cache (a partitioned LRU of encoded bodies) and the layer-row cache.
#include <algorithm>
#include <chrono>
#include <cstring>
#include <list>
#include <mutex>
#include <unordered_map>

#include "tinstream/server/handler.hpp"

namespace tinstream::server {

struct TerrainCache::Impl {
  struct Entry {
    std::string key;
    std::shared_ptr<const CachedBody> value;
    std::uint64_t cost;
  };
  // One LRU with its share of the budget. The index's keys view the list nodes' keys (list
  // nodes never move).
  struct alignas(64) Partition {
    mutable std::mutex mutex;  // guards everything below
    std::list<Entry> lru;      // front = most recent
    std::unordered_map<std::string_view, std::list<Entry>::iterator> index;
    std::uint64_t bytes = 0;
  };
  // Bookkeeping of one entry besides its strings and header block: the list node, the index
  // node and its bucket, the CachedBody with its shared_ptr control block.
  static constexpr std::uint64_t kEntryOverhead =
      sizeof(Entry) + 2 * sizeof(void*) +
      sizeof(std::pair<const std::string_view, std::list<Entry>::iterator>) + 3 * sizeof(void*) +
      sizeof(CachedBody) + 2 * sizeof(void*);

  explicit Impl(std::uint64_t max)
      : max_bytes(max),
        n_partitions(static_cast<std::size_t>(std::clamp<std::uint64_t>(max >> 24, 1, 16))),
        partition_budget(max / n_partitions),
        parts(std::make_unique<Partition[]>(n_partitions)) {}

  // The partition of a key: a mix of its last bytes (the quadkey's least significant digits;
  // cheaper than the full hash the index computes anyway).
  Partition& partition_of(std::string_view key) const {
    if (n_partitions == 1) return parts[0];
    std::uint64_t tail = 0;
    const std::size_t n = std::min<std::size_t>(key.size(), 8);
    std::memcpy(&tail, key.data() + key.size() - n, n);
    tail *= 0x9E3779B97F4A7C15ull;
    return parts[(tail >> 32) % n_partitions];
  }

  std::uint64_t max_bytes;
  std::size_t n_partitions;
  std::uint64_t partition_budget;
  std::unique_ptr<Partition[]> parts;
};

std::uint64_t TerrainCache::cost(std::string_view key, const CachedBody& value) {
  return Impl::kEntryOverhead + (key.size() + 1) + value.bytes.capacity() + 1 +
         string_heap_bytes(value.etag) + (value.head ? value.head->memory_bytes() : 0);
}

TerrainCache::TerrainCache(std::uint64_t max_bytes) : impl_(std::make_unique<Impl>(max_bytes)) {}
TerrainCache::~TerrainCache() = default;

std::shared_ptr<const CachedBody> TerrainCache::get(std::string_view key) {
  Impl::Partition& p = impl_->partition_of(key);
  std::lock_guard lock(p.mutex);
  auto it = p.index.find(key);
  if (it == p.index.end()) return nullptr;
  if (it->second != p.lru.begin()) p.lru.splice(p.lru.begin(), p.lru, it->second);
  return it->second->value;
}

void TerrainCache::put(std::string_view key, std::shared_ptr<const CachedBody> value) {
  const std::uint64_t size = cost(key, *value);
  if (size > impl_->partition_budget) return;
  Impl::Partition& p = impl_->partition_of(key);
  std::lock_guard lock(p.mutex);
  if (auto it = p.index.find(key); it != p.index.end()) {
    p.bytes -= it->second->cost;
    const auto node = it->second;
    p.index.erase(it);
    p.lru.erase(node);
  }
  p.lru.push_front(Impl::Entry{std::string(key), std::move(value), size});
  p.index.emplace(p.lru.front().key, p.lru.begin());
  p.bytes += size;
  while (p.bytes > impl_->partition_budget) {
    const Impl::Entry& last = p.lru.back();
    p.bytes -= last.cost;
    p.index.erase(last.key);
    p.lru.pop_back();
  }
}

std::uint64_t TerrainCache::bytes() const {
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < impl_->n_partitions; ++i) {
    std::lock_guard lock(impl_->parts[i].mutex);
    total += impl_->parts[i].bytes;
  }
  return total;
}

std::size_t TerrainCache::partitions() const { return impl_->n_partitions; }

struct LayerCache::Impl {
  std::chrono::milliseconds ttl;
  mutable std::mutex mutex;  // guards entries and generation
  std::unordered_map<std::string, std::pair<std::shared_ptr<const store::LayerInfo>,
                                            std::chrono::steady_clock::time_point>>
      entries;
  std::uint64_t generation = 0;
};

LayerCache::LayerCache(std::uint32_t ttl_ms) : impl_(std::make_unique<Impl>()) {
  impl_->ttl = std::chrono::milliseconds(ttl_ms);
}
LayerCache::~LayerCache() = default;

std::shared_ptr<const store::LayerInfo> LayerCache::get(const std::string& name) {
  std::lock_guard lock(impl_->mutex);
  auto it = impl_->entries.find(name);
  if (it == impl_->entries.end()) return nullptr;
  if (std::chrono::steady_clock::now() - it->second.second > impl_->ttl) {
    impl_->entries.erase(it);
    return nullptr;
  }
  return it->second.first;
}

std::uint64_t LayerCache::generation() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->generation;
}

void LayerCache::put(const store::LayerInfo& info, std::uint64_t generation) {
  std::lock_guard lock(impl_->mutex);
  if (generation != impl_->generation) return;  // read before a clear(): maybe stale already
  if (impl_->entries.size() > 10000) impl_->entries.clear();
  impl_->entries[info.name] = {std::make_shared<const store::LayerInfo>(info),
                               std::chrono::steady_clock::now()};
}

void LayerCache::clear() {
  std::lock_guard lock(impl_->mutex);
  ++impl_->generation;
  impl_->entries.clear();
}

}  // namespace tinstream::server
