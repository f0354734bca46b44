// Decodes the LAZ files of ../shared/data (SOURCES.md sections A and D) and compares the
// records with references made by others: the sha256 of laz-perf 0.0.7's decode listed in
// SOURCES.md, or the records of the uncompressed twin the file was made from.
#include <gtest/gtest.h>
#include <openssl/evp.h>

#include <cstdio>
#include <filesystem>
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
    if (keep) out.bytes.insert(out.bytes.end(), buf.begin(), buf.begin() + *n * rl);
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

}  // namespace
}  // namespace tinstream::sources
