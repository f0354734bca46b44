#include "tinstream/terrain/gzip.hpp"

#include <zlib.h>

#include <climits>
#include <string>

#include "tinstream/tile/codec.hpp"

namespace tinstream::terrain {
namespace {

// windowBits: 15 = zlib, 15 + 16 = gzip, -15 = raw deflate.
Result<std::vector<std::uint8_t>> inflate_with(std::span<const std::uint8_t> bytes,
                                               std::size_t max_output, int window_bits,
                                               const char* what) {
  if (bytes.size() > UINT_MAX) return corrupt_data(std::string(what) + ": input too large");
  z_stream zs{};
  if (inflateInit2(&zs, window_bits) != Z_OK) return io_error("inflateInit2 failed");
  zs.next_in = const_cast<Bytef*>(bytes.data());
  zs.avail_in = static_cast<uInt>(bytes.size());
  std::vector<std::uint8_t> out;
  std::uint8_t chunk[16384];
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    zs.next_out = chunk;
    zs.avail_out = sizeof chunk;
    rc = inflate(&zs, Z_NO_FLUSH);
    if (rc != Z_OK && rc != Z_STREAM_END) {
      inflateEnd(&zs);
      return corrupt_data(std::string(what) + ": corrupt or truncated stream");
    }
    const std::size_t produced = sizeof chunk - zs.avail_out;
    if (out.size() + produced > max_output) {
      inflateEnd(&zs);
      return corrupt_data(std::string(what) + ": inflates past the size limit");
    }
    out.insert(out.end(), chunk, chunk + produced);
    if (rc == Z_OK && produced == 0 && zs.avail_in == 0) {
      inflateEnd(&zs);
      return corrupt_data(std::string(what) + ": truncated stream");
    }
  }
  inflateEnd(&zs);
  return out;
}

}  // namespace

std::vector<std::uint8_t> gzip_compress(std::span<const std::uint8_t> bytes, int level) {
  return tile::compress_gzip(bytes, level);  // libdeflate: ~2x zlib's speed, a little smaller
}

Result<std::vector<std::uint8_t>> gzip_decompress(std::span<const std::uint8_t> bytes,
                                                  std::size_t max_output) {
  return inflate_with(bytes, max_output, 15 + 16, "gzip");
}

Result<std::vector<std::uint8_t>> zlib_to_gzip(std::span<const std::uint8_t> zlib,
                                               std::size_t max_output) {
  // RFC 1950: CMF FLG [DICTID] deflate-data ADLER32. We need no preset dictionary.
  if (zlib.size() < 6 || (zlib[0] & 0x0f) != 8 || ((zlib[0] << 8) | zlib[1]) % 31 != 0 ||
      (zlib[1] & 0x20) != 0) {
    return corrupt_data("zlib: not a zlib stream without preset dictionary");
  }
  auto raw = inflate_with(zlib, max_output, 15, "zlib");
  if (!raw) return raw.error();
  const auto& data = raw.value();
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), data.data(), static_cast<uInt>(data.size()));
  std::vector<std::uint8_t> out = {0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0xff};  // OS unknown
  out.insert(out.end(), zlib.begin() + 2, zlib.end() - 4);
  const auto size = static_cast<std::uint32_t>(data.size());
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(crc >> (8 * i)));
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(size >> (8 * i)));
  return out;
}

}  // namespace tinstream::terrain
