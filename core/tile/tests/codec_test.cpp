#include "tinstream/tile/codec.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "test_tiles.hpp"

namespace tinstream::tile {
namespace {

using testing::make_grid_tile;
using testing::random_tile_id;
using testing::same_tile;

TinTile random_tile(std::mt19937_64& rng, std::uint32_t max_cells = 12) {
  const auto id = random_tile_id(rng);
  return make_grid_tile(id, 1 + static_cast<std::uint32_t>(rng() % max_cells),
                        1 + static_cast<std::uint32_t>(rng() % max_cells), rng);
}

constexpr std::array<FormatVersion, 2> kVersions{FormatVersion::v1, FormatVersion::v2};

// The version field of a blob (bytes 4–5), for re-encoding what decode() accepted.
FormatVersion version_of(std::span<const std::uint8_t> b) {
  return static_cast<FormatVersion>(b[4] | b[5] << 8);
}

void put_u32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i)
    b[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}

TEST(Codec, RoundTripsRandomTilesBitExactly) {
  std::mt19937_64 rng(11);
  for (int i = 0; i < 300; ++i) {
    const TinTile t = random_tile(rng);
    for (const FormatVersion version : kVersions) {
      const auto bytes = encode(t, version);
      EXPECT_EQ(version_of(bytes), version);
      const auto back = decode(bytes);
      ASSERT_TRUE(back.ok()) << back.error().message;
      EXPECT_TRUE(same_tile(t, *back)) << t.id.to_string();
      EXPECT_TRUE(check_structure(*back).ok());
      EXPECT_EQ(encode(*back, version), bytes);  // canonical: one tile, one blob per version
    }
  }
}

TEST(Codec, RoundTripsSpecialDoubles) {
  std::mt19937_64 rng(12);
  TinTile t = make_grid_tile({10, 3, 1000}, 2, 2, rng, false);
  t.interior[0].z = -0.0;
  t.interior[0].weight = std::numeric_limits<double>::denorm_min();
  t.north[0].z = 1e300;
  t.source_points = ~std::uint64_t{0};
  for (const FormatVersion version : kVersions) {
    const auto back = decode(encode(t, version));
    ASSERT_TRUE(back.ok());
    EXPECT_TRUE(same_tile(t, *back));
    EXPECT_TRUE(std::signbit(back->interior[0].z));
  }
}

TEST(Codec, UsesSixteenBitIndicesUpTo65536VerticesAnd32BitBeyond) {
  std::mt19937_64 rng(13);
  // 255 × 255 cells = 256² = 65536 vertices: the largest 16-bit mesh.
  const TinTile small = make_grid_tile({12, 5, 5}, 255, 255, rng);
  ASSERT_EQ(small.vertex_count(), 65536u);
  const TinTile big = make_grid_tile({12, 5, 5}, 256, 255, rng);
  for (const FormatVersion version : kVersions) {
    const auto a = encode(small, version);
    EXPECT_EQ(a[6], 2);
    EXPECT_EQ(a.size(), 84 + 65536u * 32 + small.triangles.size() * 6);
    const auto small_back = decode(a);
    ASSERT_TRUE(small_back.ok()) << small_back.error().message;
    EXPECT_TRUE(same_tile(small, *small_back));
    const auto b = encode(big, version);
    EXPECT_EQ(b[6], 4);
    EXPECT_EQ(b.size(), 84 + big.vertex_count() * 32 + big.triangles.size() * 12);
    const auto back = decode(b);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_TRUE(same_tile(big, *back));
  }
}

TEST(Codec, Version1LayoutMatchesTheSpecification) {
  std::mt19937_64 rng(14);
  TinTile t = make_grid_tile({3, 5, 6}, 2, 3, rng, false);
  t.corner_nodata = {false, true, false, true};
  t.corners[1].z = t.corners[3].z = 0;
  const auto b = encode(t, FormatVersion::v1);
  EXPECT_EQ(std::memcmp(b.data(), "TINT", 4), 0);
  EXPECT_EQ(b[4], 1);
  EXPECT_EQ(b[5], 0);
  EXPECT_EQ(b[7], 0b1010);
  EXPECT_EQ(b[8], 3);
  EXPECT_EQ(b[12], 5);
  EXPECT_EQ(b[16], 6);
  EXPECT_EQ(b[20], 1);   // north count
  EXPECT_EQ(b[24], 2);   // east count
  EXPECT_EQ(b[28], 1);   // south
  EXPECT_EQ(b[32], 2);   // west
  EXPECT_EQ(b[36], 2);   // interior
  EXPECT_EQ(b[40], 12);  // triangles
  double first_x = 0;
  std::memcpy(&first_x, b.data() + 84, 8);  // little-endian host assumed by this check
  EXPECT_EQ(first_x, t.corners[0].x);
}

TEST(Codec, RejectsEveryTruncation) {
  std::mt19937_64 rng(15);
  const TinTile t = make_grid_tile({8, 100, 200}, 3, 2, rng);
  for (const FormatVersion version : kVersions) {
    const auto bytes = encode(t, version);
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      const auto r = decode(std::span(bytes.data(), n));
      ASSERT_FALSE(r.ok()) << "prefix of " << n << " bytes was accepted";
      EXPECT_EQ(r.error().code, ErrorCode::corrupt_data);
    }
    auto longer = bytes;
    longer.push_back(0);
    EXPECT_FALSE(decode(longer).ok());
  }
}

TEST(Codec, RejectsBadMagicAndVersion) {
  std::mt19937_64 rng(16);
  const auto bytes = encode(make_grid_tile({1, 1, 0}, 2, 2, rng));
  auto b = bytes;
  b[0] = 'X';
  auto r = decode(b);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("magic"), std::string::npos);
  for (const int unknown : {0, 3, 255}) {
    b = bytes;
    b[4] = static_cast<std::uint8_t>(unknown);
    r = decode(b);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code, ErrorCode::unsupported);
    EXPECT_NE(r.error().message.find("version " + std::to_string(unknown)), std::string::npos);
  }
}

TEST(Codec, RejectsAbsurdCountsWithoutAllocating) {
  std::mt19937_64 rng(17);
  const TinTile t = make_grid_tile({4, 1, 2}, 2, 2, rng);
  for (const FormatVersion version : kVersions) {
    const auto bytes = encode(t, version);
    for (std::size_t field = 20; field <= 40; field += 4) {
      for (std::uint32_t v : {0xFFFFFFFFu, 0x7FFFFFFFu, 0x10000000u, 65535u}) {
        auto b = bytes;
        put_u32(b, field, v);
        EXPECT_FALSE(decode(b).ok()) << "field " << field << " = " << v;
      }
    }
    // Counts whose sum overflows 32 bits.
    auto b = bytes;
    put_u32(b, 20, 0x80000000u);
    put_u32(b, 36, 0x80000000u);
    EXPECT_FALSE(decode(b).ok());
  }
}

TEST(Codec, Version1RejectsInvalidFields) {
  std::mt19937_64 rng(18);
  const TinTile t = make_grid_tile({4, 1, 2}, 2, 2, rng);
  const auto bytes = encode(t, FormatVersion::v1);
  auto expect_bad = [](std::vector<std::uint8_t> b, const char* what) {
    const auto r = decode(b);
    EXPECT_FALSE(r.ok()) << what;
  };
  auto b = bytes;
  b[6] = 4;  // 32-bit indices for a 9-vertex tile: not canonical
  expect_bad(b, "index width 4");
  b = bytes;
  b[6] = 3;
  expect_bad(b, "index width 3");
  b = bytes;
  b[7] = 0x10;
  expect_bad(b, "reserved nodata bits");
  b = bytes;
  put_u32(b, 8, 31);  // level 31
  expect_bad(b, "level 31");
  b = bytes;
  put_u32(b, 12, 16);  // x = 16 at level 4
  expect_bad(b, "column out of range");
  b = bytes;
  const double nan = std::nan("");
  // Vertex k is at 84 + 32·k, its z at +16 (docs/tile-format.md): vertex 5's z.
  std::memcpy(b.data() + 84 + std::ptrdiff_t{32} * 5 + 16, &nan, 8);
  expect_bad(b, "NaN height");
  b = bytes;
  b[b.size() - 2] = 9;  // last triangle's last index (16-bit) → 9 = vertex_count
  b[b.size() - 1] = 0;
  expect_bad(b, "index out of range");
}

// Random mutations of valid blobs must never crash; what decodes must re-encode to the same bytes
// (the format is canonical) and be checkable.
TEST(Codec, MiniFuzzRandomByteFlips) {
  std::mt19937_64 rng(19);
  std::vector<std::vector<std::uint8_t>> seeds;
  seeds.reserve(20);
  for (int i = 0; i < 20; ++i) seeds.push_back(encode(random_tile(rng, 5), kVersions[i % 2]));
  int accepted = 0;
  for (int i = 0; i < 30000; ++i) {
    auto b = seeds[rng() % seeds.size()];
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
      switch (rng() % 4) {
        case 0:
          b[rng() % b.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
          break;
        case 1:
          b[rng() % b.size()] = static_cast<std::uint8_t>(rng());
          break;
        case 2:
          b[rng() % 84] = static_cast<std::uint8_t>(rng());
          break;  // header
        case 3:
          b.resize(rng() % (b.size() + 1));
          if (b.empty()) b.push_back(0);
          break;
      }
    }
    const auto r = decode(b);
    if (r.ok()) {
      ++accepted;
      ASSERT_EQ(encode(*r, version_of(b)), b) << "iteration " << i;
      (void)check_structure(*r);
    } else {
      EXPECT_FALSE(r.error().message.empty());
    }
  }
  EXPECT_GT(accepted, 0);  // flips in heights and weights decode fine
}

TEST(Codec, MiniFuzzRandomGarbage) {
  std::mt19937_64 rng(20);
  for (int i = 0; i < 20000; ++i) {
    std::vector<std::uint8_t> b(rng() % 300);
    for (auto& c : b) c = static_cast<std::uint8_t>(rng());
    if (b.size() >= 6 && i % 2 == 0) {
      std::memcpy(b.data(), i % 4 == 0 ? "TINT\x01\x00" : "TINT\x02\x00", 6);
    }
    const auto r = decode(b);
    if (r.ok()) {
      EXPECT_EQ(encode(*r, version_of(b)), b);
    }
  }
}

TEST(Zlib, RoundTrips) {
  std::mt19937_64 rng(21);
  for (int i = 0; i < 50; ++i) {
    const auto raw = encode(random_tile(rng));
    const auto packed = compress(raw);
    EXPECT_EQ(packed[0] & 0x0F, 8);  // RFC 1950: CM = deflate
    const auto back = decompress(packed);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(*back, raw);
  }
  const auto empty = decompress(compress({}));
  ASSERT_TRUE(empty.ok());
  EXPECT_TRUE(empty->empty());
}

TEST(Zlib, StreamsAreInterchangeableWithZlib) {
  // Blobs are served as-is with `Content-Encoding: deflate` and stores written by earlier
  // versions hold zlib's own streams: zlib must inflate ours, and we must inflate zlib's.
  std::mt19937_64 rng(23);
  for (int i = 0; i < 20; ++i) {
    const auto raw = encode(random_tile(rng));
    const auto ours = compress(raw, 2);
    std::vector<std::uint8_t> back(raw.size() + 16);
    uLongf n = back.size();
    ASSERT_EQ(uncompress(back.data(), &n, ours.data(), ours.size()), Z_OK);
    back.resize(n);
    EXPECT_EQ(back, raw);
    std::vector<std::uint8_t> theirs(compressBound(raw.size()));
    uLongf m = theirs.size();
    ASSERT_EQ(compress2(theirs.data(), &m, raw.data(), raw.size(), 6), Z_OK);
    theirs.resize(m);
    const auto inflated = decompress(theirs);
    ASSERT_TRUE(inflated.ok()) << inflated.error().message;
    EXPECT_EQ(*inflated, raw);
  }
}

TEST(Zlib, LargeOutputAcrossManyChunks) {
  std::vector<std::uint8_t> raw(5'000'000);
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = static_cast<std::uint8_t>(i % 251);
  const auto back = decompress(compress(raw, 1));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, raw);
}

TEST(Zlib, RefusesToInflatePastTheLimit) {
  const std::vector<std::uint8_t> zeros(1'000'000, 0);
  const auto packed = compress(zeros, 9);
  EXPECT_LT(packed.size(), 2000u);
  const auto r = decompress(packed, 999'999);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("limit"), std::string::npos);
  const auto exact = decompress(packed, 1'000'000);
  ASSERT_TRUE(exact.ok());
  EXPECT_EQ(exact->size(), 1'000'000u);
}

TEST(Zlib, RejectsTruncatedGarbageAndTrailingBytes) {
  std::mt19937_64 rng(22);
  const auto packed = compress(encode(random_tile(rng)));
  for (std::size_t n = 0; n < packed.size(); ++n) {
    EXPECT_FALSE(decompress(std::span(packed.data(), n)).ok()) << n;
  }
  auto trailing = packed;
  trailing.push_back(0);
  EXPECT_FALSE(decompress(trailing).ok());
  std::vector<std::uint8_t> garbage(100);
  for (auto& c : garbage) c = static_cast<std::uint8_t>(rng());
  EXPECT_FALSE(decompress(garbage).ok());
  for (int i = 0; i < 3000; ++i) {
    auto b = packed;
    b[rng() % b.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
    const auto r = decompress(b, 1 << 20);  // adler32 catches what inflate does not
    if (r.ok()) {
      EXPECT_LE(r->size(), 1u << 20);
    }
  }
}

}  // namespace
}  // namespace tinstream::tile

namespace tinstream::tile {
namespace {

// The fuzzer's seed corpus was written by an independent Python encoder following
// docs/tile-format.md, so this also checks the specification against the implementation.
TEST(Codec, SeedCorpusFromTheSpecificationDecodes) {
  const std::filesystem::path dir =
      std::filesystem::path(TINSTREAM_SOURCE_DIR) / "core/tile/fuzz/corpus";
  int tiles = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    std::ifstream in(entry.path(), std::ios::binary);
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    auto raw = bytes;
    if (entry.path().extension() == ".zlib") {
      auto inflated = decompress(bytes);
      ASSERT_TRUE(inflated.ok()) << entry.path();
      raw = *inflated;
    }
    const auto t = decode(raw);
    ASSERT_TRUE(t.ok()) << entry.path() << ": " << t.error().message;
    const Status s = check_structure(*t);
    EXPECT_TRUE(s.ok()) << entry.path() << ": " << (s.ok() ? "" : s.error().message);
    EXPECT_EQ(encode(*t, version_of(raw)), raw);
    ++tiles;
  }
  EXPECT_GE(tiles, 3);
}

}  // namespace
}  // namespace tinstream::tile
