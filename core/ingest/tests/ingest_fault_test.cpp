// #22, worker crashes: a failure injected into each worker thread of the ingest (pass 1's
// transform workers and reading thread, pass 2's spill, run-writer and merge threads, pass 3's
// cell-index readers and tile workers, the store queue, the LOD pool), or a thread of each that
// cannot be created, ends the ingest with an Error naming the worker. Before the exception
// barriers these reached std::terminate (an exception on a worker, or a std::thread vector
// unwound while its threads ran): the whole test process died. After each failure the layer
// published before is unchanged and no temporary file is left.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "tinstream/base/fault.hpp"
#include "tinstream/ingest/ingest.hpp"
#include "tinstream/ingest/verify.hpp"

namespace tinstream::ingest {
namespace {

namespace fs = std::filesystem;

struct Fault {
  const char* point;
  std::uint64_t skip;
  fault::Kind kind;
  const char* message;  // in the ingest's Error
};

std::ostream& operator<<(std::ostream& os, const Fault& f) {
  return os << f.point << "@" << f.skip;
}

class IngestFault : public ::testing::TestWithParam<Fault> {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("tinstream-ingest-fault-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // Hilly terrain near Zürich: enough points for several spills, merge passes on two threads,
    // dozens of finest tiles and a pyramid above them.
    std::ofstream out(dir_ / "hills.xyz");
    out.precision(12);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < 30000; ++i) {
      const double lon = 8.5 + 0.02 * u(rng), lat = 47.3 + 0.02 * u(rng);
      out << lon << " " << lat << " " << 400 + 80 * std::sin(lon * 300) * std::cos(lat * 250)
          << "\n";
    }
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static IngestOptions options(const fs::path& store) {
    IngestOptions o;
    o.store_path = store;
    o.layer = "hills";
    transform::InputSpec in;
    in.path = dir_ / "hills.xyz";
    in.reproject.crs = "EPSG:4326";
    o.inputs.push_back(in);
    o.max_points = 500;
    o.threads = 2;
    o.tmp_dir = store.parent_path() / "tmp";
    o.memory_bytes = 1 << 20;  // many spills
    return o;
  }

  static fs::path dir_;
};

fs::path IngestFault::dir_;

TEST_P(IngestFault, EndsTheIngestWithAnErrorAndLeavesThePublishedLayer) {
  ASSERT_TRUE(fault::enabled()) << "fault points are not compiled into this test build";
  const Fault& f = GetParam();
  const fs::path here = dir_ / (std::string(f.point) + "-" + std::to_string(f.skip));
  fs::create_directories(here);
  const fs::path store_path = here / "store.sqlite";
  ASSERT_TRUE(run_ingest(options(store_path)).ok());
  std::int64_t version = 0;
  std::uint64_t tiles = 0;
  {
    auto store = store::TileStore::open(store_path, store::TileStore::Mode::read_only);
    ASSERT_TRUE(store.ok());
    version = store->layer("hills")->version;
    tiles = store->layer("hills")->tile_count;
  }

  const fault::Arm arm(f.point, f.skip, f.kind);
  auto failed = run_ingest(options(store_path));
  EXPECT_TRUE(arm.fired()) << "the ingest never passed " << f.point;
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.error().message.find(f.message), std::string::npos) << failed.error().message;

  auto store = store::TileStore::open(store_path, store::TileStore::Mode::read_only);
  ASSERT_TRUE(store.ok());
  EXPECT_EQ(store->layer("hills")->version, version);
  EXPECT_EQ(store->layer("hills")->tile_count, tiles);
  auto report = verify_layer(*store, "hills");
  ASSERT_TRUE(report.ok()) << report.error().message;
  EXPECT_TRUE(report->ok());
  EXPECT_TRUE(fs::is_empty(here / "tmp")) << "temporary files left behind";
}

constexpr auto kThrow = fault::Kind::throw_error;
constexpr auto kNoThread = fault::Kind::no_thread;
constexpr auto kOom = fault::Kind::out_of_memory;

INSTANTIATE_TEST_SUITE_P(
    EveryWorker, IngestFault,
    ::testing::Values(
        Fault{"pass1.transform", 0, kThrow, "pass 1 transform: injected fault at pass1.transform"},
        Fault{"pass1.read", 0, kThrow, "pass 1: injected fault at pass1.read"},
        Fault{"pass2.spill", 2, kThrow, "pass 2 spill: injected fault at pass2.spill"},
        Fault{"pass2.writer", 1, kThrow, "cannot write"},
        Fault{"pass2.merge", 0, kThrow, "pass 2 merge: injected fault at pass2.merge"},
        Fault{"pass3.cells", 3, kThrow, "pass 3 cell index: injected fault at pass3.cells"},
        Fault{"pass3.tile", 5, kThrow, "pass 3 worker: injected fault at pass3.tile"},
        Fault{"pass3.tile", 0, kOom, "pass 3 worker: out of memory"},
        Fault{"store.queue", 4, kThrow, "store queue: injected fault at store.queue"},
        Fault{"lod.tile", 2, kThrow, "lod: injected fault at lod.tile"},
        Fault{"pass1.transform.spawn", 1, kNoThread, "pass 1 transform: cannot start a thread"},
        Fault{"pass2.spill.spawn", 1, kNoThread, "pass 2 spill: cannot start a thread"},
        Fault{"pass2.writer.spawn", 0, kNoThread, "pass 2 run writer: cannot start a thread"},
        Fault{"pass2.merge.spawn", 0, kNoThread, "pass 2 merge: cannot start a thread"},
        Fault{"pass3.cells.spawn", 0, kNoThread, "pass 3 cell index: cannot start a thread"},
        Fault{"pass3.tile.spawn", 1, kNoThread, "pass 3 worker: cannot start a thread"},
        Fault{"store.queue.spawn", 0, kNoThread, "store queue: cannot start a thread"},
        Fault{"lod.tile.spawn", 1, kNoThread, "lod worker: cannot start a thread"}),
    [](const ::testing::TestParamInfo<Fault>& p) {
      std::string name = std::string(p.param.point) + "_" + std::to_string(p.param.skip) +
                         (p.param.kind == kOom ? "_oom" : "");
      for (char& c : name) {
        if (c == '.') c = '_';
      }
      return name;
    });

}  // namespace
}  // namespace tinstream::ingest
