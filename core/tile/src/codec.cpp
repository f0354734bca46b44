// The native tile blob; docs/tile-format.md is the specification this file implements.
#include "tinstream/tile/codec.hpp"

#include <libdeflate.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <string>

namespace tinstream::tile {

namespace {

constexpr std::array<std::uint8_t, 4> kMagic{'T', 'I', 'N', 'T'};
constexpr std::uint16_t kVersion = 1;
constexpr std::size_t kHeaderSize = 84;
constexpr std::size_t kVertexSize = 32;
// Triangles use 16-bit indices when every index fits, 32-bit otherwise.
constexpr std::uint64_t kMaxVerticesFor16Bit = 65536;

class Writer {
 public:
  explicit Writer(std::size_t reserve) { out_.reserve(reserve); }
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { put_le(v); }
  void u32(std::uint32_t v) { put_le(v); }
  void u64(std::uint64_t v) { put_le(v); }
  void f64(double v) { put_le(std::bit_cast<std::uint64_t>(v)); }
  void bytes(const std::uint8_t* p, std::size_t n) { out_.insert(out_.end(), p, p + n); }
  std::vector<std::uint8_t> take() { return std::move(out_); }

 private:
  template <typename U>
  void put_le(U v) {
    for (std::size_t i = 0; i < sizeof(U); ++i) {
      out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
    }
  }
  std::vector<std::uint8_t> out_;
};

// Reads little-endian values; the caller has checked the total size up front, so the reads here
// only assert (a short read would be a bug in decode's size computation).
class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  std::size_t remaining() const { return bytes_.size() - pos_; }
  std::size_t position() const { return pos_; }
  std::uint8_t u8() { return static_cast<std::uint8_t>(get_le<std::uint8_t>()); }
  std::uint16_t u16() { return get_le<std::uint16_t>(); }
  std::uint32_t u32() { return get_le<std::uint32_t>(); }
  std::uint64_t u64() { return get_le<std::uint64_t>(); }
  double f64() { return std::bit_cast<double>(get_le<std::uint64_t>()); }

 private:
  template <typename U>
  U get_le() {
    assert(remaining() >= sizeof(U));
    U v = 0;
    for (std::size_t i = 0; i < sizeof(U); ++i) {
      v = static_cast<U>(v | static_cast<U>(static_cast<U>(bytes_[pos_ + i]) << (8 * i)));
    }
    pos_ += sizeof(U);
    return v;
  }
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
};

void write_vertex(Writer& w, const Vertex& v) {
  w.f64(v.x);
  w.f64(v.y);
  w.f64(v.z);
  w.f64(v.weight);
}

}  // namespace

std::vector<std::uint8_t> encode(const TinTile& tile) {
  const std::uint64_t vertex_count = tile.vertex_count();
  assert(vertex_count <= std::numeric_limits<std::uint32_t>::max());
  const std::size_t index_width = vertex_count <= kMaxVerticesFor16Bit ? 2 : 4;
  Writer w(kHeaderSize + vertex_count * kVertexSize + tile.triangles.size() * 3 * index_width);

  w.bytes(kMagic.data(), kMagic.size());
  w.u16(kVersion);
  w.u8(static_cast<std::uint8_t>(index_width));
  std::uint8_t nodata = 0;
  for (std::size_t c = 0; c < 4; ++c) {
    if (tile.corner_nodata[c]) nodata = static_cast<std::uint8_t>(nodata | (1u << c));
  }
  w.u8(nodata);
  w.u32(tile.id.z);
  w.u32(tile.id.x);
  w.u32(tile.id.y);
  for (const auto* list : {&tile.north, &tile.east, &tile.south, &tile.west, &tile.interior}) {
    w.u32(static_cast<std::uint32_t>(list->size()));
  }
  w.u32(static_cast<std::uint32_t>(tile.triangles.size()));
  w.f64(tile.min_z);
  w.f64(tile.max_z);
  w.f64(tile.geometric_error);
  w.f64(tile.rms_error);
  w.u64(tile.source_points);

  for (const Vertex& v : tile.corners) write_vertex(w, v);
  for (const auto* list : {&tile.north, &tile.east, &tile.south, &tile.west, &tile.interior}) {
    for (const Vertex& v : *list) write_vertex(w, v);
  }
  for (const Triangle& t : tile.triangles) {
    for (const std::uint32_t index : t) {
      if (index_width == 2) {
        w.u16(static_cast<std::uint16_t>(index));
      } else {
        w.u32(index);
      }
    }
  }
  return w.take();
}

Result<TinTile> decode(std::span<const std::uint8_t> bytes) {
  const auto bad = [](const std::string& what) { return corrupt_data("tile blob: " + what); };
  if (bytes.size() < kHeaderSize) {
    return bad("truncated header (" + std::to_string(bytes.size()) + " of " +
               std::to_string(kHeaderSize) + " bytes)");
  }
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    return bad("bad magic (not a tinstream tile)");
  }
  Reader r(bytes.subspan(kMagic.size()));
  const std::uint16_t version = r.u16();
  if (version != kVersion) {
    return unsupported("tile blob: format version " + std::to_string(version) +
                       " is not supported (this build reads version " + std::to_string(kVersion) +
                       ")");
  }
  const std::uint8_t index_width = r.u8();
  const std::uint8_t nodata = r.u8();
  if (index_width != 2 && index_width != 4) {
    return bad("triangle index width " + std::to_string(index_width) + " is neither 2 nor 4");
  }
  if ((nodata & 0xF0u) != 0) return bad("reserved bits set in the corner NODATA flags");

  TinTile tile;
  const std::uint32_t z = r.u32(), x = r.u32(), y = r.u32();
  const auto id = geo::TileId::from_zxy(z, x, y);
  if (!id) return bad("invalid tile id: " + id.error().message);
  tile.id = *id;
  const std::string name = "tile blob " + tile.id.to_string() + ": ";

  std::array<std::uint32_t, 5> list_sizes{};
  for (auto& n : list_sizes) n = r.u32();
  const std::uint32_t triangle_count = r.u32();

  // Validate every count against the bytes that are really there before allocating anything.
  std::uint64_t vertex_count = 4;
  for (const auto n : list_sizes) vertex_count += n;
  if (vertex_count > std::numeric_limits<std::uint32_t>::max()) {
    return corrupt_data(name + "vertex count exceeds 32-bit indices");
  }
  const std::size_t expected_width = vertex_count <= kMaxVerticesFor16Bit ? 2 : 4;
  if (index_width != expected_width) {
    return corrupt_data(name + "triangle index width " + std::to_string(index_width) +
                        " does not match " + std::to_string(vertex_count) + " vertices");
  }
  const std::uint64_t expected_size =
      kHeaderSize + vertex_count * kVertexSize + std::uint64_t{triangle_count} * 3 * index_width;
  if (expected_size != bytes.size()) {
    return corrupt_data(name + "counts (" + std::to_string(vertex_count) + " vertices, " +
                        std::to_string(triangle_count) + " triangles) need " +
                        std::to_string(expected_size) + " bytes, the blob has " +
                        std::to_string(bytes.size()));
  }

  tile.min_z = r.f64();
  tile.max_z = r.f64();
  tile.geometric_error = r.f64();
  tile.rms_error = r.f64();
  tile.source_points = r.u64();
  if (!std::isfinite(tile.min_z) || !std::isfinite(tile.max_z) ||
      !std::isfinite(tile.geometric_error) || !std::isfinite(tile.rms_error)) {
    return corrupt_data(name + "non-finite statistics");
  }
  for (std::size_t c = 0; c < 4; ++c) tile.corner_nodata[c] = ((nodata >> c) & 1u) != 0;

  std::uint64_t vertex_index = 0;
  const auto read_vertex = [&](Vertex& v) -> bool {
    v.x = r.f64();
    v.y = r.f64();
    v.z = r.f64();
    v.weight = r.f64();
    ++vertex_index;
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) &&
           std::isfinite(v.weight);
  };
  const auto non_finite = [&] {
    return corrupt_data(name + "vertex " + std::to_string(vertex_index - 1) +
                        " has a non-finite value");
  };
  for (Vertex& v : tile.corners) {
    if (!read_vertex(v)) return non_finite();
  }
  std::array<std::vector<Vertex>*, 5> lists{&tile.north, &tile.east, &tile.south, &tile.west,
                                            &tile.interior};
  for (std::size_t l = 0; l < lists.size(); ++l) {
    lists[l]->resize(list_sizes[l]);
    for (Vertex& v : *lists[l]) {
      if (!read_vertex(v)) return non_finite();
    }
  }
  tile.triangles.resize(triangle_count);
  for (std::size_t t = 0; t < tile.triangles.size(); ++t) {
    for (std::uint32_t& index : tile.triangles[t]) {
      index = index_width == 2 ? r.u16() : r.u32();
      if (index >= vertex_count) {
        return corrupt_data(name + "triangle " + std::to_string(t) + " refers to vertex " +
                            std::to_string(index) + " of " + std::to_string(vertex_count));
      }
    }
  }
  assert(r.remaining() == 0);
  return tile;
}

namespace {

// libdeflate (de)compressors are not thread-safe but cheap to keep: one per thread and level.
struct DeflateCompressor {
  libdeflate_compressor* c = nullptr;
  int level = -1;
  ~DeflateCompressor() { libdeflate_free_compressor(c); }
};
struct DeflateDecompressor {
  libdeflate_decompressor* d = libdeflate_alloc_decompressor();
  ~DeflateDecompressor() { libdeflate_free_decompressor(d); }
};

// This thread's compressor at `level` (0–12), kept from call to call.
libdeflate_compressor* compressor(int level) {
  thread_local DeflateCompressor state;
  level = std::clamp(level, 0, 12);
  if (state.level != level) {
    libdeflate_free_compressor(state.c);
    state.c = libdeflate_alloc_compressor(level);
    state.level = level;
  }
  if (state.c == nullptr) throw std::bad_alloc();
  return state.c;
}

// `bytes` through this thread's compressor at `level`, in the container of Bound/Compress
// (libdeflate's zlib or gzip pair).
template <auto Bound, auto Compress>
std::vector<std::uint8_t> deflate_into(std::span<const std::uint8_t> bytes, int level) {
  libdeflate_compressor* c = compressor(level);
  std::vector<std::uint8_t> out(Bound(c, bytes.size()));
  const std::size_t n = Compress(c, bytes.data(), bytes.size(), out.data(), out.size());
  assert(n > 0);  // the bound always suffices
  out.resize(n);
  return out;
}

}  // namespace

std::vector<std::uint8_t> compress(std::span<const std::uint8_t> bytes, int level) {
  return deflate_into<libdeflate_zlib_compress_bound, libdeflate_zlib_compress>(bytes, level);
}

std::vector<std::uint8_t> compress_gzip(std::span<const std::uint8_t> bytes, int level) {
  return deflate_into<libdeflate_gzip_compress_bound, libdeflate_gzip_compress>(bytes, level);
}

Result<std::vector<std::uint8_t>> decompress(std::span<const std::uint8_t> bytes,
                                             std::size_t max_output) {
  thread_local DeflateDecompressor state;
  if (state.d == nullptr) return Error(ErrorCode::internal, "zlib: out of memory");
  // The inflated size is not stored: start from 4× the input (tiles inflate ~2×) and double up to
  // the limit. One byte past the limit tells "exactly at the limit" from "over it".
  const std::size_t ceiling =
      max_output == std::numeric_limits<std::size_t>::max() ? max_output : max_output + 1;
  std::size_t capacity =
      std::min(ceiling, std::max<std::size_t>(4 * bytes.size() + 1024, std::size_t{1} << 12));
  std::vector<std::uint8_t> out;
  for (;;) {
    out.resize(capacity);
    std::size_t used_in = 0, produced = 0;
    const libdeflate_result rc = libdeflate_zlib_decompress_ex(
        state.d, bytes.data(), bytes.size(), out.data(), out.size(), &used_in, &produced);
    if (rc == LIBDEFLATE_SUCCESS) {
      if (produced > max_output) {
        return corrupt_data("zlib: inflated data exceed the limit of " +
                            std::to_string(max_output) + " bytes");
      }
      if (used_in != bytes.size()) {
        return corrupt_data("zlib: trailing bytes after the end of the stream");
      }
      out.resize(produced);
      return out;
    }
    if (rc == LIBDEFLATE_INSUFFICIENT_SPACE) {
      if (capacity >= ceiling) {
        return corrupt_data("zlib: inflated data exceed the limit of " +
                            std::to_string(max_output) + " bytes");
      }
      capacity = capacity > ceiling / 2 ? ceiling : 2 * capacity;
      continue;
    }
    return corrupt_data("zlib: corrupt or truncated stream");
  }
}

}  // namespace tinstream::tile
