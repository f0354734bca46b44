#include "stored_tiles.hpp"

#include <zlib.h>

#include <array>
#include <cstring>

#include "tinstream/store/etag.hpp"
#include "tinstream/terrain/gzip.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::server {
namespace {

constexpr std::size_t kHeaderBytes = 84;  // docs/tile-format.md §3

std::uint32_t u32_at(const std::array<std::uint8_t, kHeaderBytes>& h, std::size_t at) {
  return static_cast<std::uint32_t>(h[at]) | static_cast<std::uint32_t>(h[at + 1]) << 8 |
         static_cast<std::uint32_t>(h[at + 2]) << 16 | static_cast<std::uint32_t>(h[at + 3]) << 24;
}

Error corrupt(const geo::TileId& id, const std::string& what) {
  return Error(ErrorCode::corrupt_data, "tile " + id.to_string() + " in the store: " + what);
}

// The first kHeaderBytes of the inflated blob, inflating nothing past them.
Result<std::array<std::uint8_t, kHeaderBytes>> inflate_header(std::span<const std::uint8_t> zlib,
                                                              const geo::TileId& id) {
  std::array<std::uint8_t, kHeaderBytes> header{};
  z_stream zs{};
  if (inflateInit(&zs) != Z_OK) return Error(ErrorCode::internal, "zlib: inflateInit failed");
  zs.next_in = const_cast<Bytef*>(zlib.data());
  zs.avail_in = static_cast<uInt>(std::min<std::size_t>(zlib.size(), 1u << 30));
  zs.next_out = header.data();
  zs.avail_out = static_cast<uInt>(header.size());
  int rc = Z_OK;
  while (zs.avail_out > 0 && rc == Z_OK) rc = inflate(&zs, Z_SYNC_FLUSH);
  inflateEnd(&zs);
  if (zs.avail_out > 0) return corrupt(id, "the blob is not a zlib stream of a tile");
  return header;
}

}  // namespace

Result<std::size_t> check_blob(const store::StoredTile& stored, const geo::TileId& expected) {
  auto header = inflate_header(stored.compressed, expected);
  if (!header) return header.error();
  const auto& h = *header;
  if (std::memcmp(h.data(), "TINT", 4) != 0) return corrupt(expected, "no tile header (magic)");
  const unsigned version = static_cast<unsigned>(h[4]) | static_cast<unsigned>(h[5]) << 8;
  if (version != 1 && version != 2)
    return corrupt(expected, "unknown format version " + std::to_string(version));
  const geo::TileId held{u32_at(h, 8), u32_at(h, 12), u32_at(h, 16)};
  if (held != expected) return corrupt(expected, "the blob holds tile " + held.to_string());
  std::uint64_t vertices = 4;
  for (std::size_t at = 20; at <= 36; at += 4) vertices += u32_at(h, at);
  const std::uint64_t triangles = u32_at(h, 40);
  const std::uint64_t width = h[6] == 4 ? 4 : 2;
  const std::uint64_t size = kHeaderBytes + 32 * vertices + 3 * width * triangles;
  if (size > kMaxTileBytes) {
    return corrupt(expected, "declares " + std::to_string(size) + " bytes, more than the " +
                                 std::to_string(kMaxTileBytes) + " a tile may have");
  }
  return static_cast<std::size_t>(size);
}

Result<std::vector<std::uint8_t>> inflate_blob(const store::StoredTile& stored,
                                               const geo::TileId& expected) {
  auto size = check_blob(stored, expected);
  if (!size) return size.error();
  auto raw = tile::decompress(stored.compressed, *size);
  if (!raw) return corrupt(expected, raw.error().message);
  return raw;
}

Result<std::vector<std::uint8_t>> blob_as_gzip(const store::StoredTile& stored,
                                               const geo::TileId& expected) {
  auto size = check_blob(stored, expected);
  if (!size) return size.error();
  auto gz = terrain::zlib_to_gzip(stored.compressed, *size);
  if (!gz) return corrupt(expected, gz.error().message);
  return gz;
}

std::string safe_etag(const store::StoredTile& stored) {
  const std::string& tag = stored.etag;
  bool ok = tag.size() >= 3 && tag.size() <= 258 && tag.front() == '"' && tag.back() == '"';
  for (std::size_t i = 1; ok && i + 1 < tag.size(); ++i) {
    const auto c = static_cast<unsigned char>(tag[i]);
    ok = c == 0x21 || (c >= 0x23 && c <= 0x7e);
  }
  return ok ? tag : store::make_etag(stored.compressed);
}

Status check_layer_row(const store::LayerInfo& info) {
  if (info.min_level <= info.max_level && info.max_level <= 30) return {};
  return Error(ErrorCode::corrupt_data,
               "layer \"" + info.name + "\" is corrupt in the store: min_level " +
                   std::to_string(info.min_level) + ", max_level " +
                   std::to_string(info.max_level) + " (min_level <= max_level <= 30)");
}

}  // namespace tinstream::server
