// Decodes the LAZ files of ../shared/data (SOURCES.md sections A and D) and compares the
// records with references made by others: the sha256 of laz-perf 0.0.7's decode listed in
// SOURCES.md, or the records of the uncompressed twin the file was made from.
#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/sources/las_records.hpp"

namespace tinstream::sources {
namespace {

const std::filesystem::path kData = TINSTREAM_SHARED_DATA;

#define SKIP_WITHOUT_DATA(name)                                          \
  if (!std::filesystem::exists(kData / (name))) {                        \
    GTEST_SKIP() << "shared data absent: " << (kData / (name)).string(); \
  }

std::string hex(const unsigned char* p, unsigned n) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (unsigned i = 0; i < n; ++i) {
    s += d[p[i] >> 4];
    s += d[p[i] & 15];
  }
  return s;
}

struct Decoded {
  std::string sha256;
  std::uint64_t records = 0;
  std::vector<std::uint8_t> bytes;  // kept when asked
};

// Reads every record in batches of `batch` and hashes them in order.
Decoded decode_all(const std::filesystem::path& path, RecordOptions options, std::size_t batch,
                   bool keep = false) {
  Decoded out;
  auto reader = LasRecordReader::open(path, options);
  EXPECT_TRUE(reader.ok()) << (reader.ok() ? "" : reader.error().message);
  if (!reader.ok()) return out;
  const std::size_t rl = (*reader)->summary().record_length;
  std::vector<std::uint8_t> buf(batch * rl);
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
  for (;;) {
    auto n = (*reader)->read(buf.data(), batch);
    EXPECT_TRUE(n.ok()) << (n.ok() ? "" : n.error().message);
    if (!n.ok() || *n == 0) break;
    EVP_DigestUpdate(ctx, buf.data(), *n * rl);
    if (keep) {
      out.bytes.insert(out.bytes.end(), buf.begin(),
                       buf.begin() + static_cast<std::ptrdiff_t>(*n * rl));
    }
    out.records += *n;
  }
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned len = 0;
  EVP_DigestFinal_ex(ctx, md, &len);
  EVP_MD_CTX_free(ctx);
  out.sha256 = hex(md, len);
  return out;
}

struct Reference {
  const char* file;
  std::uint64_t points;
  const char* sha256;  // laz-perf 0.0.7's decode (SOURCES.md)
};

const Reference kReferences[] = {
    {"autzen_trim.laz", 110000, "f4eb6d80bf1fa507ffdcdaa73606d09041982659a50ee3895957e0b2b347f54b"},
    {"lone_star_tls.laz", 518862,
     "29178e5d5621e60aa11b25c399e17d27e4163cb95bda4eedef8633a5cbb0d02f"},
    {"laz_point10.laz", 1065, "d2033d0504e6b849a1301368703f90c77eda09c93e5d623e89cab06cb98ad63f"},
    {"laz_1_4_w_evlr.laz", 1000,
     "923571fd0bdbfdc886522adcb5fccaa6462642142937b1a3c490519155d447ba"},
    {"laz_simple.copc.laz", 1065,
     "361eda6829430490b1bba3a2665408642d16211f6c349b2f11edf451c8164422"},
    {"laz_append-bug.laz", 37805,
     "da661009d733479c3c414a9f9584df5f4066260ae9b091e9e16b542ba7fab34c"},
    {"laz_las_with_several_extra_byte_bloc.laz", 697721,
     "c19b99bc99062598ede4bed3bc6648832211f51b80ac22c8095cb547d8836406"},
};

class LazReference : public ::testing::TestWithParam<Reference> {};

TEST_P(LazReference, RecordsMatchLazPerfOnOneAndTwoThreads) {
  const Reference& ref = GetParam();
  SKIP_WITHOUT_DATA(ref.file);
  for (unsigned threads : {1u, 2u}) {
    for (std::size_t batch : {std::size_t{1000}, std::size_t{77777}}) {
      RecordOptions o;
      o.threads = threads;
      const Decoded d = decode_all(kData / ref.file, o, batch);
      EXPECT_EQ(d.records, ref.points) << ref.file << " threads " << threads;
      EXPECT_EQ(d.sha256, ref.sha256) << ref.file << " threads " << threads << " batch " << batch;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(SharedData, LazReference, ::testing::ValuesIn(kReferences),
                         [](const auto& test) {
                           std::string n = test.param.file;
                           for (char& c : n) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return n;
                         });

// A rewind while the reader hands out the second chunk of a lock-step pair (lone_star on one
// thread: records 50001-100000 come from that buffer) starts again from the first record.
TEST(LazDecode, RewindInsideAPairedChunkStartsAgain) {
  SKIP_WITHOUT_DATA("lone_star_tls.laz");
  RecordOptions o;
  o.threads = 1;
  auto reader = LasRecordReader::open(kData / "lone_star_tls.laz", o);
  ASSERT_TRUE(reader.ok());
  const std::size_t rl = (*reader)->summary().record_length;
  std::vector<std::uint8_t> first(rl), again(rl), buf(75000 * rl);
  ASSERT_EQ((*reader)->read(first.data(), 1).value(), 1u);
  ASSERT_EQ((*reader)->read(buf.data(), 75000).value(), 75000u);
  ASSERT_TRUE((*reader)->rewind().ok());
  ASSERT_EQ((*reader)->read(again.data(), 1).value(), 1u);
  EXPECT_TRUE(first == again);
  std::uint64_t records = 1;
  for (;;) {
    auto n = (*reader)->read(buf.data(), 75000);
    ASSERT_TRUE(n.ok()) << n.error().message;
    if (*n == 0) break;
    records += *n;
  }
  EXPECT_EQ(records, 518862u);
}

// Layered files read with only the layers a terrain needs give the same coordinates, returns,
// flags and classes as a full decode (what the ingest reads; the skipped fields may differ).
TEST(LazDecode, GeometryAndClassLayersMatchAFullDecode) {
  for (const char* name : {"laz_las_with_several_extra_byte_bloc.laz", "laz_simple.copc.laz",
                           "laz_1_4_w_evlr.laz", "laz_append-bug.laz"}) {
    SKIP_WITHOUT_DATA(name);
    RecordOptions partial;
    partial.geometry_and_class_only = true;
    const Decoded all = decode_all(kData / name, {}, 5000, true);
    const Decoded part = decode_all(kData / name, partial, 5000, true);
    ASSERT_EQ(all.bytes.size(), part.bytes.size()) << name;
    ASSERT_GT(all.records, 0u);
    const std::size_t rl = all.bytes.size() / all.records;
    std::size_t differing_other_fields = 0;
    for (std::size_t i = 0; i < all.records; ++i) {
      const std::uint8_t* a = all.bytes.data() + i * rl;
      const std::uint8_t* b = part.bytes.data() + i * rl;
      // x, y, z (0-11); returns (14); flags + channel (15); classification (16).
      ASSERT_EQ(std::memcmp(a, b, 12), 0) << name << " record " << i;
      ASSERT_EQ(std::memcmp(a + 14, b + 14, 3), 0) << name << " record " << i;
      if (std::memcmp(a, b, rl) != 0) ++differing_other_fields;
    }
    // The skipped layers really were skipped (they vary in these files).
    EXPECT_GT(differing_other_fields, 0u) << name;
  }
}

// Files whose reference is their uncompressed twin.
TEST(LazDecode, PointwiseVersion1MatchesItsLasTwin) {
  SKIP_WITHOUT_DATA("laz_point-version-1-point-wise.laz");
  const Decoded laz = decode_all(kData / "laz_point-version-1-point-wise.laz", {}, 4096);
  const Decoded las = decode_all(kData / "laz_point-version-1-point-wise.las", {}, 4096);
  EXPECT_EQ(laz.records, 11781u);
  EXPECT_EQ(laz.sha256, las.sha256);
}

TEST(LazDecode, AutzenMatchesItsLasTwin) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  const Decoded laz = decode_all(kData / "autzen_trim.laz", {}, 4096);
  const Decoded las = decode_all(kData / "autzen_trim.las", {}, 4096);
  EXPECT_EQ(laz.sha256, las.sha256);
}

// Files LASzip wrote beside their uncompressed twins (tests/data/README.md): every point format
// but 3 (autzen is one), the layered ones with four scanner channels switching mid-chunk and at
// chunk starts and up to 15 returns, 0, 1, 2, 3 and 7 extra bytes, RGB, NIR, both waveform
// items; three layered files again with LASzip's item version 4 (same points, so the v3 file's
// twin); two pointwise files with item version 1, one of them not chunked (compressor 1).
// Always present (in the repository).
const std::filesystem::path kGenerated = TINSTREAM_LAZ_TEST_DATA;

struct GeneratedFile {
  const char* laz;
  const char* twin;  // the .las holding the same records
  int format;        // point data format
  std::uint64_t points;
};

// The first record where two decodes differ, and its first differing byte ("" when equal).
std::string first_difference(const Decoded& a, const Decoded& b, std::size_t rl) {
  const std::size_t n = std::min(a.bytes.size(), b.bytes.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (a.bytes[i] != b.bytes[i]) {
      return "record " + std::to_string(i / rl) + " byte " + std::to_string(i % rl);
    }
  }
  return a.bytes.size() == b.bytes.size() ? "" : "lengths differ";
}

class GeneratedLaz : public ::testing::TestWithParam<GeneratedFile> {};

TEST_P(GeneratedLaz, RecordsMatchTheLasTwinLaszipWrote) {
  const std::string name = GetParam().laz;
  const Decoded las =
      decode_all(kGenerated / (std::string(GetParam().twin) + ".las"), {}, 4096, true);
  ASSERT_EQ(las.records, GetParam().points) << name;
  const std::size_t rl = las.bytes.size() / las.records;
  for (unsigned threads : {1u, 2u}) {
    for (std::size_t batch : {std::size_t{1}, std::size_t{333}, std::size_t{4096}}) {
      RecordOptions o;
      o.threads = threads;
      const Decoded laz = decode_all(kGenerated / (name + ".laz"), o, batch, true);
      EXPECT_EQ(laz.records, las.records) << name;
      EXPECT_EQ(first_difference(laz, las, rl), "")
          << name << " threads " << threads << " batch " << batch;
    }
  }
}

// Reading only what a terrain needs (x, y, z, returns, flags and channel, class) across channel
// switches: those bytes as in the twin.
TEST_P(GeneratedLaz, GeometryAndClassLayersMatchTheTwinAcrossChannelSwitches) {
  const std::string name = GetParam().laz;
  const Decoded las =
      decode_all(kGenerated / (std::string(GetParam().twin) + ".las"), {}, 4096, true);
  ASSERT_GT(las.records, 0u);
  const std::size_t rl = las.bytes.size() / las.records;
  RecordOptions partial;
  partial.geometry_and_class_only = true;
  const Decoded part = decode_all(kGenerated / (name + ".laz"), partial, 500, true);
  ASSERT_EQ(part.bytes.size(), las.bytes.size()) << name;
  // Formats 0-5 keep returns, flags and class in bytes 14-15; formats 6-10 in 14-16.
  const std::size_t returns_to_class = GetParam().format <= 5 ? 2 : 3;
  for (std::size_t i = 0; i < las.records; ++i) {
    const std::uint8_t* a = las.bytes.data() + i * rl;
    const std::uint8_t* b = part.bytes.data() + i * rl;
    ASSERT_EQ(std::memcmp(a, b, 12), 0) << name << " record " << i;
    ASSERT_EQ(std::memcmp(a + 14, b + 14, returns_to_class), 0) << name << " record " << i;
  }
}

const GeneratedFile kGeneratedFiles[] = {
    {"laz_gen_f0_eb1", "laz_gen_f0_eb1", 0, 1500},
    {"laz_gen_f1_eb7", "laz_gen_f1_eb7", 1, 2500},
    {"laz_gen_f2_eb0", "laz_gen_f2_eb0", 2, 1500},
    {"laz_gen_f4_eb3", "laz_gen_f4_eb3", 4, 1500},
    {"laz_gen_f5_eb0", "laz_gen_f5_eb0", 5, 1500},
    {"laz_gen_f6_eb7_4ch", "laz_gen_f6_eb7_4ch", 6, 2500},
    {"laz_gen_f7_eb1_4ch", "laz_gen_f7_eb1_4ch", 7, 2500},
    {"laz_gen_f8_eb7_4ch", "laz_gen_f8_eb7_4ch", 8, 1500},
    {"laz_gen_f9_eb0_4ch", "laz_gen_f9_eb0_4ch", 9, 1500},
    {"laz_gen_f10_eb2_4ch", "laz_gen_f10_eb2_4ch", 10, 2500},
    {"laz_gen_f3_eb2_v1_nochunks", "laz_gen_f3_eb2_v1_nochunks", 3, 1500},
    {"laz_gen_f5_eb1_v1", "laz_gen_f5_eb1_v1", 5, 1500},
    {"laz_gen_f7_eb1_4ch_v4", "laz_gen_f7_eb1_4ch", 7, 2500},
    {"laz_gen_f9_eb0_4ch_v4", "laz_gen_f9_eb0_4ch", 9, 1500},
    {"laz_gen_f10_eb2_4ch_v4", "laz_gen_f10_eb2_4ch", 10, 2500},
};

INSTANTIATE_TEST_SUITE_P(Generated, GeneratedLaz, ::testing::ValuesIn(kGeneratedFiles),
                         [](const auto& test) { return std::string(test.param.laz); });

}  // namespace
}  // namespace tinstream::sources

namespace tinstream::sources {
namespace {

// Fullwave (format 10, WAVEPACKET14) has no outside decode to compare with (laz-perf 0.0.7
// cannot read it): every layer must be used to its last byte (the decoder checks) and every
// point must lie inside the header's bounds, which the writer computed from the points.
TEST(LazDecode, FullwaveDecodesInsideItsHeaderBounds) {
  SKIP_WITHOUT_DATA("laz_fullwave.laz");
  for (unsigned threads : {1u, 2u}) {
    RecordOptions o;
    o.threads = threads;
    auto reader = LasRecordReader::open(kData / "laz_fullwave.laz", o);
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    const LasFileSummary& s = (*reader)->summary();
    ASSERT_EQ(s.record_length, 67);
    std::vector<std::uint8_t> buf(std::size_t{1000} * s.record_length);
    std::uint64_t total = 0;
    for (;;) {
      auto n = (*reader)->read(buf.data(), 1000);
      ASSERT_TRUE(n.ok()) << n.error().message;
      if (*n == 0) break;
      for (std::size_t i = 0; i < *n; ++i) {
        const std::uint8_t* r = buf.data() + i * s.record_length;
        for (int a = 0; a < 3; ++a) {
          std::int32_t raw;
          std::memcpy(&raw, r + std::ptrdiff_t{4} * a, 4);
          const double v =
              raw * s.scale[static_cast<std::size_t>(a)] + s.offset[static_cast<std::size_t>(a)];
          ASSERT_GE(v, s.min[static_cast<std::size_t>(a)] - 1e-6) << "point " << total + i;
          ASSERT_LE(v, s.max[static_cast<std::size_t>(a)] + 1e-6) << "point " << total + i;
        }
      }
      total += *n;
    }
    EXPECT_EQ(total, 10750u);
  }
}

// --- damaged files: copies of real files with bytes changed -----------------------------------

std::vector<std::uint8_t> slurp(const std::filesystem::path& p) {
  std::vector<std::uint8_t> b(std::filesystem::file_size(p));
  std::FILE* f = std::fopen(p.c_str(), "rb");
  EXPECT_EQ(std::fread(b.data(), 1, b.size(), f), b.size());
  std::fclose(f);
  return b;
}

std::uint64_t le(const std::vector<std::uint8_t>& b, std::size_t at, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | b[at + static_cast<std::size_t>(i)];
  return v;
}
void put_le(std::vector<std::uint8_t>& b, std::size_t at, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i)
    b[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}

class DamagedLaz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("tinstream_laz_" + std::to_string(::getpid()) + "_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path write(const std::vector<std::uint8_t>& bytes, const std::string& name) {
    auto p = dir_ / name;
    std::FILE* f = std::fopen(p.c_str(), "wb");
    std::fwrite(bytes.data(), 1, bytes.size(), f);
    std::fclose(f);
    return p;
  }
  // Reads every record; returns the first error (or nothing).
  static std::optional<Error> read_error(const std::filesystem::path& p, unsigned threads,
                                         std::string* sha = nullptr) {
    RecordOptions o;
    o.threads = threads;
    auto reader = LasRecordReader::open(p, o);
    if (!reader.ok()) return reader.error();
    const std::size_t rl = (*reader)->summary().record_length;
    std::vector<std::uint8_t> buf(5000 * rl);
    EVP_MD_CTX* ctx = EVP_MD_CTX_new();
    EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
    std::optional<Error> err;
    for (;;) {
      auto n = (*reader)->read(buf.data(), 5000);
      if (!n.ok()) {
        err = n.error();
        // The error sticks.
        auto again = (*reader)->read(buf.data(), 5000);
        EXPECT_FALSE(again.ok());
        break;
      }
      if (*n == 0) break;
      EVP_DigestUpdate(ctx, buf.data(), *n * rl);
    }
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned len = 0;
    EVP_DigestFinal_ex(ctx, md, &len);
    EVP_MD_CTX_free(ctx);
    if (sha) *sha = hex(md, len);
    return err;
  }
  static std::vector<laz::ChunkInfo> chunks_of(const std::filesystem::path& p) {
    auto reader = LasRecordReader::open(p, {});
    EXPECT_TRUE(reader.ok());
    return (*reader)->laz()->chunks();
  }
  static void expect_mentions(const Error& e, std::initializer_list<std::string> parts) {
    for (const std::string& part : parts) {
      EXPECT_NE(e.message.find(part), std::string::npos) << e.message << "\n  lacks: " << part;
    }
  }
  std::filesystem::path dir_;
};

constexpr const char* kAutzenSha =
    "f4eb6d80bf1fa507ffdcdaa73606d09041982659a50ee3895957e0b2b347f54b";
constexpr const char* kExtraBytesSha =
    "c19b99bc99062598ede4bed3bc6648832211f51b80ac22c8095cb547d8836406";

TEST_F(DamagedLaz, FlippedByteInAPointwiseChunkNamesTheChunk) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  auto bytes = slurp(kData / "autzen_trim.laz");
  const auto chunks = chunks_of(kData / "autzen_trim.laz");
  ASSERT_EQ(chunks.size(), 3u);
  bytes[chunks[1].offset + chunks[1].bytes / 2] ^= 0x5A;
  const auto p = write(bytes, "flipped.laz");
  for (unsigned threads : {1u, 2u}) {
    auto e = read_error(p, threads);
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(e->code, ErrorCode::corrupt_data);
    expect_mentions(*e, {p.string(), "chunk 2 of 3", "points 50001-100000"});
  }
}

// On one thread lone_star's chunks are decoded two at a time in lock step (1 with 2, 3 with 4,
// ...): damage in either of a pair is reported in its own chunk, after the records before it.
TEST_F(DamagedLaz, FlippedByteInEitherOfTwoChunksDecodedInLockStepNamesIt) {
  SKIP_WITHOUT_DATA("lone_star_tls.laz");
  const auto src = kData / "lone_star_tls.laz";
  const auto chunks = chunks_of(src);
  ASSERT_EQ(chunks.size(), 11u);
  for (const std::size_t damaged : {std::size_t{2}, std::size_t{3}}) {
    auto bytes = slurp(src);
    bytes[chunks[damaged].offset + chunks[damaged].bytes / 2] ^= 0x5A;
    const auto p = write(bytes, "flipped_" + std::to_string(damaged) + ".laz");
    for (unsigned threads : {1u, 2u}) {
      auto e = read_error(p, threads);
      ASSERT_TRUE(e.has_value());
      EXPECT_EQ(e->code, ErrorCode::corrupt_data);
      const std::string first = std::to_string(damaged * 50000 + 1);
      expect_mentions(*e, {p.string(), "chunk " + std::to_string(damaged + 1) + " of 11",
                           "points " + first + "-" + std::to_string(damaged * 50000 + 50000)});
    }
  }
}

// A layer table whose XY/returns layer is empty, its bytes counted in the Z layer instead (the
// sizes still add up to the chunk): a clear error for that chunk. Before, the first chunk a
// decoder met like that divided by zero (SIGFPE), a later one read on in the previous chunk's
// XY stream.
TEST_F(DamagedLaz, EmptyXyLayerInALayerTableNamesTheChunk) {
  SKIP_WITHOUT_DATA("laz_las_with_several_extra_byte_bloc.laz");
  const auto src = kData / "laz_las_with_several_extra_byte_bloc.laz";
  const std::vector<std::uint8_t> original = slurp(src);
  const auto chunks = chunks_of(src);
  ASSERT_EQ(chunks.size(), 14u);
  for (const std::size_t chunk : {std::size_t{0}, std::size_t{2}}) {
    std::vector<std::uint8_t> bytes = original;
    const std::size_t table = chunks[chunk].offset + 41 + 4;  // after the raw point and count
    const std::uint64_t xy = le(bytes, table, 4);
    ASSERT_GT(xy, 0u);
    put_le(bytes, table + 4, le(bytes, table + 4, 4) + xy, 4);
    put_le(bytes, table, 0, 4);
    const auto p = write(bytes, "empty_xy_layer_" + std::to_string(chunk) + ".laz");
    for (unsigned threads : {1u, 2u}) {
      auto e = read_error(p, threads);
      ASSERT_TRUE(e.has_value());
      EXPECT_EQ(e->code, ErrorCode::corrupt_data);
      expect_mentions(*e, {p.string(), "chunk " + std::to_string(chunk + 1) + " of 14",
                           "XY/returns layer is empty"});
    }
  }
}

TEST_F(DamagedLaz, FlippedByteInALayerNamesTheChunk) {
  SKIP_WITHOUT_DATA("laz_las_with_several_extra_byte_bloc.laz");
  const auto src = kData / "laz_las_with_several_extra_byte_bloc.laz";
  auto bytes = slurp(src);
  const auto chunks = chunks_of(src);
  ASSERT_EQ(chunks.size(), 14u);
  // Chunk 5's first layer (X, Y, returns) starts after the raw point, the count and 9 + 2 + 3
  // layer sizes; damage it a little way in.
  bytes[chunks[4].offset + 41 + 4 + std::size_t{4} * 14 + 100] ^= 0x01;
  const auto p = write(bytes, "flipped_layer.laz");
  for (unsigned threads : {1u, 2u}) {
    auto e = read_error(p, threads);
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(e->code, ErrorCode::corrupt_data);
    expect_mentions(*e, {p.string(), "chunk 5 of 14", "points 200001-250000", "layer"});
  }
}

TEST_F(DamagedLaz, TruncatedPointwiseFileFailsInTheCutChunk) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  auto bytes = slurp(kData / "autzen_trim.laz");
  const auto chunks = chunks_of(kData / "autzen_trim.laz");
  bytes.resize(chunks[1].offset + chunks[1].bytes / 3);  // the table is gone too
  const auto p = write(bytes, "truncated.laz");
  auto e = read_error(p, 2);
  ASSERT_TRUE(e.has_value());
  expect_mentions(*e, {p.string(), "chunk 2 of 3", "points 50001-100000"});
}

TEST_F(DamagedLaz, TruncatedLayeredFileIsRefusedAtOpenNamingTheChunk) {
  SKIP_WITHOUT_DATA("laz_las_with_several_extra_byte_bloc.laz");
  const auto src = kData / "laz_las_with_several_extra_byte_bloc.laz";
  auto bytes = slurp(src);
  const auto chunks = chunks_of(src);
  bytes.resize(chunks[7].offset + 1000);
  const auto p = write(bytes, "truncated_layered.laz");
  auto reader = LasRecordReader::open(p, {});
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.error().code, ErrorCode::corrupt_data);
  expect_mentions(reader.error(), {p.string(), "chunk 8", "run past the end"});
}

TEST_F(DamagedLaz, ZeroedChunkTableIsRebuiltForFixedSizeChunks) {
  for (const auto& [name, sha] :
       {std::pair{"autzen_trim.laz", kAutzenSha},
        std::pair{"laz_las_with_several_extra_byte_bloc.laz", kExtraBytesSha}}) {
    SKIP_WITHOUT_DATA(name);
    auto bytes = slurp(kData / name);
    const std::size_t points_at = le(bytes, 96, 4);
    const std::size_t table = le(bytes, points_at, 8);
    std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(table), bytes.end(), 0);
    const auto p = write(bytes, std::string("zeroed_") + name);
    for (unsigned threads : {1u, 2u}) {
      std::string got;
      auto e = read_error(p, threads, &got);
      EXPECT_FALSE(e.has_value()) << e->message;
      EXPECT_EQ(got, sha) << name << " threads " << threads;
    }
    auto reader = LasRecordReader::open(p, {});
    ASSERT_TRUE(reader.ok());
    ASSERT_FALSE((*reader)->laz()->notes().empty());
    EXPECT_NE((*reader)->laz()->notes()[0].find("chunk table unusable"), std::string::npos);
  }
}

TEST_F(DamagedLaz, ZeroedChunkTableOfVariableLayeredChunksIsRebuilt) {
  SKIP_WITHOUT_DATA("laz_simple.copc.laz");
  auto bytes = slurp(kData / "laz_simple.copc.laz");
  const std::size_t points_at = le(bytes, 96, 4);
  const std::size_t table = le(bytes, points_at, 8);
  std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(table),
            bytes.begin() + static_cast<std::ptrdiff_t>(table) + 64, 0);
  const auto p = write(bytes, "zeroed.copc.laz");
  std::string got;
  auto e = read_error(p, 2, &got);
  EXPECT_FALSE(e.has_value()) << e->message;
  EXPECT_EQ(got, "361eda6829430490b1bba3a2665408642d16211f6c349b2f11edf451c8164422");
}

// Finds the LASzip VLR body in a file's bytes.
std::size_t laszip_body(const std::vector<std::uint8_t>& b) {
  const std::string user = "laszip encoded";
  auto it = std::search(b.begin(), b.end(), user.begin(), user.end());
  EXPECT_NE(it, b.end());
  return static_cast<std::size_t>(it - b.begin()) - 2 + 54;
}

TEST_F(DamagedLaz, VariablePointwiseChunksWithoutTableAreAClearError) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  auto bytes = slurp(kData / "autzen_trim.laz");
  put_le(bytes, laszip_body(bytes) + 12, 0, 4);  // chunk size 0: variable
  const std::size_t points_at = le(bytes, 96, 4);
  std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(le(bytes, points_at, 8)), bytes.end(), 0);
  const auto p = write(bytes, "variable.laz");
  auto reader = LasRecordReader::open(p, {});
  ASSERT_FALSE(reader.ok());
  EXPECT_EQ(reader.error().code, ErrorCode::corrupt_data);
  expect_mentions(reader.error(), {p.string(), "variable sizes", "chunk table"});
}

TEST_F(DamagedLaz, UnknownCompressorCoderAndItemVersionAreUnsupported) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  const auto original = slurp(kData / "autzen_trim.laz");
  const std::size_t body = laszip_body(original);
  struct Case {
    std::size_t at;
    std::uint16_t value;
    const char* says;
  };
  for (const Case& c : {Case{body, 7, "compressor 7"}, Case{body + 2, 1, "coder 1"},
                        Case{body + 34 + 6 + 4, 9, "coder version 9"},
                        Case{body + 34 + 12, 99, "unknown type 99"}}) {
    auto bytes = original;
    put_le(bytes, c.at, c.value, 2);
    const auto p = write(bytes, "vlr.laz");
    auto reader = LasRecordReader::open(p, {});
    ASSERT_FALSE(reader.ok()) << c.says;
    EXPECT_EQ(reader.error().code, ErrorCode::unsupported);
    expect_mentions(reader.error(), {p.string(), "LASzip VLR", c.says});
  }
}

TEST_F(DamagedLaz, HeaderCountBeyondTheDataFailsInTheFirstMissingChunk) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  auto bytes = slurp(kData / "autzen_trim.laz");
  put_le(bytes, 107, 200000, 4);  // legacy point count; the chunks hold 110,000
  const auto p = write(bytes, "count.laz");
  auto e = read_error(p, 1);
  ASSERT_TRUE(e.has_value());
  EXPECT_EQ(e->code, ErrorCode::corrupt_data);
  expect_mentions(*e, {p.string(), "chunk 3 of 4", "points 100001-150000"});
}

TEST_F(DamagedLaz, TableOffsetMinusOneIsReadFromTheEnd) {
  SKIP_WITHOUT_DATA("autzen_trim.laz");
  auto bytes = slurp(kData / "autzen_trim.laz");
  const std::size_t points_at = le(bytes, 96, 4);
  const std::uint64_t table = le(bytes, points_at, 8);
  put_le(bytes, points_at, ~std::uint64_t{0}, 8);  // -1
  bytes.resize(bytes.size() + 8);
  put_le(bytes, bytes.size() - 8, table, 8);
  const auto p = write(bytes, "minus_one.laz");
  std::string got;
  auto e = read_error(p, 2, &got);
  EXPECT_FALSE(e.has_value()) << e->message;
  EXPECT_EQ(got, kAutzenSha);
  auto reader = LasRecordReader::open(p, {});
  ASSERT_TRUE(reader.ok());
  EXPECT_TRUE((*reader)->laz()->notes().empty());  // the table itself was used
}

}  // namespace
}  // namespace tinstream::sources
