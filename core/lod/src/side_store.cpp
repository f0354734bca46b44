#include "side_store.hpp"

#include <unistd.h>

#include <chrono>
#include <cstring>
#include <string>

namespace tinstream::lod::detail {

namespace {

template <typename T>
void put_value(std::vector<std::uint8_t>& out, T v) {
  const auto at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));
}

template <typename T>
bool get_value(std::span<const std::uint8_t> in, std::size_t& at, T& v) {
  if (in.size() - at < sizeof(T)) return false;
  std::memcpy(&v, in.data() + at, sizeof(T));
  at += sizeof(T);
  return true;
}

}  // namespace

std::vector<std::uint8_t> encode_side(const LodTile& tile) {
  std::vector<std::uint8_t> out;
  out.reserve(8 + 8 * tile.bounds.size() + 32 * tile.witnesses.size());
  put_value(out, static_cast<std::uint32_t>(tile.bounds.size()));
  for (const auto& b : tile.bounds) put_value(out, b.above), put_value(out, b.below);
  put_value(out, static_cast<std::uint32_t>(tile.reaches.size()));
  for (const auto& b : tile.reaches) put_value(out, b.triangle), put_value(out, b.reach);
  put_value(out, static_cast<std::uint32_t>(tile.witnesses.size()));
  for (const auto& w : tile.witnesses) {
    put_value(out, w.x), put_value(out, w.y), put_value(out, w.z), put_value(out, w.weight);
  }
  return out;
}

Status decode_side(std::span<const std::uint8_t> record, LodTile& tile) {
  const std::string where = "lod: side record of tile " + tile.tile.id.to_string();
  std::size_t at = 0;
  std::uint32_t n = 0;
  if (!get_value(record, at, n) || n != tile.tile.triangles.size()) {
    return corrupt_data(where + ": triangle count does not match the tile");
  }
  tile.bounds.resize(n);
  for (auto& b : tile.bounds) {
    if (!get_value(record, at, b.above) || !get_value(record, at, b.below)) {
      return corrupt_data(where + ": truncated");
    }
  }
  if (!get_value(record, at, n)) return corrupt_data(where + ": truncated");
  tile.reaches.resize(n);
  for (auto& b : tile.reaches) {
    if (!get_value(record, at, b.triangle) || !get_value(record, at, b.reach) ||
        b.triangle >= tile.tile.triangles.size() || !(b.reach >= 0 && b.reach <= 1)) {
      return corrupt_data(where + ": bad residual reach");
    }
  }
  if (!get_value(record, at, n) || record.size() - at != std::size_t{n} * 32) {
    return corrupt_data(where + ": bad witness count");
  }
  tile.witnesses.resize(n);
  for (auto& w : tile.witnesses) {
    get_value(record, at, w.x), get_value(record, at, w.y), get_value(record, at, w.z);
    get_value(record, at, w.weight);
  }
  return {};
}

SideStore::~SideStore() {
  while (!files_.empty()) forget_level(files_.begin()->first);
}

Result<SideStore::LevelFile*> SideStore::file_of(std::uint32_t z) {
  auto [it, fresh] = files_.try_emplace(z);
  LevelFile& f = it->second;
  if (fresh) {
    f.path = dir_ / ("lod-side-" + std::to_string(::getpid()) + "-" +
                     std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()) +
                     "-level" + std::to_string(z));
    f.file.reset(std::fopen(f.path.c_str(), "w+b"));
  }
  if (!f.file) return io_error("lod: cannot create the side file " + f.path.string());
  return &f;
}

Status SideStore::put(const geo::TileId& id, std::vector<std::uint8_t> record) {
  if (dir_.empty()) {
    memory_[id] = std::move(record);
    return {};
  }
  auto f = file_of(id.z);
  if (!f) return f.error();
  LevelFile& level = **f;
  if (std::fseek(level.file.get(), static_cast<long>(level.end), SEEK_SET) != 0 ||
      std::fwrite(record.data(), 1, record.size(), level.file.get()) != record.size()) {
    return io_error("lod: cannot write the side file " + level.path.string());
  }
  index_[id] = {level.end, record.size()};
  level.end += record.size();
  return {};
}

Result<std::optional<std::vector<std::uint8_t>>> SideStore::get(const geo::TileId& id) {
  using Found = std::optional<std::vector<std::uint8_t>>;
  if (dir_.empty()) {
    const auto it = memory_.find(id);
    return it == memory_.end() ? Found{} : Found{it->second};
  }
  const auto it = index_.find(id);
  const auto level = files_.find(id.z);
  if (it == index_.end() || level == files_.end()) return Found{};
  std::FILE* file = level->second.file.get();
  std::vector<std::uint8_t> out(it->second.second);
  if (std::fflush(file) != 0 ||
      std::fseek(file, static_cast<long>(it->second.first), SEEK_SET) != 0 ||
      std::fread(out.data(), 1, out.size(), file) != out.size()) {
    return io_error("lod: cannot read the side file " + level->second.path.string());
  }
  return Found{std::move(out)};
}

void SideStore::forget_level(std::uint32_t z) {
  std::erase_if(memory_, [&](const auto& e) { return e.first.z == z; });
  std::erase_if(index_, [&](const auto& e) { return e.first.z == z; });
  if (const auto it = files_.find(z); it != files_.end()) {
    it->second.file.reset();
    std::error_code ec;
    std::filesystem::remove(it->second.path, ec);
    files_.erase(it);
  }
}

}  // namespace tinstream::lod::detail
