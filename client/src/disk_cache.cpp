#include "tinstream/client/disk_cache.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

namespace tinstream::client {

namespace fs = std::filesystem;

namespace {

// File layout: "TSDC" u8 version(1) u8 encoding u16 etag length, etag bytes, then the payload.
constexpr char kMagic[4] = {'T', 'S', 'D', 'C'};

std::optional<DiskEntry> read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  char header[8];
  if (!in.read(header, 8) || std::memcmp(header, kMagic, 4) != 0 || header[4] != 1 ||
      static_cast<unsigned char>(header[5]) > 2)
    return std::nullopt;
  DiskEntry e;
  e.encoding = static_cast<ContentEncoding>(header[5]);
  const std::size_t etag_len =
      static_cast<unsigned char>(header[6]) |
      (static_cast<std::size_t>(static_cast<unsigned char>(header[7])) << 8);
  e.etag.resize(etag_len);
  if (etag_len && !in.read(e.etag.data(), static_cast<std::streamsize>(etag_len)))
    return std::nullopt;
  const std::streampos start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg() - start;
  if (size < 0 || size > (std::streamoff{256} << 20)) return std::nullopt;
  in.seekg(start);
  e.bytes.resize(static_cast<std::size_t>(size));
  if (size && !in.read(reinterpret_cast<char*>(e.bytes.data()), size)) return std::nullopt;
  return e;
}

bool write_file(const fs::path& path, const DiskEntry& e) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  static std::atomic<std::uint64_t> counter{0};
  std::ostringstream tmp_name;
  tmp_name << path.filename().string() << ".tmp." << ::getpid() << "." << counter++;
  const fs::path tmp = path.parent_path() / tmp_name.str();
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return false;
    const std::size_t etag_len = std::min<std::size_t>(e.etag.size(), 65535);
    const char header[8] = {kMagic[0],
                            kMagic[1],
                            kMagic[2],
                            kMagic[3],
                            1,
                            static_cast<char>(e.encoding),
                            static_cast<char>(etag_len & 0xFF),
                            static_cast<char>(etag_len >> 8)};
    out.write(header, 8);
    out.write(e.etag.data(), static_cast<std::streamsize>(etag_len));
    out.write(reinterpret_cast<const char*>(e.bytes.data()),
              static_cast<std::streamsize>(e.bytes.size()));
    if (!out.flush()) {
      fs::remove(tmp, ec);
      return false;
    }
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return false;
  }
  return true;
}

}  // namespace

DiskCache::DiskCache(fs::path dir, std::uint64_t budget) : dir_(std::move(dir)) {
  counters_.budget = budget;
}

Result<std::unique_ptr<DiskCache>> DiskCache::open(const fs::path& dir, std::uint64_t budget) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    return io_error("disk cache " + dir.string() + ": cannot create the directory" +
                    (ec ? ": " + ec.message() : std::string()));
  std::unique_ptr<DiskCache> cache(new DiskCache(dir, budget));
  // Index what is there, least recently modified first, so the LRU order survives restarts.
  struct Found {
    std::string rel;
    std::uint64_t bytes;
    fs::file_time_type time;
  };
  std::vector<Found> found;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    const fs::path& p = it->path();
    if (p.extension() != ".tile") {
      if (p.filename().string().find(".tile.tmp.") != std::string::npos) fs::remove(p, ec);
      continue;
    }
    found.push_back(
        {fs::relative(p, dir, ec).string(), it->file_size(ec), it->last_write_time(ec)});
  }
  std::sort(found.begin(), found.end(),
            [](const Found& a, const Found& b) { return a.time < b.time; });
  std::vector<fs::path> victims;
  {
    std::lock_guard lock(cache->mutex_);
    for (const Found& f : found) cache->insert_locked(f.rel, f.bytes, victims);
    cache->counters_.inserts = 0;
  }
  for (const fs::path& v : victims) fs::remove(v, ec);
  return cache;
}

std::string DiskCache::relative_path(const TileKey& key, const LayerDescription& layer) const {
  const std::string quadkey = key.tile.z == 0 ? "_" : key.tile.quadkey();
  return std::string(to_string(key.kind)) + "/" + layer.name + "/" + layer.cache_version() + "/" +
         quadkey + ".tile";
}

void DiskCache::insert_locked(const std::string& rel, std::uint64_t bytes,
                              std::vector<fs::path>& victims) {
  erase_locked(rel);
  while (!lru_.empty() && counters_.bytes + bytes > counters_.budget) {
    const Entry& victim = lru_.back();
    victims.push_back(dir_ / victim.rel);
    counters_.bytes -= victim.bytes;
    ++counters_.evictions;
    index_.erase(victim.rel);
    lru_.pop_back();
  }
  lru_.push_front({rel, bytes});
  index_[rel] = lru_.begin();
  counters_.bytes += bytes;
  counters_.peak_bytes = std::max(counters_.peak_bytes, counters_.bytes);
  counters_.largest_entry = std::max(counters_.largest_entry, bytes);
  counters_.entries = lru_.size();
  ++counters_.inserts;
}

void DiskCache::erase_locked(const std::string& rel) {
  const auto it = index_.find(rel);
  if (it == index_.end()) return;
  counters_.bytes -= it->second->bytes;
  lru_.erase(it->second);
  index_.erase(it);
  counters_.entries = lru_.size();
}

std::optional<DiskEntry> DiskCache::get(const TileKey& key, const LayerDescription& layer) {
  const std::string rel = relative_path(key, layer);
  {
    std::lock_guard lock(mutex_);
    const auto it = index_.find(rel);
    if (it == index_.end()) {
      ++counters_.misses;
      return std::nullopt;
    }
    lru_.splice(lru_.begin(), lru_, it->second);
  }
  auto entry = read_file(dir_ / rel);
  std::lock_guard lock(mutex_);
  if (!entry) {
    ++counters_.misses;
    erase_locked(rel);
    std::error_code ec;
    fs::remove(dir_ / rel, ec);
    return std::nullopt;
  }
  ++counters_.hits;
  return entry;
}

void DiskCache::put(const TileKey& key, const LayerDescription& layer, const DiskEntry& entry) {
  const std::string rel = relative_path(key, layer);
  if (!write_file(dir_ / rel, entry)) return;
  const std::uint64_t bytes = 8 + entry.etag.size() + entry.bytes.size();
  std::vector<fs::path> victims;
  {
    std::lock_guard lock(mutex_);
    insert_locked(rel, bytes, victims);
  }
  std::error_code ec;
  for (const fs::path& v : victims) fs::remove(v, ec);
}

void DiskCache::touch(const TileKey& key, const LayerDescription& layer) {
  const std::string rel = relative_path(key, layer);
  {
    std::lock_guard lock(mutex_);
    const auto it = index_.find(rel);
    if (it == index_.end()) return;
    lru_.splice(lru_.begin(), lru_, it->second);
  }
  std::error_code ec;
  fs::last_write_time(dir_ / rel, fs::file_time_type::clock::now(), ec);
}

void DiskCache::erase(const TileKey& key, const LayerDescription& layer) {
  const std::string rel = relative_path(key, layer);
  {
    std::lock_guard lock(mutex_);
    erase_locked(rel);
  }
  std::error_code ec;
  fs::remove(dir_ / rel, ec);
}

TierCounters DiskCache::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace tinstream::client
