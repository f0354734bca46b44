#include "tinstream/subdivide/sorted_run.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <tuple>

namespace tinstream::subdivide {
namespace {

namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("tinstream-subdivide-test-" + std::to_string(::getpid()) + "-" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }
  std::size_t entries() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(path_), fs::directory_iterator()));
  }

 private:
  fs::path path_;
};

PointFeed feed_of(const std::vector<InputPoint>& points, std::size_t batch_size = 1000) {
  auto pos = std::make_shared<std::size_t>(0);
  return [&points, pos, batch_size](std::vector<InputPoint>& batch) -> Result<std::size_t> {
    const std::size_t n = std::min(batch_size, points.size() - *pos);
    batch.insert(batch.end(), points.begin() + static_cast<std::ptrdiff_t>(*pos),
                 points.begin() + static_cast<std::ptrdiff_t>(*pos + n));
    *pos += n;
    return n;
  };
}

// Points around a small area (a few km near Bern), with clusters, like a LiDAR strip.
std::vector<InputPoint> clustered_points(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<InputPoint> pts;
  const double x0 = 0.0414, y0 = 0.3524, span = 2e-4;
  while (pts.size() < n) {
    double x, y;
    if (pts.size() % 3 == 0) {
      x = x0 + span * (0.3 + 0.02 * g(rng));
      y = y0 + span * (0.6 + 0.02 * g(rng));
    } else {
      x = x0 + span * u(rng);
      y = y0 + span * u(rng);
    }
    pts.push_back({x, y, 500.0 + 100.0 * u(rng)});
  }
  return pts;
}

std::vector<SortedPoint> read_all(const SortedRun& run) {
  auto reader = SortedRunReader::open(run.path);
  EXPECT_TRUE(reader.ok());
  std::vector<SortedPoint> all;
  EXPECT_TRUE(reader->read(0, reader->size(), all).ok());
  return all;
}

// The reference order, computed from the tile module rather than the run's bit tricks:
// Morton pre-order of the level-30 cell, then x, then y.
bool reference_less(const InputPoint& a, const InputPoint& b) {
  const geo::TileId ca = geo::TileId::containing({a.x, a.y}, 30);
  const geo::TileId cb = geo::TileId::containing({b.x, b.y}, 30);
  if (ca != cb) return geo::morton_less(ca, cb);
  if (a.x != b.x) return a.x < b.x;
  return a.y < b.y;
}

void expect_matches_reference(std::vector<InputPoint> input, const SortedRun& run) {
  std::sort(input.begin(), input.end(), reference_less);
  const auto all = read_all(run);
  ASSERT_EQ(all.size(), input.size());
  for (std::size_t i = 0; i < all.size(); ++i) {
    ASSERT_EQ(all[i].x, input[i].x) << i;
    ASSERT_EQ(all[i].y, input[i].y) << i;
    ASSERT_EQ(all[i].z, input[i].z) << i;
  }
}

TEST(Subdivide, SortsIntoMortonOrderAndChoosesSmallestFittingLevel) {
  TempDir tmp;
  const auto pts = clustered_points(60000, 1);
  SubdivideOptions opt;
  opt.max_points = 2000;
  opt.tmp_dir = tmp.path();
  auto run = subdivide(feed_of(pts), opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  EXPECT_EQ(run->points, pts.size());
  EXPECT_EQ(run->duplicates_merged, 0u);
  expect_matches_reference(pts, *run);

  // Independent count of the fullest tile per level.
  auto fullest = [&](std::uint32_t level) {
    std::map<geo::TileId, std::uint64_t> counts;
    for (const auto& p : pts) ++counts[geo::TileId::containing({p.x, p.y}, level)];
    std::uint64_t m = 0;
    for (const auto& [id, c] : counts) m = std::max(m, c);
    return m;
  };
  const std::uint32_t L = run->finest_level;
  EXPECT_LE(fullest(L), opt.max_points);
  ASSERT_GT(L, 0u);
  EXPECT_GT(fullest(L - 1), opt.max_points);
  EXPECT_EQ(run->max_tile_points[L], fullest(L));

  // The index: Morton-ordered tiles whose ranges hold exactly their points.
  const auto all = read_all(*run);
  std::uint64_t expected_first = 0;
  for (std::size_t t = 0; t < run->tiles.size(); ++t) {
    const TileRange& r = run->tiles[t];
    EXPECT_EQ(r.first, expected_first);
    if (t > 0) {
      EXPECT_TRUE(geo::morton_less(run->tiles[t - 1].id, r.id));
    }
    for (std::uint64_t i = r.first; i < r.first + r.count; ++i) {
      ASSERT_EQ(geo::TileId::containing({all[i].x, all[i].y}, L), r.id);
    }
    expected_first += r.count;
  }
  EXPECT_EQ(expected_first, all.size());
  EXPECT_EQ(tmp.entries(), 1u);  // only the output run remains
}

TEST(Subdivide, TinyMemoryBudgetForcesMultiPassMergeWithSameResult) {
  TempDir tmp;
  const auto pts = clustered_points(300000, 2);
  SubdivideOptions opt;
  opt.max_points = 5000;
  opt.memory_bytes = 4096 * sizeof(SortedPoint);  // 1024-record chunks → ~293 runs > fan-in 64
  opt.tmp_dir = tmp.path();
  int merge_reports = 0;
  auto run = subdivide(feed_of(pts, 777), opt, [&](const Progress& p) {
    if (p.phase == "merge") ++merge_reports;
    return true;
  });
  ASSERT_TRUE(run.ok()) << run.error().message;
  expect_matches_reference(pts, *run);
  EXPECT_GT(merge_reports, 0);
  EXPECT_EQ(tmp.entries(), 1u);
}

// What the run must hold, computed the slow way: every point keyed, std::sort by the full run
// order (key, x, y, lowest z, highest weight), then the first of every equal (x, y) kept.
std::vector<SortedPoint> reference_run(const std::vector<InputPoint>& input) {
  std::vector<SortedPoint> all;
  all.reserve(input.size());
  for (const auto& p : input) all.push_back({cell_key(p.x, p.y), p.x, p.y, p.z, p.weight, 0});
  std::sort(all.begin(), all.end(), [](const SortedPoint& a, const SortedPoint& b) {
    return std::tie(a.key, a.x, a.y, a.z, b.weight) < std::tie(b.key, b.x, b.y, b.z, a.weight);
  });
  std::vector<SortedPoint> kept;
  for (const auto& p : all) {
    if (!kept.empty() && kept.back().x == p.x && kept.back().y == p.y) continue;
    kept.push_back(p);
  }
  return kept;
}

void expect_same_records(const std::vector<SortedPoint>& expected, const SortedRun& run) {
  const auto all = read_all(run);
  ASSERT_EQ(all.size(), expected.size());
  for (std::size_t i = 0; i < all.size(); ++i) {
    ASSERT_EQ(all[i].key, expected[i].key) << i;
    ASSERT_EQ(all[i].x, expected[i].x) << i;
    ASSERT_EQ(all[i].y, expected[i].y) << i;
    ASSERT_EQ(all[i].z, expected[i].z) << i;
    ASSERT_EQ(all[i].weight, expected[i].weight) << i;
  }
}

// Keys that share a level-30 cell (many points a few ulps apart, so equal keys are common),
// exact duplicates with different z and weights, keys varying in every bit (points all over the
// map, on tile edges and on the map's border): the radix sort plus the equal-key pass must give
// exactly the comparator's order, in single runs and through multi-pass merges.
TEST(Subdivide, RadixOrderEqualsComparatorOrderOnAdversarialKeys) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> small(0, 3);
  std::vector<InputPoint> pts;
  pts.reserve(3000);
  for (int i = 0; i < 3000; ++i) {  // all over the map
    pts.push_back({u(rng), u(rng), 10.0 * small(rng), static_cast<float>(small(rng))});
  }
  for (double edge : {-1.0, -0.5, 0.0, 0.25, 0.5, 1.0}) {  // tile edges and the map's border
    for (int i = 0; i < 50; ++i) pts.push_back({edge, u(rng), 1.0 * i, 1});
    pts.push_back({edge, edge, 2.0, 1});
  }
  const double cx = 0.123456789, cy = -0.3456789;
  for (int i = 0; i < 6000; ++i) {  // one cell: equal keys, x and y a few ulps apart, duplicates
    double x = cx, y = cy;
    for (int k = small(rng); k > 0; --k) x = std::nextafter(x, 1.0);
    for (int k = small(rng); k > 0; --k) y = std::nextafter(y, -1.0);
    pts.push_back({x, y, 1.0 * small(rng), static_cast<float>(small(rng))});
  }
  std::shuffle(pts.begin(), pts.end(), rng);
  const auto expected = reference_run(pts);
  ASSERT_LT(expected.size(), pts.size());  // the input does hold duplicates
  for (std::size_t memory : {std::size_t{256} << 20, std::size_t{1}}) {
    TempDir tmp;
    SubdivideOptions opt;
    opt.tmp_dir = tmp.path();
    opt.max_points = 100;
    opt.memory_bytes = memory;  // one run, or ~20 runs of 731 records
    auto run = subdivide(feed_of(pts, 333), opt);
    ASSERT_TRUE(run.ok()) << run.error().message;
    expect_same_records(expected, *run);
    EXPECT_EQ(run->duplicates_merged, pts.size() - expected.size());
    // The fullest tile of every level, counted over the distinct points through the tile module.
    ASSERT_EQ(run->max_tile_points.size(), 31u);
    for (std::uint32_t level = 0; level <= 30; ++level) {
      std::map<geo::TileId, std::uint64_t> counts;
      for (const auto& p : expected) ++counts[geo::TileId::containing({p.x, p.y}, level)];
      std::uint64_t fullest = 0;
      for (const auto& [id, c] : counts) fullest = std::max(fullest, c);
      EXPECT_EQ(run->max_tile_points[level], fullest) << "level " << level << ", " << memory;
    }
  }
}

// The tile index comes from the merge's tally when it could keep a fine enough level and from a
// re-read of the run when not; both must be the index of the run. With T tiles at level L, a
// tally of T entries ends exactly at L (after coarsening from max_level), T - 1 entries forces
// the re-read, 4T ends finer than L.
TEST(Subdivide, TileIndexSameWhetherTalliedOrReRead) {
  const auto pts = clustered_points(50000, 12);
  auto check = [&](std::size_t entries) -> std::size_t {
    TempDir tmp;
    SubdivideOptions opt;
    opt.tmp_dir = tmp.path();
    opt.max_points = 2000;
    opt.index_entries = entries;
    opt.memory_bytes = 4096 * sizeof(SortedPoint);
    auto run = subdivide(feed_of(pts), opt);
    EXPECT_TRUE(run.ok()) << run.error().message;
    if (!run.ok()) return 0;
    // Independent: the tiles of level L in the order of the run, counted from the records.
    const auto all = read_all(*run);
    std::vector<TileRange> expected;
    for (std::uint64_t i = 0; i < all.size(); ++i) {
      const auto id = geo::TileId::containing({all[i].x, all[i].y}, run->finest_level);
      if (expected.empty() || expected.back().id != id) expected.push_back({id, i, 0});
      ++expected.back().count;
    }
    EXPECT_EQ(run->tiles.size(), expected.size()) << entries;
    for (std::size_t t = 0; t < std::min(expected.size(), run->tiles.size()); ++t) {
      EXPECT_EQ(run->tiles[t].id, expected[t].id) << entries << " " << t;
      EXPECT_EQ(run->tiles[t].first, expected[t].first) << entries << " " << t;
      EXPECT_EQ(run->tiles[t].count, expected[t].count) << entries << " " << t;
    }
    EXPECT_EQ(tmp.entries(), 1u);
    return expected.size();
  };
  const std::size_t tiles = check(2);
  ASSERT_GT(tiles, 10u);
  for (std::size_t entries : {tiles - 1, tiles, 4 * tiles, std::size_t{0}, std::size_t{1} << 20}) {
    check(entries);
  }
}

// A file already at the output path is replaced by the sorted run (the merge creates its output):
// the file then has exactly the run's size, whether the old one was longer or shorter.
TEST(Subdivide, ExistingOutputFileIsReplaced) {
  const auto pts = clustered_points(5000, 14);
  const auto expected = reference_run(pts);
  for (std::size_t garbage : {std::size_t{1} << 20, std::size_t{1000}}) {
    TempDir tmp;
    SubdivideOptions opt;
    opt.tmp_dir = tmp.path();
    opt.max_points = 500;
    opt.output = tmp.path() / "sorted.run";
    {
      std::FILE* f = std::fopen(opt.output.c_str(), "wb");
      const std::vector<char> junk(garbage, 'x');
      std::fwrite(junk.data(), 1, junk.size(), f);
      std::fclose(f);
    }
    auto run = subdivide(feed_of(pts), opt);
    ASSERT_TRUE(run.ok()) << run.error().message;
    EXPECT_EQ(fs::file_size(opt.output), expected.size() * sizeof(SortedPoint));
    expect_same_records(expected, *run);
    EXPECT_EQ(tmp.entries(), 1u);
  }
}

TEST(Subdivide, DuplicatesMergedLowestZWins) {
  TempDir tmp;
  std::vector<InputPoint> pts = {{0.1, 0.2, 10}, {0.1, 0.2, 7}, {0.3, 0.2, 1},
                                 {0.1, 0.2, 9},  {0.3, 0.2, 1}, {-0.5, -0.5, 3}};
  SubdivideOptions opt;
  opt.tmp_dir = tmp.path();
  opt.memory_bytes = 1;  // even the smallest budget works (runs of a few records)
  auto run = subdivide(feed_of(pts, 2), opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  EXPECT_EQ(run->points, 3u);
  EXPECT_EQ(run->duplicates_merged, 3u);
  const auto all = read_all(*run);
  for (const auto& p : all) {
    if (p.x == 0.1) {
      EXPECT_EQ(p.z, 7);
    }
  }
  // 3 points fit the world tile, but they span 0.8 of the map's width 2: level 1's tiles (1 wide)
  // are the finest at least that wide (the extent floor).
  EXPECT_EQ(run->finest_level, 1u);
}

TEST(Subdivide, ExtentLevelIsTheDeepestLevelWhoseTilesAreAtLeastTheBoxWide) {
  EXPECT_EQ(extent_level(0, 0), 0u);  // one position: no scale
  EXPECT_EQ(extent_level(2, 0), 0u);  // the whole map
  EXPECT_EQ(extent_level(1, 0.3), 1u);
  EXPECT_EQ(extent_level(0.3, 1.0000001), 0u);
  for (const double w : {1e-3, 3.7e-6, 1e-9}) {
    const std::uint32_t l = extent_level(w, w / 2);
    EXPECT_GE(2.0 / std::pow(2.0, l), w) << w;      // its tiles hold the box's width
    EXPECT_LT(2.0 / std::pow(2.0, l + 1), w) << w;  // the next level's do not
  }
  EXPECT_EQ(extent_level(1e-300, 0), 30u);  // never past the key level
}

// A small dataset (a LiDAR crop fits one tile's budget) is not stored in a world-sized tile: its
// finest level is where it spans at most 2 × 2 tiles, as quantised encodings need (quantized-mesh:
// 32,767 steps across a tile; a 9,003-point crop in a level-0 tile read as 5 positions).
TEST(Subdivide, ASmallDatasetGetsTheFinestLevelItsExtentAsksFor) {
  TempDir tmp;
  std::vector<InputPoint> pts;
  const double x0 = -0.5903, y0 = 0.2077, side = 1e-5;  // about 100 m square at 35° N
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) pts.push_back({x0 + side * i / 29, y0 + side * j / 29, 1.0 * i});
  SubdivideOptions opt;
  opt.tmp_dir = tmp.path();
  auto run = subdivide(feed_of(pts), opt);
  ASSERT_TRUE(run.ok()) << run.error().message;
  // 900 points fit level 0's budget; 2 / 2^17 ≈ 1.5e-5 ≥ 1e-5 > 2 / 2^18.
  EXPECT_EQ(run->finest_level, 17u);
  EXPECT_GE(run->tiles.size(), 1u);
  EXPECT_LE(run->tiles.size(), 4u);
  std::uint64_t points = 0;
  for (const TileRange& t : run->tiles) points += t.count;
  EXPECT_EQ(points, 900u);
  // max_level still caps it.
  opt.max_level = 12;
  auto capped = subdivide(feed_of(pts), opt);
  ASSERT_TRUE(capped.ok()) << capped.error().message;
  EXPECT_EQ(capped->finest_level, 12u);
}

TEST(Subdivide, LevelCappedWhenPointsCannotBeSeparated) {
  TempDir tmp;
  std::vector<InputPoint> pts;
  pts.reserve(50);
  for (int i = 0; i < 50; ++i) pts.push_back({0.25 + i * 1e-15, 0.25, 1.0 * i});
  SubdivideOptions opt;
  opt.tmp_dir = tmp.path();
  opt.max_points = 10;
  opt.max_level = 12;
  auto run = subdivide(feed_of(pts), opt);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->finest_level, 12u);
  ASSERT_EQ(run->tiles.size(), 1u);
  EXPECT_EQ(run->tiles[0].count, 50u);
}

TEST(Subdivide, NonFiniteOrOutOfRangePointRejectedByIndex) {
  TempDir tmp;
  SubdivideOptions opt;
  opt.tmp_dir = tmp.path();
  std::vector<InputPoint> pts = {{0.1, 0.1, 1}, {0.2, 0.2, 2}, {0.3, NAN, 3}};
  auto run = subdivide(feed_of(pts), opt);
  ASSERT_FALSE(run.ok());
  EXPECT_NE(run.error().message.find("point 2"), std::string::npos) << run.error().message;
  pts = {{1.5, 0.1, 1}};
  EXPECT_FALSE(subdivide(feed_of(pts), opt).ok());
  EXPECT_EQ(tmp.entries(), 0u);  // nothing left behind
}

TEST(Subdivide, CancelStopsAndCleansUp) {
  TempDir tmp;
  const auto pts = clustered_points(20000, 3);
  SubdivideOptions opt;
  opt.tmp_dir = tmp.path();
  opt.memory_bytes = 4096 * sizeof(SortedPoint);
  auto run = subdivide(feed_of(pts), opt, [](const Progress& p) { return p.done < 5000; });
  ASSERT_FALSE(run.ok());
  EXPECT_EQ(run.error().code, ErrorCode::cancelled);
  EXPECT_EQ(tmp.entries(), 0u);
}

TEST(Subdivide, KeyToTileMatchesContainment) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 20000; ++i) {
    const double x = u(rng), y = u(rng);
    const std::uint64_t key = cell_key(x, y);
    for (std::uint32_t level : {0u, 3u, 11u, 20u, 30u}) {
      ASSERT_EQ(tile_of_key(key, level), geo::TileId::containing({x, y}, level));
    }
  }
}

// cell_key finds the level-30 cell without geo's search: it must agree with
// TileId::containing exactly, also on and one ulp either side of cell edges (where c + 1 rounds),
// at the map's border, beyond it (clamped) and for NaN.
TEST(Subdivide, CellKeyMatchesContainmentOnCellEdges) {
  std::mt19937_64 rng(13);
  std::uniform_int_distribution<std::uint32_t> cell(0, (1u << 30) - 1);
  std::vector<double> coords = {-1.0,    1.0,   0.0,    -0.0, 0.5,  -0.5, 1e-300,
                                -1e-300, 1e-20, -1e-20, 2.0,  -3.0, NAN};
  for (int i = 0; i < 20000; ++i) {
    const double edge = -1.0 + std::ldexp(static_cast<double>(cell(rng)), -29);
    coords.push_back(edge);
    coords.push_back(std::nextafter(edge, -2.0));
    coords.push_back(std::nextafter(edge, 2.0));
  }
  std::uniform_int_distribution<std::size_t> pick(0, coords.size() - 1);
  for (int i = 0; i < 200000; ++i) {
    const double x = coords[pick(rng)], y = coords[pick(rng)];
    const geo::TileId expected = geo::TileId::containing({x, y}, 30);
    ASSERT_EQ(tile_of_key(cell_key(x, y), 30), expected) << x << " " << y;
  }
}

TEST(Subdivide, ReaderRejectsOutOfRangeAndTruncatedFiles) {
  TempDir tmp;
  const fs::path bad = tmp.path() / "bad.run";
  {
    std::FILE* f = std::fopen(bad.c_str(), "wb");
    std::fputs("not a multiple of forty bytes", f);
    std::fclose(f);
  }
  auto r = SortedRunReader::open(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("bad.run"), std::string::npos);
  const auto pts = clustered_points(100, 5);
  SubdivideOptions opt;
  opt.tmp_dir = tmp.path();
  auto run = subdivide(feed_of(pts), opt);
  ASSERT_TRUE(run.ok());
  auto reader = SortedRunReader::open(run->path);
  ASSERT_TRUE(reader.ok());
  std::vector<SortedPoint> out;
  EXPECT_FALSE(reader->read(90, 20, out).ok());
  EXPECT_TRUE(reader->read(90, 10, out).ok());
}

// The temporary runs store 32 bytes per record, without the key; the merge computes it again
// as it reads them (a key left 0, or wrong, would show in the order and in the keys of the
// sorted run, which keeps them): the sorted run's bytes are 40-byte records whose keys are
// those of the tile module, through single- and multi-pass merges.
TEST(Subdivide, SpillsDropTheKeyAndTheSortedRunKeepsIt) {
  const auto pts = clustered_points(3000, 21);
  const auto expected = reference_run(pts);
  for (std::size_t memory : {std::size_t{256} << 20, std::size_t{1}}) {
    TempDir tmp;
    SubdivideOptions opt;
    opt.tmp_dir = tmp.path();
    opt.memory_bytes = memory;
    auto run = subdivide(feed_of(pts, 100), opt);
    ASSERT_TRUE(run.ok()) << run.error().message;
    std::ifstream in(run->path, std::ios::binary);
    const std::vector<unsigned char> bytes(std::istreambuf_iterator<char>(in), {});
    ASSERT_EQ(bytes.size(), expected.size() * 40);
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const unsigned char* rec = bytes.data() + 40 * i;
      std::uint64_t key;
      double x, y, z;
      float w;
      std::memcpy(&key, rec, 8);
      std::memcpy(&x, rec + 8, 8);
      std::memcpy(&y, rec + 16, 8);
      std::memcpy(&z, rec + 24, 8);
      std::memcpy(&w, rec + 32, 4);
      const geo::TileId cell = geo::TileId::containing({x, y}, 30);
      ASSERT_EQ(key, morton_interleave(cell.x, cell.y)) << i;
      ASSERT_EQ(x, expected[i].x) << i;
      ASSERT_EQ(y, expected[i].y) << i;
      ASSERT_EQ(z, expected[i].z) << i;
      ASSERT_EQ(w, expected[i].weight) << i;
    }
    expect_same_records(expected, *run);
  }
}

// The final merge split between two threads at one key: many records share a key (all of them
// must land on one side: the split key is a run's middle key, here that cell's), duplicates lie
// on both sides (across runs, so the lower half's leave a gap in the output that is closed), in
// one run and in many. Same records, tile index, level counts and duplicate count as the
// single-threaded merge and the reference.
TEST(Subdivide, TwoThreadMergeEqualsOneThreadMerge) {
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<InputPoint> pts;
  for (int i = 0; i < 6000; ++i) {  // spread out, every fourth point given again with another z
    const InputPoint p{0.0414 + 2e-4 * u(rng), 0.3524 + 2e-4 * u(rng), 100 * u(rng), 1};
    pts.push_back(p);
    if (i % 4 == 0) pts.push_back({p.x, p.y, p.z - 1, 2});
  }
  const double cx = 0.04150001, cy = 0.35250001;  // one level-30 cell, ulps apart
  for (int i = 0; i < 8000; ++i) {
    double x = cx, y = cy;
    for (int k = i % 5; k > 0; --k) x = std::nextafter(x, 1.0);
    for (int k = (i / 5) % 5; k > 0; --k) y = std::nextafter(y, 1.0);
    pts.push_back({x, y, 1.0 * (i % 7), static_cast<float>(i % 3)});
  }
  std::shuffle(pts.begin(), pts.end(), rng);
  const auto expected = reference_run(pts);
  for (std::size_t memory : {std::size_t{256} << 20, std::size_t{1}}) {
    std::vector<std::vector<unsigned char>> bytes;
    std::vector<SortedRun> runs;
    for (unsigned threads : {1u, 2u}) {
      TempDir tmp;
      SubdivideOptions opt;
      opt.tmp_dir = tmp.path();
      opt.max_points = 300;
      opt.memory_bytes = memory;
      opt.merge_threads = threads;
      auto run = subdivide(feed_of(pts, 500), opt);
      ASSERT_TRUE(run.ok()) << run.error().message;
      expect_same_records(expected, *run);
      EXPECT_EQ(run->duplicates_merged, pts.size() - expected.size()) << memory << " " << threads;
      std::ifstream in(run->path, std::ios::binary);
      bytes.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      EXPECT_EQ(tmp.entries(), 1u);
      runs.push_back(std::move(*run));
    }
    EXPECT_EQ(bytes[0], bytes[1]) << memory;
    EXPECT_EQ(runs[0].max_tile_points, runs[1].max_tile_points) << memory;
    EXPECT_EQ(runs[0].finest_level, runs[1].finest_level) << memory;
    ASSERT_EQ(runs[0].tiles.size(), runs[1].tiles.size()) << memory;
    for (std::size_t t = 0; t < runs[0].tiles.size(); ++t) {
      EXPECT_EQ(runs[0].tiles[t].id, runs[1].tiles[t].id) << memory << " " << t;
      EXPECT_EQ(runs[0].tiles[t].first, runs[1].tiles[t].first) << memory << " " << t;
      EXPECT_EQ(runs[0].tiles[t].count, runs[1].tiles[t].count) << memory << " " << t;
    }
  }
}

}  // namespace
}  // namespace tinstream::subdivide
