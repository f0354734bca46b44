// The native tile blob; docs/tile-format.md is the specification this file implements.
//
// Two body layouts share one 84-byte header (§3 of the specification):
//
//   version 1   vertices as V records (x, y, z, weight) of f64, then the triangle indices;
//   version 2   the same 32·V + 3·W·T bytes, rearranged for deflate (§4):
//
//       [ 84-byte header ][ vertex planes: 8 × 4V bytes ][ index planes: W × 3T bytes ]
//
//     vertex words: the 4V f64 bit patterns in column order (x of every vertex, then y, z,
//     weight), each replaced by the zigzag of its difference (mod 2^64) from the word before it
//     in the same column; plane p holds byte p of every word. Index words: the 3T indices, each
//     the zigzag of its difference (mod 2^(8W)) from the index before it; plane p holds byte p.
//
// Both transforms are bijections on the bit patterns, so version 2 is as lossless and as
// canonical as version 1, and it has the same size.
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
constexpr std::size_t kHeaderSize = 84;
constexpr std::size_t kVertexSize = 32;
// Triangles use 16-bit indices when every index fits, 32-bit otherwise.
constexpr std::uint64_t kMaxVerticesFor16Bit = 65536;

// The vertex columns of version 2, in blob order, and their names for error messages.
constexpr std::array<double Vertex::*, 4> kColumns{&Vertex::x, &Vertex::y, &Vertex::z,
                                                   &Vertex::weight};
constexpr std::array<const char*, 4> kColumnNames{"x", "y", "z", "weight"};

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

// Calls f(vertex) for every vertex of `tile` (const or not) in the numbering of tin_tile.hpp.
template <typename Tile, typename F>
void for_each_vertex(Tile& tile, F&& f) {
  for (auto& v : tile.corners) f(v);
  for (auto* list : {&tile.north, &tile.east, &tile.south, &tile.west, &tile.interior}) {
    for (auto& v : *list) f(v);
  }
}

// Zigzag maps a difference taken modulo 2^bits to small codes for small magnitudes of either sign
// (0, -1, 1, -2 … → 0, 1, 2, 3 …); `mask` is 2^bits − 1 and `top` is bits − 1.
template <typename U>
constexpr U zigzag(U d, U mask, unsigned top) {
  return static_cast<U>(((d << 1) ^ (U{0} - (d >> top))) & mask);
}
template <typename U>
constexpr U unzigzag(U e, U mask) {
  return static_cast<U>(((e >> 1) ^ (U{0} - (e & 1u))) & mask);
}
static_assert(zigzag<std::uint32_t>(0xFFFFu, 0xFFFFu, 15) == 1);  // −1 in 16 bits
static_assert(unzigzag<std::uint32_t>(1, 0xFFFFu) == 0xFFFFu);
static_assert(zigzag<std::uint64_t>(2, ~std::uint64_t{0}, 63) == 4);

void write_vertex(Writer& w, const Vertex& v) {
  w.f64(v.x);
  w.f64(v.y);
  w.f64(v.z);
  w.f64(v.weight);
}

void write_header(Writer& w, const TinTile& tile, FormatVersion version, std::size_t index_width) {
  w.bytes(kMagic.data(), kMagic.size());
  w.u16(static_cast<std::uint16_t>(version));
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
}

void write_body_v1(Writer& w, const TinTile& tile, std::size_t index_width) {
  for_each_vertex(tile, [&](const Vertex& v) { write_vertex(w, v); });
  for (const Triangle& t : tile.triangles) {
    for (const std::uint32_t index : t) {
      if (index_width == 2) {
        w.u16(static_cast<std::uint16_t>(index));
      } else {
        w.u32(index);
      }
    }
  }
}

// Version 2 body into `out` (exactly 32·V + 3·W·T bytes, see the top of this file).
void write_body_v2(std::uint8_t* out, const TinTile& tile, std::size_t vertex_count,
                   std::size_t index_width) {
  const std::size_t words = 4 * vertex_count;  // bytes per vertex plane
  std::size_t k = 0;
  for (double Vertex::*const column : kColumns) {
    std::uint64_t previous = 0;
    for_each_vertex(tile, [&](const Vertex& v) {
      const auto bits = std::bit_cast<std::uint64_t>(v.*column);
      const std::uint64_t code = zigzag<std::uint64_t>(bits - previous, ~std::uint64_t{0}, 63);
      previous = bits;
      for (std::size_t p = 0; p < 8; ++p) {
        out[p * words + k] = static_cast<std::uint8_t>(code >> (8 * p));
      }
      ++k;
    });
  }
  std::uint8_t* indices = out + 8 * words;
  const std::size_t n = 3 * tile.triangles.size();  // bytes per index plane
  const std::uint32_t mask = index_width == 2 ? 0xFFFFu : 0xFFFFFFFFu;
  const unsigned top = index_width == 2 ? 15 : 31;
  std::uint32_t previous = 0;
  std::size_t i = 0;
  for (const Triangle& t : tile.triangles) {
    for (const std::uint32_t index : t) {
      const std::uint32_t code = zigzag<std::uint32_t>((index - previous) & mask, mask, top);
      previous = index;
      for (std::size_t p = 0; p < index_width; ++p) {
        indices[p * n + i] = static_cast<std::uint8_t>(code >> (8 * p));
      }
      ++i;
    }
  }
}

}  // namespace

std::vector<std::uint8_t> encode(const TinTile& tile, FormatVersion version) {
  const std::uint64_t vertex_count = tile.vertex_count();
  assert(vertex_count <= std::numeric_limits<std::uint32_t>::max());
  const std::size_t index_width = vertex_count <= kMaxVerticesFor16Bit ? 2 : 4;
  const std::size_t body = vertex_count * kVertexSize + tile.triangles.size() * 3 * index_width;
  Writer w(kHeaderSize + body);
  write_header(w, tile, version, index_width);
  if (version == FormatVersion::v1) {
    write_body_v1(w, tile, index_width);
    return w.take();
  }
  assert(version == FormatVersion::v2);
  std::vector<std::uint8_t> out = w.take();
  out.resize(kHeaderSize + body);
  write_body_v2(out.data() + kHeaderSize, tile, vertex_count, index_width);
  return out;
}

namespace {

// The counts of the header, validated against the blob's size by decode().
struct Layout {
  std::array<std::uint32_t, 5> list_sizes{};  // north, east, south, west, interior
  std::uint32_t triangle_count = 0;
  std::uint64_t vertex_count = 0;
  std::size_t index_width = 0;
};

// Fills the vertex lists from a version-1 body. The `bad` of the caller names the tile.
template <typename Bad>
Result<TinTile> read_body_v1(Reader& r, TinTile tile, const Layout& layout, const Bad& bad) {
  std::uint64_t vertex_index = 0;
  bool finite = true;
  for_each_vertex(tile, [&](Vertex& v) {
    v.x = r.f64();
    v.y = r.f64();
    v.z = r.f64();
    v.weight = r.f64();
    if (finite && !(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) &&
                    std::isfinite(v.weight))) {
      finite = false;
    } else if (finite) {
      ++vertex_index;
    }
  });
  if (!finite) return bad("vertex " + std::to_string(vertex_index) + " has a non-finite value");
  for (std::size_t t = 0; t < tile.triangles.size(); ++t) {
    for (std::uint32_t& index : tile.triangles[t]) {
      index = layout.index_width == 2 ? r.u16() : r.u32();
      if (index >= layout.vertex_count) {
        return bad("triangle " + std::to_string(t) + " refers to vertex " + std::to_string(index) +
                   " of " + std::to_string(layout.vertex_count));
      }
    }
  }
  assert(r.remaining() == 0);
  return tile;
}

// Fills the vertex lists from a version-2 body (`body` is exactly 32·V + 3·W·T bytes).
template <typename Bad>
Result<TinTile> read_body_v2(std::span<const std::uint8_t> body, TinTile tile, const Layout& layout,
                             const Bad& bad) {
  const std::size_t words = 4 * layout.vertex_count;
  const std::uint8_t* planes = body.data();
  std::size_t k = 0;
  for (std::size_t c = 0; c < kColumns.size(); ++c) {
    double Vertex::*const column = kColumns[c];
    std::uint64_t previous = 0;
    std::size_t first_bad = std::numeric_limits<std::size_t>::max();
    std::size_t vertex_index = 0;
    for_each_vertex(tile, [&](Vertex& v) {
      std::uint64_t code = 0;
      for (std::size_t p = 0; p < 8; ++p) {
        code |= std::uint64_t{planes[p * words + k]} << (8 * p);
      }
      previous += unzigzag<std::uint64_t>(code, ~std::uint64_t{0});
      v.*column = std::bit_cast<double>(previous);
      if (!std::isfinite(v.*column) && first_bad > vertex_index) first_bad = vertex_index;
      ++vertex_index;
      ++k;
    });
    if (first_bad != std::numeric_limits<std::size_t>::max()) {
      return bad("vertex " + std::to_string(first_bad) + " has a non-finite " + kColumnNames[c]);
    }
  }
  const std::uint8_t* indices = planes + 8 * words;
  const std::size_t n = 3 * std::size_t{layout.triangle_count};
  const std::uint32_t mask = layout.index_width == 2 ? 0xFFFFu : 0xFFFFFFFFu;
  std::uint32_t previous = 0;
  std::size_t i = 0;
  for (std::size_t t = 0; t < tile.triangles.size(); ++t) {
    for (std::uint32_t& index : tile.triangles[t]) {
      std::uint32_t code = 0;
      for (std::size_t p = 0; p < layout.index_width; ++p) {
        code |= std::uint32_t{indices[p * n + i]} << (8 * p);
      }
      ++i;
      previous = (previous + unzigzag<std::uint32_t>(code, mask)) & mask;
      index = previous;
      if (index >= layout.vertex_count) {
        return bad("triangle " + std::to_string(t) + " refers to vertex " + std::to_string(index) +
                   " of " + std::to_string(layout.vertex_count));
      }
    }
  }
  return tile;
}

}  // namespace

Result<TinTile> decode(std::span<const std::uint8_t> bytes) {
  const auto blob_error = [](const std::string& what) {
    return corrupt_data("tile blob: " + what);
  };
  if (bytes.size() < kHeaderSize) {
    return blob_error("truncated header (" + std::to_string(bytes.size()) + " of " +
                      std::to_string(kHeaderSize) + " bytes)");
  }
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    return blob_error("bad magic (not a tinstream tile)");
  }
  Reader r(bytes.subspan(kMagic.size()));
  const std::uint16_t version = r.u16();
  if (version != static_cast<std::uint16_t>(FormatVersion::v1) &&
      version != static_cast<std::uint16_t>(FormatVersion::v2)) {
    return unsupported("tile blob: format version " + std::to_string(version) +
                       " is not supported (this build reads versions 1 and 2)");
  }
  const std::uint8_t index_width = r.u8();
  const std::uint8_t nodata = r.u8();
  if (index_width != 2 && index_width != 4) {
    return blob_error("triangle index width " + std::to_string(index_width) +
                      " is neither 2 nor 4");
  }
  if ((nodata & 0xF0u) != 0) return blob_error("reserved bits set in the corner NODATA flags");

  TinTile tile;
  const std::uint32_t z = r.u32(), x = r.u32(), y = r.u32();
  const auto id = geo::TileId::from_zxy(z, x, y);
  if (!id) return blob_error("invalid tile id: " + id.error().message);
  tile.id = *id;
  const std::string name =
      "tile blob " + tile.id.to_string() + " (version " + std::to_string(version) + "): ";
  const auto bad = [&name](const std::string& what) { return corrupt_data(name + what); };

  Layout layout;
  for (auto& n : layout.list_sizes) n = r.u32();
  layout.triangle_count = r.u32();
  layout.index_width = index_width;

  // Validate every count against the bytes that are really there before allocating anything.
  layout.vertex_count = 4;
  for (const auto n : layout.list_sizes) layout.vertex_count += n;
  if (layout.vertex_count > std::numeric_limits<std::uint32_t>::max()) {
    return bad("vertex count exceeds 32-bit indices");
  }
  const std::size_t expected_width = layout.vertex_count <= kMaxVerticesFor16Bit ? 2 : 4;
  if (index_width != expected_width) {
    return bad("triangle index width " + std::to_string(index_width) + " does not match " +
               std::to_string(layout.vertex_count) + " vertices");
  }
  const std::uint64_t expected_size = kHeaderSize + layout.vertex_count * kVertexSize +
                                      std::uint64_t{layout.triangle_count} * 3 * index_width;
  if (expected_size != bytes.size()) {
    return bad("counts (" + std::to_string(layout.vertex_count) + " vertices, " +
               std::to_string(layout.triangle_count) + " triangles) need " +
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
    return bad("non-finite statistics");
  }
  for (std::size_t c = 0; c < 4; ++c) tile.corner_nodata[c] = ((nodata >> c) & 1u) != 0;
  tile.north.resize(layout.list_sizes[0]);
  tile.east.resize(layout.list_sizes[1]);
  tile.south.resize(layout.list_sizes[2]);
  tile.west.resize(layout.list_sizes[3]);
  tile.interior.resize(layout.list_sizes[4]);
  tile.triangles.resize(layout.triangle_count);

  assert(r.position() + kMagic.size() == kHeaderSize);
  if (version == static_cast<std::uint16_t>(FormatVersion::v1)) {
    return read_body_v1(r, std::move(tile), layout, bad);
  }
  return read_body_v2(bytes.subspan(kHeaderSize), std::move(tile), layout, bad);
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
