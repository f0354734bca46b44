#include "tinstream/transform/pass1.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "tinstream/base/fault.hpp"

namespace tinstream::transform {
namespace {

const std::filesystem::path kPass1Data = TINSTREAM_SHARED_DATA;

std::filesystem::path scratch(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("tinstream_transform_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Collects every point handed on, in order.
struct Collector {
  std::vector<RunPoint> points;
  std::function<Status(std::span<const RunPoint>)> sink() {
    return [this](std::span<const RunPoint> batch) -> Status {
      points.insert(points.end(), batch.begin(), batch.end());
      return {};
    };
  }
};

// Options handing the points to nowhere (the tests that look only at counts and errors).
TransformOptions discarding() {
  TransformOptions opt;
  opt.on_points = [](std::span<const RunPoint>) -> Status { return {}; };
  return opt;
}

void expect_same_points(const std::vector<RunPoint>& a, const std::vector<RunPoint>& b,
                        const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].x, b[i].x) << what << " " << i;
    ASSERT_EQ(a[i].y, b[i].y) << what << " " << i;
    ASSERT_EQ(a[i].z, b[i].z) << what << " " << i;
    ASSERT_EQ(a[i].weight, b[i].weight) << what << " " << i;
    ASSERT_EQ(a[i].input, b[i].input) << what << " " << i;
    ASSERT_EQ(a[i].classification, b[i].classification) << what << " " << i;
  }
}

// ---- pass 1 -------------------------------------------------------------------------------

bool have(const char* name) { return std::filesystem::exists(kPass1Data / name); }

TEST(Pass1, MixedInputsGiveCountsBoxesAndTheirPoints) {
  if (!have("autzen_trim.las") || !have("luxembourg_elev.tif")) GTEST_SKIP() << "missing data";
  std::vector<InputSpec> inputs(2);
  inputs[0].path = kPass1Data / "autzen_trim.las";
  inputs[1].path = kPass1Data / "luxembourg_elev.tif";
  inputs[1].weight = 2.0f;
  TransformOptions opt;
  Collector handed;
  opt.on_points = handed.sink();
  opt.batch_size = 5000;
  std::vector<Progress> seen;
  auto sink = [&](const Progress& p) {
    seen.push_back(p);
    return true;
  };
  auto s = transform_sources(inputs, opt, sink);
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(s->inputs.size(), 2u);
  const auto& a = s->inputs[0];
  EXPECT_EQ(a.counters.records_read, 110000u);
  EXPECT_EQ(a.counters.rejected_class, 83893u);
  EXPECT_EQ(a.points_written, 26107u);
  const auto& l = s->inputs[1];
  EXPECT_EQ(l.counters.records_read, 8550u);
  EXPECT_EQ(l.counters.rejected_nodata, 3942u);
  EXPECT_EQ(l.points_written, 4608u);
  EXPECT_EQ(s->header.point_count, 26107u + 4608u);
  EXPECT_EQ(s->header.input_count, 2u);
  // Boxes from SOURCES.md: Eugene (-123.07, 44.05) and Luxembourg (5.74–6.53, 49.44–50.19).
  EXPECT_NEAR(s->header.lonlat.min_x, -123.0734, 2e-4);
  EXPECT_LT(s->header.lonlat.max_x, 6.533333);
  EXPECT_GT(s->header.lonlat.max_x, 6.5);
  EXPECT_NEAR(s->header.lonlat.min_y, 44.0499, 2e-4);
  EXPECT_LT(s->header.lonlat.max_y, 50.191667);
  EXPECT_NEAR(s->header.min_z, 406.26 * 0.3048, 0.005);
  EXPECT_LE(s->header.max_z, 547);
  EXPECT_GE(s->header.max_z, 500);
  // Mercator x = lon / 180.
  EXPECT_NEAR(s->header.mercator.min_x, -123.0734 / 180, 2e-4 / 180);
  // Progress: ends with done == total == all records.
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back().phase, "transform");
  EXPECT_EQ(seen.back().done, 118550u);
  EXPECT_EQ(seen.back().total, 118550u);

  // Every accepted point was handed on, the first input's first, each with its input's tag.
  const auto& pts = handed.points;
  ASSERT_EQ(pts.size(), 30715u);
  const geo::NormalisedMercator merc(geo::Projection::spherical);
  double min_x = std::numeric_limits<double>::infinity(), max_z = -min_x;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto ll = merc.inverse(geo::MercatorXY{pts[i].x, pts[i].y});
    min_x = std::min(min_x, pts[i].x);
    max_z = std::max(max_z, pts[i].z);
    if (i < 26107) {
      ASSERT_EQ(pts[i].input, 0);
      ASSERT_EQ(pts[i].classification, 2);
      ASSERT_EQ(pts[i].weight, 1.0f);
      ASSERT_NEAR(ll.lon, -123.0712, 0.003);
      ASSERT_NEAR(ll.lat, 44.0507, 0.002);
    } else {
      ASSERT_EQ(pts[i].input, 1);
      ASSERT_EQ(pts[i].weight, 2.0f);
      ASSERT_GT(ll.lon, 5.741667);
      ASSERT_LT(ll.lat, 50.191667);
      ASSERT_GE(pts[i].z, 141);
      ASSERT_LE(pts[i].z, 547);
    }
  }
  // The header describes the points handed on.
  EXPECT_EQ(s->header.mercator.min_x, min_x);
  EXPECT_EQ(s->header.max_z, max_z);
}

TEST(Pass1, AFailingInputNamesTheLine) {
  if (!have("luxembourg_elev.tif")) GTEST_SKIP() << "missing data";
  auto dir = scratch("failing");
  const auto bad = dir / "bad.xyz";
  std::ofstream(bad) << "6.0 49.5 300\n6.1 49.6 oops\n";
  std::vector<InputSpec> inputs(2);
  inputs[0].path = kPass1Data / "luxembourg_elev.tif";
  inputs[1].path = bad;
  inputs[1].reproject.crs = "EPSG:4326";
  auto s = transform_sources(inputs, discarding());
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find(bad.string() + ": line 2"), std::string::npos)
      << s.error().message;
  std::filesystem::remove_all(dir);
}

TEST(Pass1, CancelStopsThePass) {
  if (!have("N00E010.hgt")) GTEST_SKIP() << "missing data";
  std::vector<InputSpec> inputs(1);
  inputs[0].path = kPass1Data / "N00E010.hgt";
  TransformOptions opt;
  Collector handed;
  opt.on_points = handed.sink();
  opt.batch_size = 1000;
  int calls = 0;
  auto s = transform_sources(inputs, opt, [&](const Progress&) { return ++calls < 1; });
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::cancelled);
  EXPECT_EQ(calls, 1);
  EXPECT_LE(handed.points.size(), 1000u);  // stopped at the first progress report
}

TEST(Pass1, EsriAsciiNeedsACrsAndWorksWithOne) {
  if (!have("boulder_srtmgl3.asc")) GTEST_SKIP() << "missing data";
  std::vector<InputSpec> inputs(1);
  inputs[0].path = kPass1Data / "boulder_srtmgl3.asc";
  const TransformOptions opt = discarding();
  auto s = transform_sources(inputs, opt);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("--crs"), std::string::npos);
  inputs[0].reproject.crs = "EPSG:4326";
  auto ok = transform_sources(inputs, opt);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(ok->header.point_count, 240u * 144u);
  EXPECT_EQ(ok->header.min_z, 1943);
  EXPECT_EQ(ok->header.max_z, 3286);
  EXPECT_NEAR(ok->header.lonlat.min_x, -105.55, 0.001);
  EXPECT_NEAR(ok->header.lonlat.max_y, 40.21, 0.001);
}

// One input: an XYZ file in `dir` holding `text` (lon lat h lines, EPSG:4326).
std::vector<InputSpec> lonlat_xyz(const std::filesystem::path& dir, const std::string& text) {
  const auto path = dir / "lonlat.xyz";
  std::ofstream(path) << text;
  std::vector<InputSpec> inputs(1);
  inputs[0].path = path;
  inputs[0].reproject.crs = "EPSG:4326";
  return inputs;
}

TEST(Pass1, LatitudeOutsideTheMercatorSquareNamesTheRecord) {
  auto dir = scratch("polar");
  std::vector<InputSpec> inputs = lonlat_xyz(dir, "10 60 1\n10 85.04 2\n10 85.06 3\n10 -89 4\n");
  TransformOptions opt = discarding();
  auto s = transform_sources(inputs, opt);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("record 3"), std::string::npos) << s.error().message;
  // The ellipsoidal projection reaches 85.0841°, so 85.06 fits there; -89 never does.
  inputs[0].source.invalid = sources::InvalidPolicy::skip;
  opt.projection = geo::Projection::ellipsoidal;
  auto skipped = transform_sources(inputs, opt);
  ASSERT_TRUE(skipped.ok()) << skipped.error().message;
  EXPECT_EQ(skipped->header.point_count, 3u);
  EXPECT_EQ(skipped->inputs[0].outside_mercator, 1u);
  EXPECT_EQ(skipped->inputs[0].counters.rejected_invalid, 1u);
  EXPECT_EQ(skipped->header.projection, geo::Projection::ellipsoidal);
  std::filesystem::remove_all(dir);
}

// With every record skipped nothing is handed on and the header's boxes and z range are empty.
TEST(Pass1, NoPointLeftGivesAnEmptyHeader) {
  auto dir = scratch("none_left");
  std::vector<InputSpec> inputs = lonlat_xyz(dir, "10 86 1\n10 -89 2\n");
  inputs[0].source.invalid = sources::InvalidPolicy::skip;
  TransformOptions opt;
  Collector handed;
  opt.on_points = handed.sink();
  auto s = transform_sources(inputs, opt);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_TRUE(handed.points.empty());
  EXPECT_EQ(s->header.point_count, 0u);
  EXPECT_EQ(s->header.input_count, 1u);
  EXPECT_EQ(s->inputs[0].outside_mercator, 2u);
  EXPECT_TRUE(s->header.mercator.empty());
  EXPECT_TRUE(s->header.lonlat.empty());
  EXPECT_GT(s->header.min_z, s->header.max_z);
  std::filesystem::remove_all(dir);
}

// Points in UTM 32N around (500 km, 5 000 km); `bad` lines get a northing far beyond the pole's
// latitude limit (outside the Mercator square).
std::filesystem::path utm_points(const std::filesystem::path& dir, int n,
                                 const std::vector<int>& bad = {}) {
  auto path = dir / "utm.xyz";
  std::ofstream out(path);
  for (int i = 1; i <= n; ++i) {
    const bool is_bad = std::find(bad.begin(), bad.end(), i) != bad.end();
    out << 500000.0 + (i * 7919 % 1000) * 0.37 << ' '
        << (is_bad ? 9'600'000.0 : 5'000'000.0 + (i * 104729 % 1000) * 0.41) << ' '
        << 100.0 + i * 0.001 << '\n';
  }
  return path;
}

TEST(Pass1, HelperThreadHandsOnTheSamePointsAndHeader) {
  auto dir = scratch("helper");
  std::vector<InputSpec> inputs(2);
  inputs[0].path = utm_points(dir, 10'007);
  inputs[0].reproject.crs = "EPSG:32632";
  inputs[1] = inputs[0];  // a second input: the helper's reprojector is made per input
  inputs[1].weight = 3;
  TransformOptions opt;
  opt.batch_size = 1000;  // 11 batches per input: an odd one out at the end
  Collector one_handed, two_handed;
  opt.on_points = one_handed.sink();
  auto one = transform_sources(inputs, opt);
  ASSERT_TRUE(one.ok()) << one.error().message;
  opt.on_points = two_handed.sink();
  opt.threads = 2;
  auto two = transform_sources(inputs, opt);
  ASSERT_TRUE(two.ok()) << two.error().message;
  EXPECT_EQ(two->header.point_count, 20'014u);
  expect_same_points(one_handed.points, two_handed.points, "1 vs 2 threads");
  EXPECT_EQ(one->header.mercator.min_x, two->header.mercator.min_x);
  EXPECT_EQ(one->header.mercator.max_y, two->header.mercator.max_y);
  EXPECT_EQ(one->header.lonlat.max_x, two->header.lonlat.max_x);
  EXPECT_EQ(one->header.min_z, two->header.min_z);
  EXPECT_EQ(one->header.max_z, two->header.max_z);
  std::filesystem::remove_all(dir);
}

TEST(Pass1, HelperThreadReportsTheFirstBadRecordInFileOrder) {
  auto dir = scratch("helper_bad");
  std::vector<InputSpec> inputs(1);
  inputs[0].reproject.crs = "EPSG:32632";
  TransformOptions opt = discarding();
  opt.batch_size = 1000;
  opt.threads = 2;
  // Record 1500 is in the batch this thread transforms, record 700 in the helper's (earlier).
  inputs[0].path = utm_points(dir, 3000, {700, 1500});
  auto both = transform_sources(inputs, opt);
  ASSERT_FALSE(both.ok());
  EXPECT_NE(both.error().message.find("record 700:"), std::string::npos) << both.error().message;
  // Only a bad record in this thread's batch.
  inputs[0].path = utm_points(dir, 3000, {1500});
  auto second = transform_sources(inputs, opt);
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.error().message.find("record 1500:"), std::string::npos)
      << second.error().message;
  // Skipped instead, both are counted.
  inputs[0].path = utm_points(dir, 3000, {700, 1500, 2999});
  inputs[0].source.invalid = sources::InvalidPolicy::skip;
  auto skipped = transform_sources(inputs, opt);
  ASSERT_TRUE(skipped.ok()) << skipped.error().message;
  EXPECT_EQ(skipped->inputs[0].outside_mercator, 3u);
  EXPECT_EQ(skipped->header.point_count, 2997u);
  std::filesystem::remove_all(dir);
}

// The points handed to on_points are the same, in the same order, whatever the worker count; an
// error from on_points stops the pass; without on_points the pass is refused.
TEST(Pass1, WorkersHandEveryBatchOverInRecordOrder) {
  auto dir = scratch("on_points");
  std::vector<InputSpec> inputs(2);
  inputs[0].path = utm_points(dir, 7'003);
  inputs[0].reproject.crs = "EPSG:32632";
  inputs[1] = inputs[0];
  inputs[1].weight = 2;
  TransformOptions opt;
  opt.batch_size = 500;
  std::vector<RunPoint> first;
  for (unsigned threads : {1u, 2u, 3u}) {
    opt.threads = threads;
    Collector handed;
    opt.on_points = handed.sink();
    auto s = transform_sources(inputs, opt);
    ASSERT_TRUE(s.ok()) << s.error().message;
    ASSERT_EQ(handed.points.size(), 14'006u) << threads;
    EXPECT_EQ(s->header.point_count, 14'006u) << threads;
    EXPECT_EQ(handed.points[7'003].input, 1) << threads;
    EXPECT_EQ(handed.points[7'003].weight, 2.0f) << threads;
    if (first.empty()) {
      first = handed.points;
    } else {
      expect_same_points(first, handed.points, std::to_string(threads) + " threads");
    }
  }
  std::size_t calls = 0;
  opt.on_points = [&](std::span<const RunPoint>) -> Status {
    if (++calls == 5) return Error(ErrorCode::io_error, "pass 2 is full");
    return {};
  };
  auto stopped = transform_sources(inputs, opt);
  ASSERT_FALSE(stopped.ok());
  EXPECT_EQ(stopped.error().message, "pass 2 is full");
  EXPECT_EQ(calls, 5u);

  opt.on_points = nullptr;
  auto refused = transform_sources(inputs, opt);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::invalid_argument);
  std::filesystem::remove_all(dir);
}

// #22: heights far outside the Earth's range (an undeclared NODATA of -3.4e38, a z unit wrong by
// 10^6) were accepted as terrain and published. They are errors naming the record, or invalid
// records under --skip-invalid.
TEST(Pass1, HeightsOutsideTheEarthsRangeAreRejectedOrCountedInvalid) {
  auto dir = scratch("heights");
  std::vector<InputSpec> inputs = lonlat_xyz(
      dir, "8.5 47.4 420\n8.6 47.4 -3.4e38\n8.5 47.5 100001\n8.6 47.5 -100000\n8.55 47.45 8848\n");
  TransformOptions opt = discarding();
  for (unsigned threads : {1u, 2u}) {
    opt.threads = threads;
    auto s = transform_sources(inputs, opt);
    ASSERT_FALSE(s.ok()) << threads;
    EXPECT_EQ(s.error().code, ErrorCode::corrupt_data);
    EXPECT_NE(s.error().message.find("record 2: height"), std::string::npos) << s.error().message;
    EXPECT_NE(s.error().message.find("outside the Earth's range"), std::string::npos);
    EXPECT_NE(s.error().message.find("--skip-invalid"), std::string::npos);
  }
  inputs[0].source.invalid = sources::InvalidPolicy::skip;
  auto skipped = transform_sources(inputs, opt);
  ASSERT_TRUE(skipped.ok()) << skipped.error().message;
  EXPECT_EQ(skipped->header.point_count, 3u);  // 420, -100000 (the limit itself) and 8848
  EXPECT_EQ(skipped->inputs[0].implausible_height, 2u);
  EXPECT_EQ(skipped->inputs[0].counters.rejected_invalid, 2u);
  EXPECT_EQ(skipped->inputs[0].counters.accepted, 3u);
  EXPECT_EQ(skipped->header.min_z, -100000);
  EXPECT_EQ(skipped->header.max_z, 8848);
  std::filesystem::remove_all(dir);
}

// #22, worker crashes: an exception on a pass-1 worker (or the reading thread) and a worker that
// cannot be started are the pass's Error; before, the first reached std::terminate and the second
// unwound a vector of running threads into it.
TEST(Pass1, AWorkerExceptionAThrowingReaderAndAFailedThreadStartAreErrors) {
  ASSERT_TRUE(fault::enabled()) << "fault points are not compiled into this test build";
  auto dir = scratch("faults");
  std::vector<InputSpec> inputs(1);
  inputs[0].path = utm_points(dir, 5'000);
  inputs[0].reproject.crs = "EPSG:32632";
  TransformOptions opt = discarding();
  opt.batch_size = 500;
  struct Case {
    const char* point;
    std::uint64_t skip;
    fault::Kind kind;
    unsigned threads;
    const char* message;
  };
  const Case cases[] = {
      {"pass1.transform", 3, fault::Kind::throw_error, 3,
       "pass 1 transform: injected fault at pass1.transform"},
      {"pass1.transform", 0, fault::Kind::out_of_memory, 2, "pass 1 transform: out of memory"},
      {"pass1.transform", 2, fault::Kind::throw_error, 1,
       "pass 1 transform: injected fault at pass1.transform"},
      {"pass1.read", 4, fault::Kind::throw_error, 3, "pass 1: injected fault at pass1.read"},
      {"pass1.transform.spawn", 1, fault::Kind::no_thread, 3,
       "pass 1 transform: cannot start a thread"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.point) + " threads " + std::to_string(c.threads));
    opt.threads = c.threads;
    const fault::Arm arm(c.point, c.skip, c.kind);
    auto s = transform_sources(inputs, opt);
    EXPECT_TRUE(arm.fired());
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.error().code, ErrorCode::internal);
    EXPECT_NE(s.error().message.find(c.message), std::string::npos) << s.error().message;
  }
  // Nothing armed: the same input goes through.
  opt.threads = 3;
  auto fine = transform_sources(inputs, opt);
  ASSERT_TRUE(fine.ok()) << fine.error().message;
  EXPECT_EQ(fine->header.point_count, 5'000u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace tinstream::transform
