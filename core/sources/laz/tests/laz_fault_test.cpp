// The LAZ chunk decoder's worker threads (chunk_pipeline) under injected failures (fault.hpp):
// an exception or an out-of-memory in a worker, and a thread that cannot be created, are the
// reader's Error naming the file — never std::terminate — and the process reads the file
// afterwards as usual. Reads autzen_trim.laz of ../shared/data
// (three chunks, so two threads decode it through the pipeline); skipped when it is absent.
#include <gtest/gtest.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/base/fault.hpp"
#include "tinstream/sources/las_records.hpp"

namespace tinstream::sources {
namespace {

const std::filesystem::path kAutzen =
    std::filesystem::path(TINSTREAM_SHARED_DATA) / "autzen_trim.laz";
constexpr std::uint64_t kAutzenPoints = 110000;

struct Outcome {
  std::uint64_t records = 0;
  std::optional<Error> error;
};

// Reads every record on two threads; stops at the first error, which must stick.
Outcome read_all() {
  Outcome out;
  RecordOptions o;
  o.threads = 2;
  auto reader = LasRecordReader::open(kAutzen, o);
  if (!reader.ok()) {
    out.error = reader.error();
    return out;
  }
  const std::size_t rl = (*reader)->summary().record_length;
  std::vector<std::uint8_t> buf(4096 * rl);
  for (;;) {
    auto n = (*reader)->read(buf.data(), 4096);
    if (!n.ok()) {
      out.error = n.error();
      auto again = (*reader)->read(buf.data(), 4096);
      EXPECT_FALSE(again.ok()) << "the error did not stick";
      return out;
    }
    if (*n == 0) return out;
    out.records += *n;
  }
}

struct Case {
  const char* point;
  std::uint64_t skip;
  fault::Kind kind;
  const char* message;
};

class LazWorkerFault : public ::testing::TestWithParam<Case> {};

TEST_P(LazWorkerFault, IsTheReadersErrorAndTheNextReadSucceeds) {
  if (!std::filesystem::exists(kAutzen)) GTEST_SKIP() << "shared data absent: " << kAutzen;
  if (!fault::enabled()) GTEST_SKIP() << "built without fault injection";
  const Case& c = GetParam();
  {
    const fault::Arm arm(c.point, c.skip, c.kind);
    const Outcome failed = read_all();
    EXPECT_TRUE(arm.fired()) << "the reader never passed " << c.point;
    ASSERT_TRUE(failed.error.has_value()) << "read " << failed.records << " records";
    EXPECT_NE(failed.error->message.find(c.message), std::string::npos) << failed.error->message;
    EXPECT_NE(failed.error->message.find("autzen_trim.laz"), std::string::npos)
        << failed.error->message;
    EXPECT_LT(failed.records, kAutzenPoints);
  }
  const Outcome ok = read_all();
  EXPECT_FALSE(ok.error.has_value()) << ok.error->message;
  EXPECT_EQ(ok.records, kAutzenPoints);
}

INSTANTIATE_TEST_SUITE_P(
    ChunkPipeline, LazWorkerFault,
    ::testing::Values(Case{"laz.decode", 0, fault::Kind::throw_error,
                           "injected fault at laz.decode"},
                      Case{"laz.decode", 2, fault::Kind::out_of_memory, "out of memory"},
                      Case{"laz.decode.spawn", 0, fault::Kind::no_thread, "cannot start a thread"},
                      Case{"laz.decode.spawn", 1, fault::Kind::no_thread, "cannot start a thread"}),
    [](const ::testing::TestParamInfo<Case>& p) {
      std::string name = std::string(p.param.point) + "_" + std::to_string(p.param.skip);
      for (char& ch : name) {
        if (ch == '.') ch = '_';
      }
      return name;
    });

}  // namespace
}  // namespace tinstream::sources
