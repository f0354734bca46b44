// tinstream/client/disk_cache.hpp — the slowest cache tier: compressed tiles as received, on disk.
//
// Optional (`--disk-cache DIR`), survives restarts, holds at most `budget` bytes of files (never
// more than one tile over). One file per tile,
//   DIR/<kind>/<layer>/<layer cache version>/<quadkey or "_">.tile
// so a layer re-published under a new version never sees the old version's tiles; each file
// carries the tile's ETag and content encoding, and the loader revalidates it with the server
// (`If-None-Match`; 304 keeps it). Files are written to a temporary name and renamed, so a
// reader (or a crash) never sees half a file; a damaged file is a miss and is removed.
//
// Thread-safe: the index (LRU order, sizes) is guarded by one mutex that is never held during
// file I/O. The index is this process's view: two viewers sharing DIR each keep their own budget.
#pragma once

#include <cstdint>
#include <filesystem>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/layer.hpp"
#include "tinstream/client/lru_tier.hpp"
#include "tinstream/client/render_mesh.hpp"
#include "tinstream/client/tile_key.hpp"

namespace tinstream::client {

struct DiskEntry {
  std::string etag;
  ContentEncoding encoding = ContentEncoding::deflate;
  std::vector<std::uint8_t> bytes;
};

class DiskCache {
 public:
  // Creates DIR when absent and indexes the files already there (oldest modification first).
  static Result<std::unique_ptr<DiskCache>> open(const std::filesystem::path& dir,
                                                 std::uint64_t budget_bytes);

  // Counts a hit (and promotes) or a miss.
  std::optional<DiskEntry> get(const TileKey& key, const LayerDescription& layer);
  // Stores (replacing), then evicts least recently used files beyond the budget. An I/O error
  // only loses the entry.
  void put(const TileKey& key, const LayerDescription& layer, const DiskEntry& entry);
  // The server confirmed the entry (304): promote it.
  void touch(const TileKey& key, const LayerDescription& layer);
  void erase(const TileKey& key, const LayerDescription& layer);

  TierCounters counters() const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  DiskCache(std::filesystem::path dir, std::uint64_t budget);
  std::string relative_path(const TileKey& key, const LayerDescription& layer) const;
  void insert_locked(const std::string& rel, std::uint64_t bytes,
                     std::vector<std::filesystem::path>& victims);
  void erase_locked(const std::string& rel);

  struct Entry {
    std::string rel;
    std::uint64_t bytes;
  };
  std::filesystem::path dir_;
  mutable std::mutex mutex_;
  std::list<Entry> lru_;  // guarded by mutex_; front = most recently used
  std::unordered_map<std::string, std::list<Entry>::iterator> index_;  // guarded by mutex_
  TierCounters counters_;                                              // guarded by mutex_
};

}  // namespace tinstream::client
