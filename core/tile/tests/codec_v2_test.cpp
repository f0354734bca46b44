// Format version 2 (docs/tile-format.md §4): lossless on adversarial doubles and index patterns,
// the layout of the specification, clear errors on damaged blobs, and agreement with the seeds an
// independent Python encoder (core/tile/fuzz/make_v2_seeds.py) wrote from the specification.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>

#include "test_tiles.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::tile {
namespace {

using testing::make_grid_tile;
using testing::same_tile;

std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

// A random tile of 1 … max_cells × 1 … max_cells grid cells.
TinTile random_grid_tile(std::mt19937_64& rng, std::uint32_t max_cells) {
  const auto id = testing::random_tile_id(rng);
  const auto nx = 1 + static_cast<std::uint32_t>(rng() % max_cells);
  const auto ny = 1 + static_cast<std::uint32_t>(rng() % max_cells);
  return make_grid_tile(id, nx, ny, rng);
}

// §4 zigzag of a difference taken modulo 2^64, written from the specification's signed form.
std::uint64_t zigzag64(std::uint64_t d) {
  const auto s = static_cast<std::int64_t>(d);
  return s >= 0 ? 2 * static_cast<std::uint64_t>(s) : 2 * (~static_cast<std::uint64_t>(s)) + 1;
}

std::vector<std::uint8_t> read_seed(const std::string& name) {
  const auto path = std::filesystem::path(TINSTREAM_SOURCE_DIR) / "core/tile/fuzz/corpus" / name;
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TinTile decode_or_fail(std::span<const std::uint8_t> b) {
  auto t = decode(b);
  EXPECT_TRUE(t.ok()) << t.error().message;
  return t.ok() ? *t : TinTile{};
}

// A finite double from random bits, with the hard cases mixed in.
double adversarial_double(std::mt19937_64& rng) {
  static constexpr std::array<double, 12> kSpecial{
      0.0, -0.0, std::numeric_limits<double>::denorm_min(),
      -std::numeric_limits<double>::denorm_min(), std::numeric_limits<double>::min(),
      std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(), 1e-310, -1e300,
      1.0,
      // nextafter(1.0, 2.0); std::nextafter is not
      // constexpr before C++23
      1.0 + std::numeric_limits<double>::epsilon(), -8848.86};
  if (rng() % 3 == 0) return kSpecial[rng() % kSpecial.size()];
  for (;;) {
    const double d = std::bit_cast<double>(rng());
    if (std::isfinite(d)) return d;
  }
}

// The tile with every vertex value replaced by an adversarial double and triangles with random
// indices, including 0 and V−1 next to each other (the largest index differences, both signs).
TinTile scramble(TinTile t, std::mt19937_64& rng) {
  const auto scramble_vertex = [&](Vertex& v) {
    v.x = adversarial_double(rng);
    v.y = adversarial_double(rng);
    v.z = adversarial_double(rng);
    v.weight = adversarial_double(rng);
  };
  for (auto& v : t.corners) scramble_vertex(v);
  for (auto* list : {&t.north, &t.east, &t.south, &t.west, &t.interior}) {
    for (auto& v : *list) scramble_vertex(v);
  }
  const auto last = static_cast<std::uint32_t>(t.vertex_count() - 1);
  for (std::size_t i = 0; i < t.triangles.size(); ++i) {
    auto& tri = t.triangles[i];
    if (i % 5 == 0) {
      tri = {0, last, 0};
    } else if (i % 5 == 1) {
      tri = {last, 0, last};
    } else {
      for (auto& index : tri) index = static_cast<std::uint32_t>(rng() % (last + 1));
    }
  }
  return t;
}

TEST(CodecV2, IsTheDefaultAndKeepsTheVersion1HeaderAndSize) {
  std::mt19937_64 rng(31);
  const TinTile t = make_grid_tile({3, 5, 6}, 2, 3, rng);
  const auto v2 = encode(t);
  const auto v1 = encode(t, FormatVersion::v1);
  EXPECT_EQ(v2[4], 2);
  EXPECT_EQ(v2[5], 0);
  ASSERT_EQ(v2.size(), v1.size());
  // Header identical apart from the version.
  EXPECT_TRUE(std::equal(v1.begin() + 6, v1.begin() + 84, v2.begin() + 6));
}

TEST(CodecV2, VertexAndIndexPlanesAreWhereTheSpecificationPutsThem) {
  std::mt19937_64 rng(32);
  const TinTile t = make_grid_tile({10, 3, 1000}, 3, 2, rng);
  const auto b = encode(t);
  const std::vector<Vertex> vs = t.vertices();
  const std::size_t v = vs.size(), words = 4 * v;
  std::size_t j = 0;
  for (double Vertex::*column : {&Vertex::x, &Vertex::y, &Vertex::z, &Vertex::weight}) {
    std::uint64_t previous = 0;
    for (const Vertex& vertex : vs) {
      const std::uint64_t word = zigzag64(bits(vertex.*column) - previous);
      previous = bits(vertex.*column);
      for (std::size_t p = 0; p < 8; ++p) {
        ASSERT_EQ(b[84 + p * words + j], static_cast<std::uint8_t>(word >> (8 * p)))
            << "word " << j << " byte " << p;
      }
      ++j;
    }
  }
  const std::size_t n = 3 * t.triangles.size();
  std::int64_t previous = 0;
  std::size_t i = 0;
  for (const Triangle& tri : t.triangles) {
    for (const std::uint32_t index : tri) {
      const std::int64_t d = std::int64_t{index} - previous;  // |d| < 2^15 for this small tile
      previous = index;
      const auto word = static_cast<std::uint16_t>(d >= 0 ? 2 * d : -2 * d - 1);
      EXPECT_EQ(b[84 + 32 * v + i], word & 0xFF) << "index " << i;
      EXPECT_EQ(b[84 + 32 * v + n + i], word >> 8) << "index " << i;
      ++i;
    }
  }
}

TEST(CodecV2, RoundTripsAdversarialValuesBitExactly) {
  std::mt19937_64 rng(33);
  for (int i = 0; i < 200; ++i) {
    const TinTile t = scramble(random_grid_tile(rng, 9), rng);
    const auto b = encode(t);
    const auto back = decode(b);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_TRUE(same_tile(t, *back)) << "tile " << i;
    EXPECT_EQ(encode(*back), b);
    // The same values through version 1 give the same tile.
    const auto via_v1 = decode(encode(t, FormatVersion::v1));
    ASSERT_TRUE(via_v1.ok());
    EXPECT_TRUE(same_tile(*via_v1, *back));
  }
}

TEST(CodecV2, RoundTripsAtThe16And32BitIndexBoundary) {
  std::mt19937_64 rng(34);
  // 65536 vertices: the largest 16-bit tile; 65537 (one more interior point): 32-bit.
  const TinTile small = scramble(make_grid_tile({12, 5, 5}, 255, 255, rng), rng);
  ASSERT_EQ(small.vertex_count(), 65536u);
  TinTile big = small;
  big.interior.push_back({0.5, 0.5, -0.0, 1.0});
  big.triangles.push_back({65536, 0, 65535});
  for (const TinTile* t : std::array<const TinTile*, 2>{&small, &big}) {
    const auto b = encode(*t);
    EXPECT_EQ(b[6], t == &small ? 2 : 4);
    const auto back = decode(b);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_TRUE(same_tile(*t, *back));
    EXPECT_EQ(encode(*back), b);
  }
}

TEST(CodecV2, RoundTripsTilesWithoutInteriorOrTriangles) {
  std::mt19937_64 rng(35);
  TinTile corners_only = make_grid_tile({7, 100, 20}, 1, 1, rng);
  ASSERT_TRUE(corners_only.interior.empty());
  ASSERT_EQ(corners_only.vertex_count(), 4u);
  TinTile no_triangles = corners_only;
  no_triangles.triangles.clear();
  for (const TinTile* t : std::array<const TinTile*, 2>{&corners_only, &no_triangles}) {
    const auto b = encode(*t);
    EXPECT_EQ(b.size(), 84 + 4 * 32 + t->triangles.size() * 6);
    const auto back = decode(b);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_TRUE(same_tile(*t, *back));
  }
}

TEST(CodecV2, DamagedBlobsGiveErrorsThatNameTheProblem) {
  std::mt19937_64 rng(36);
  const TinTile t = make_grid_tile({4, 1, 2}, 2, 2, rng);  // 9 vertices, 8 triangles
  const auto bytes = encode(t);
  const std::size_t v = t.vertex_count(), words = 4 * v, n = 3 * t.triangles.size();
  const auto message = [](const std::vector<std::uint8_t>& b) {
    const auto r = decode(b);
    EXPECT_FALSE(r.ok());
    return r.ok() ? std::string() : r.error().message;
  };

  // Truncated (every prefix) and extended.
  for (std::size_t size = 84; size < bytes.size(); ++size) {
    const auto m = message({bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(size)});
    EXPECT_NE(m.find("need " + std::to_string(bytes.size()) + " bytes, the blob has " +
                     std::to_string(size)),
              std::string::npos)
        << m;
  }
  auto b = bytes;
  b.push_back(0);
  EXPECT_NE(message(b).find("the blob has " + std::to_string(bytes.size() + 1)), std::string::npos);

  // Vertex 5's z decodes to +infinity: its word is the zigzag of inf − z[4].
  b = bytes;
  const std::uint64_t word =
      zigzag64(bits(std::numeric_limits<double>::infinity()) - bits(t.vertex(4).z));
  for (std::size_t p = 0; p < 8; ++p) {
    b[84 + p * words + 2 * v + 5] = static_cast<std::uint8_t>(word >> (8 * p));
  }
  EXPECT_NE(message(b).find("vertex 5 has a non-finite z"), std::string::npos) << message(b);
  EXPECT_NE(message(b).find("version 2"), std::string::npos);

  // The last index decodes to 9 (= V): its word is the zigzag of 9 − the index before it.
  b = bytes;
  const auto before = static_cast<std::int64_t>(t.triangles.back()[1]);
  const std::int64_t d = 9 - before;
  const auto code = static_cast<std::uint16_t>(d >= 0 ? 2 * d : -2 * d - 1);
  b[84 + 32 * v + n - 1] = static_cast<std::uint8_t>(code & 0xFF);
  b[84 + 32 * v + 2 * n - 1] = static_cast<std::uint8_t>(code >> 8);
  EXPECT_NE(message(b).find("triangle 7 refers to vertex 9 of 9"), std::string::npos) << message(b);

  // A large difference early in the index planes wraps around: out of range, not a crash.
  b = bytes;
  b[84 + 32 * v + n] = 0x7F;  // byte 1 of the first index word
  EXPECT_NE(message(b).find("refers to vertex"), std::string::npos);
}

// Random damage to version-2 blobs never crashes, and what decodes re-encodes to the same bytes.
TEST(CodecV2, MiniFuzzRandomDamage) {
  std::mt19937_64 rng(37);
  std::vector<std::vector<std::uint8_t>> seeds;
  seeds.reserve(10);
  for (int i = 0; i < 10; ++i) {
    seeds.push_back(encode(random_grid_tile(rng, 6)));
  }
  int accepted = 0;
  for (int i = 0; i < 20000; ++i) {
    auto b = seeds[rng() % seeds.size()];
    for (int f = 1 + static_cast<int>(rng() % 3); f > 0; --f) {
      if (rng() % 8 == 0) {
        b.resize(rng() % (b.size() + 1));
      } else if (!b.empty()) {
        b[rng() % b.size()] = static_cast<std::uint8_t>(rng());
      }
    }
    const auto r = decode(b);
    if (r.ok()) {
      ++accepted;
      ASSERT_EQ(encode(*r), b) << "iteration " << i;
    } else {
      EXPECT_FALSE(r.error().message.empty());
    }
  }
  EXPECT_GT(accepted, 0);
}

// --- Seeds written by the independent Python encoder -------------------------------------------

TEST(CodecV2, PythonSeedsReencodedFromVersion1DecodeToTheSameTiles) {
  for (const char* name : {"world_two_triangles", "level3_fan", "level3_north_edge"}) {
    const auto v1 = read_seed(std::string(name) + ".tint");
    const auto v2 = read_seed(std::string("v2_from_v1_") + name + ".tint");
    ASSERT_EQ(v2[4], 2) << name;
    const TinTile a = decode_or_fail(v1), b = decode_or_fail(v2);
    EXPECT_TRUE(same_tile(a, b)) << name;
    EXPECT_EQ(encode(a), v2) << name;  // and our encoder writes the same bytes
    EXPECT_EQ(encode(b, FormatVersion::v1), v1) << name;
  }
}

TEST(CodecV2, PythonWorkedExampleOfTheSpecification) {
  const auto b = read_seed("v2_world_two_triangles.tint");
  ASSERT_EQ(b.size(), 224u);
  const TinTile t = decode_or_fail(b);
  EXPECT_EQ(t.id, (geo::TileId{0, 0, 0}));
  const std::array<std::array<double, 2>, 4> xy{{{-1, 1}, {1, 1}, {-1, -1}, {1, -1}}};
  for (std::size_t c = 0; c < 4; ++c) {
    EXPECT_EQ(t.corners[c].x, xy[c][0]);
    EXPECT_EQ(t.corners[c].y, xy[c][1]);
    EXPECT_EQ(t.corners[c].z, 100.0);
    EXPECT_EQ(t.corners[c].weight, 1.0);
  }
  ASSERT_EQ(t.triangles.size(), 2u);
  EXPECT_EQ(t.triangles[0], (Triangle{2, 3, 1}));
  EXPECT_EQ(t.triangles[1], (Triangle{2, 1, 0}));
  EXPECT_TRUE(check_structure(t).ok());
}

TEST(CodecV2, PythonAdversarialSeedDecodesToTheValuesThePythonScriptWrote) {
  const auto raw = read_seed("v2_adversarial.tint");
  const auto inflated = decompress(read_seed("v2_adversarial.tint.zlib"));
  ASSERT_TRUE(inflated.ok()) << inflated.error().message;
  EXPECT_EQ(*inflated, raw);
  const TinTile t = decode_or_fail(raw);
  // Bit patterns printed by make_v2_seeds.py (x, y, z, weight of vertices 0 … 5).
  const std::array<std::array<std::uint64_t, 4>, 6> expected{{
      {0xbff0000000000000, 0x3ff0000000000000, 0x8000000000000000, 0x0000000000000000},
      {0x3ff0000000000000, 0x3ff0000000000000, 0x0000000000000000, 0x0000000000000000},
      {0xbff0000000000000, 0xbff0000000000000, 0x7e37e43c8800759c, 0x4004000000000000},
      {0x3ff0000000000000, 0xbff0000000000000, 0x800012688b70e62b, 0x0000000000000001},
      {0x3fd0000000000000, 0x3ff0000000000000, 0xc0c1486e147ae148, 0x01a56e1fc2f8f359},
      {0x0000000000000001, 0x8000000000000000, 0x0010000000000000, 0x7fefffffffffffff},
  }};
  ASSERT_EQ(t.vertex_count(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k) {
    const Vertex& v = t.vertex(k);
    EXPECT_EQ(bits(v.x), expected[k][0]) << "vertex " << k;
    EXPECT_EQ(bits(v.y), expected[k][1]) << "vertex " << k;
    EXPECT_EQ(bits(v.z), expected[k][2]) << "vertex " << k;
    EXPECT_EQ(bits(v.weight), expected[k][3]) << "vertex " << k;
  }
  EXPECT_EQ(t.corner_nodata, (std::array<bool, 4>{false, true, false, false}));
  EXPECT_EQ(t.north.size(), 1u);
  EXPECT_EQ(t.interior.size(), 1u);
  EXPECT_EQ(t.min_z, -8848.86);
  EXPECT_EQ(t.max_z, 1e300);
  EXPECT_EQ(t.geometric_error, 1e-310);
  EXPECT_EQ(t.source_points, ~std::uint64_t{0});
  const std::vector<Triangle> triangles{{2, 3, 5}, {3, 1, 5}, {1, 4, 5}, {4, 0, 5}, {0, 2, 5}};
  EXPECT_EQ(t.triangles, triangles);
  const Status s = check_structure(t);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  EXPECT_EQ(encode(t), raw);
}

// A data-edge tile written by make_v2_seeds.py from docs/tile-format.md §2.1 and §4: NW is a
// NODATA corner with a continued height; the footprint printed by the script.
TEST(CodecV2, PythonDataEdgeSeedHasTheSpecifiedFootprint) {
  const TinTile t = decode_or_fail(read_seed("v2_nodata_footprint.tint"));
  EXPECT_EQ(t.id, (geo::TileId{12, 100, 200}));
  EXPECT_EQ(t.corner_nodata, (std::array<bool, 4>{true, false, false, false}));
  EXPECT_EQ(t.corners[0].z, 3105.25);
  EXPECT_EQ(t.min_z, 3120.0);  // the data vertices' range: the NODATA corner is left out
  EXPECT_EQ(t.max_z, 3150.0);
  EXPECT_EQ(t.footprint_mask(), (std::vector<std::uint8_t>{0, 0, 1, 1, 1, 1}));
  const Status s = check_structure(t);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
}

}  // namespace
}  // namespace tinstream::tile

// --- compress_runs: a deflate encoder of our own, so every inflater must read what it writes ---

namespace tinstream::tile {
namespace {

std::vector<std::uint8_t> zlib_inflate(const std::vector<std::uint8_t>& packed, std::size_t size) {
  std::vector<std::uint8_t> out(size + 1);
  uLongf n = out.size();
  const int rc = uncompress(out.data(), &n, packed.data(), packed.size());
  EXPECT_EQ(rc, Z_OK);
  out.resize(rc == Z_OK ? n : 0);
  return out;
}

void expect_round_trip(const std::vector<std::uint8_t>& raw, const std::string& what) {
  const auto packed = compress_runs(raw);
  const auto back = decompress(packed);  // libdeflate
  ASSERT_TRUE(back.ok()) << what << ": " << back.error().message;
  EXPECT_EQ(*back, raw) << what;
  EXPECT_EQ(zlib_inflate(packed, raw.size()), raw) << what;  // zlib, as HTTP clients use
  // Never more than stored blocks cost: 6 bytes per 16 KiB block and the zlib frame.
  EXPECT_LE(packed.size(), raw.size() + 6 * (raw.size() / 16384 + 1) + 7) << what;
}

TEST(CompressRuns, RoundTripsEdgeSizesAndContents) {
  std::mt19937_64 rng(41);
  for (const std::size_t size :
       {0, 1, 2, 3, 4, 5, 257, 258, 259, 16383, 16384, 16385, 32768, 100000}) {
    std::vector<std::uint8_t> zeros(size, 0), noise(size), few(size), runs(size);
    for (auto& c : noise) c = static_cast<std::uint8_t>(rng());
    for (auto& c : few) c = static_cast<std::uint8_t>(rng() % 3);
    std::uint8_t value = 7;
    for (std::size_t i = 0; i < size; ++i) {
      if (rng() % 300 == 0) value = static_cast<std::uint8_t>(rng());
      runs[i] = value;
    }
    for (const auto* data : {&zeros, &noise, &few, &runs}) {
      expect_round_trip(*data, "size " + std::to_string(size));
    }
  }
}

TEST(CompressRuns, RoundTripsRunsStartingAtEveryOffsetOfAWord) {
  // The literal counter skips eight bytes at a time where none repeats the byte before it: runs
  // of 2 to 10 bytes placed at every offset after stretches of distinct neighbours, and at the
  // end of a block, must still come out as the same bytes.
  std::mt19937_64 rng(45);
  std::vector<std::uint8_t> raw;
  auto distinct = [&](std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      std::uint8_t c;
      do {
        c = static_cast<std::uint8_t>(rng());
      } while (!raw.empty() && c == raw.back());
      raw.push_back(c);
    }
  };
  for (std::size_t offset = 0; offset < 17; ++offset) {
    for (std::size_t run = 2; run <= 10; ++run) {
      distinct(offset);
      raw.insert(raw.end(), run, raw.empty() ? 0 : raw.back());
    }
  }
  expect_round_trip(raw, "runs after distinct bytes");
  raw.resize(16384 - 5);
  raw.insert(raw.end(), 9, 0xAB);  // a run across the block boundary
  distinct(30);
  expect_round_trip(raw, "run across a block boundary");
}

TEST(CompressRuns, LimitsCodeLengthsOnSkewedCounts) {
  // Fibonacci counts over 19 byte values (10945 bytes, one block) would give a Huffman tree 18
  // deep; deflate allows 15.
  std::vector<std::uint8_t> raw;
  std::uint64_t a = 1, b = 1;
  for (std::uint8_t symbol = 0; symbol < 19; ++symbol) {
    for (std::uint64_t i = 0; i < a; ++i) raw.push_back(symbol);
    const std::uint64_t c = a + b;
    a = b;
    b = c;
  }
  ASSERT_LT(raw.size(), 16384u);
  // Shuffled so that the counts are literals, not runs.
  std::mt19937_64 rng(42);
  std::shuffle(raw.begin(), raw.end(), rng);
  expect_round_trip(raw, "fibonacci");
}

TEST(CompressRuns, RoundTripsTileBlobsAndIsSmallerThanStoredOnThem) {
  std::mt19937_64 rng(43);
  for (int i = 0; i < 20; ++i) {
    const TinTile t = random_grid_tile(rng, 60);
    for (const FormatVersion version : {FormatVersion::v1, FormatVersion::v2}) {
      const auto raw = encode(t, version);
      expect_round_trip(raw, "tile " + std::to_string(i));
      const auto back = decode(*decompress(compress_runs(raw)));
      ASSERT_TRUE(back.ok());
      EXPECT_TRUE(same_tile(t, *back));
    }
    const auto v2 = encode(t);
    EXPECT_LT(compress_runs(v2).size(), v2.size()) << "tile " << i;
  }
}

TEST(CompressRuns, RandomInputsRoundTrip) {
  std::mt19937_64 rng(44);
  for (int i = 0; i < 300; ++i) {
    std::vector<std::uint8_t> raw(rng() % 40000);
    const unsigned alphabet = 1 + static_cast<unsigned>(rng() % 256);
    const unsigned run_odds = 1 + static_cast<unsigned>(rng() % 50);
    for (std::size_t k = 0; k < raw.size(); ++k) {
      raw[k] = (k > 0 && rng() % run_odds != 0) ? raw[k - 1]
                                                : static_cast<std::uint8_t>(rng() % alphabet);
    }
    expect_round_trip(raw, "input " + std::to_string(i));
  }
}

}  // namespace
}  // namespace tinstream::tile
