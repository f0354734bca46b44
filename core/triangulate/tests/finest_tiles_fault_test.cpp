// #22: deferred read errors in pass 3. A tile's candidate cells are read ahead ("peeked") while
// its halo grows, and a failed peek is reported when the round ends. Before the fix a failed peek
// went on with the chunk of the previous read (another cell's points, taken as this cell's) and a
// later failed peek overwrote the first error. Now the first error is the tile's and a failed
// read contributes nothing. Reads fail through the fault point "sorted_run.read" (error kind),
// from pass n on, for every n until the tile needs no more reads.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "tinstream/base/fault.hpp"
#include "tinstream/subdivide/sorted_run.hpp"
#include "tinstream/triangulate/finest_tiles.hpp"

namespace tinstream::triangulate {
namespace {

namespace fs = std::filesystem;
using subdivide::InputPoint;

TEST(FinestTileFaults, TheFirstFailedReadIsTheTilesErrorWhereverItHappens) {
  ASSERT_TRUE(fault::enabled()) << "fault points are not compiled into this test build";
  const fs::path dir =
      fs::temp_directory_path() / ("tinstream-tri-fault-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  // A cluster with a sparse ring around it: the middle tiles' halos need candidate cells from
  // their neighbours, read ahead (peeked) before they join.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<InputPoint> points;
  for (int i = 0; i < 4000; ++i) {
    const double x = 0.1 + 3e-4 * u(rng), y = 0.2 + 3e-4 * u(rng);
    points.push_back({x, y, 100.0 + 50.0 * std::sin(x * 3e4)});
  }
  subdivide::SubdivideOptions opt;
  opt.tmp_dir = dir;
  opt.max_points = 200;
  std::size_t pos = 0;
  auto run = subdivide::subdivide(
      [&](std::vector<InputPoint>& batch) -> Result<std::size_t> {
        const std::size_t n = std::min<std::size_t>(4096, points.size() - pos);
        batch.insert(batch.end(), points.begin() + static_cast<std::ptrdiff_t>(pos),
                     points.begin() + static_cast<std::ptrdiff_t>(pos + n));
        pos += n;
        return n;
      },
      opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  ASSERT_GT(run->tiles.size(), 9u);
  auto cells = PointCells::build(*run, 1);
  ASSERT_TRUE(cells.ok()) << cells.error().message;
  const geo::TileId id = run->tiles[run->tiles.size() / 2].id;
  auto reader = subdivide::SortedRunReader::open(run->path);
  ASSERT_TRUE(reader.ok());
  auto clean = build_finest_tile(id, **cells, *reader);
  ASSERT_TRUE(clean.ok()) << clean.error().message;

  std::uint64_t reads = 0;
  for (std::uint64_t skip = 0; skip < 100000; ++skip) {
    const fault::Arm arm("sorted_run.read", skip, fault::Kind::error, 1u << 30);
    auto tile = build_finest_tile(id, **cells, *reader);
    if (!arm.fired()) {  // the tile needs no more than `skip` reads
      ASSERT_TRUE(tile.ok()) << tile.error().message;
      reads = skip;
      break;
    }
    ASSERT_FALSE(tile.ok()) << "a tile built although read " << skip + 1 << " failed";
    EXPECT_EQ(tile.error().code, ErrorCode::io_error);
    const std::string first = "(pass " + std::to_string(skip + 1) + ")";
    EXPECT_NE(tile.error().message.find(first), std::string::npos)
        << "read " << skip + 1 << " failed first, the tile reports: " << tile.error().message;
  }
  EXPECT_GT(reads, 2u) << "the tile should read its own points, its ring and peeked cells";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace tinstream::triangulate
