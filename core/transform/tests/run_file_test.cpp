#include "tinstream/transform/run_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>

#include "tinstream/base/fault.hpp"
#include "tinstream/transform/pass1.hpp"

namespace tinstream::transform {
namespace {

const std::filesystem::path kData = TINSTREAM_SHARED_DATA;

std::filesystem::path scratch(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("tinstream_transform_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::size_t files_in(const std::filesystem::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

std::vector<unsigned char> slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<unsigned char>(std::istreambuf_iterator<char>(in), {});
}

TEST(RunFile, RecordLayoutIsLittleEndianAndFixed) {
  unsigned char rec[kRunRecordBytes];
  encode_run_point(RunPoint{1.0, -2.0, 0.5, 2.0f, 0x1234, 9}, rec);
  // 1.0 = 0x3FF0000000000000, -2.0 = 0xC000000000000000, 0.5 = 0x3FE0…, 2.0f = 0x40000000.
  const unsigned char expected[kRunRecordBytes] = {
      0, 0, 0, 0, 0, 0, 0xF0, 0x3F, 0, 0, 0, 0,    0,    0,    0, 0xC0,
      0, 0, 0, 0, 0, 0, 0xE0, 0x3F, 0, 0, 0, 0x40, 0x34, 0x12, 9, 0};
  EXPECT_EQ(std::memcmp(rec, expected, kRunRecordBytes), 0);
  const RunPoint back = decode_run_point(rec);
  EXPECT_EQ(back.x, 1.0);
  EXPECT_EQ(back.y, -2.0);
  EXPECT_EQ(back.z, 0.5);
  EXPECT_EQ(back.weight, 2.0f);
  EXPECT_EQ(back.input, 0x1234);
  EXPECT_EQ(back.classification, 9);
}

TEST(RunFile, WriteCommitReadRoundTrip) {
  auto dir = scratch("roundtrip");
  const auto path = dir / "points.run";
  auto w = RunFileWriter::create(path, geo::Projection::ellipsoidal, 2);
  ASSERT_TRUE(w.ok()) << w.error().message;
  std::vector<RunPoint> pts;
  std::vector<geo::LonLat> ll;
  for (int i = 0; i < 20000; ++i) {
    pts.push_back(RunPoint{-0.5 + i * 1e-5, 0.25 - i * 1e-6, 100.0 + i * 0.001, 1.5f,
                           static_cast<std::uint16_t>(i % 2), static_cast<std::uint8_t>(i % 7)});
    ll.push_back(geo::LonLat{-90 + i * 1e-3, 10 + i * 1e-4});
  }
  ASSERT_TRUE(w->append(std::span(pts).first(12345), std::span(ll).first(12345)).ok());
  ASSERT_TRUE(w->append(std::span(pts).subspan(12345), std::span(ll).subspan(12345)).ok());
  EXPECT_FALSE(std::filesystem::exists(path)) << "visible before commit";
  auto h = w->commit();
  ASSERT_TRUE(h.ok()) << h.error().message;
  EXPECT_TRUE(std::filesystem::exists(path));
  EXPECT_EQ(files_in(dir), 1u);  // the partial file was renamed, not copied
  EXPECT_EQ(std::filesystem::file_size(path), 128u + 32u * 20000u);

  auto r = RunFileReader::open(path);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->header().point_count, 20000u);
  EXPECT_EQ(r->header().projection, geo::Projection::ellipsoidal);
  EXPECT_EQ(r->header().input_count, 2u);
  EXPECT_EQ(r->header().mercator.min_x, -0.5);
  EXPECT_EQ(r->header().mercator.max_x, -0.5 + 19999 * 1e-5);
  EXPECT_EQ(r->header().mercator.max_y, 0.25);
  EXPECT_EQ(r->header().min_z, 100.0);
  EXPECT_EQ(r->header().lonlat.min_x, -90);
  EXPECT_EQ(r->header().lonlat.max_y, 10 + 19999 * 1e-4);
  std::vector<RunPoint> back;
  while (true) {
    auto n = r->read(back, 3000);
    ASSERT_TRUE(n.ok());
    if (*n == 0) break;
  }
  ASSERT_EQ(back.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(back[i].x, pts[i].x);
    ASSERT_EQ(back[i].y, pts[i].y);
    ASSERT_EQ(back[i].z, pts[i].z);
    ASSERT_EQ(back[i].input, pts[i].input);
    ASSERT_EQ(back[i].classification, pts[i].classification);
  }
  ASSERT_TRUE(r->rewind().ok());
  std::vector<RunPoint> again;
  ASSERT_TRUE(r->read(again, 1).ok());
  EXPECT_EQ(again[0].x, pts[0].x);
  std::filesystem::remove_all(dir);
}

TEST(RunFile, AbandonedWriterLeavesNothing) {
  auto dir = scratch("abandon");
  const auto path = dir / "points.run";
  {
    auto w = RunFileWriter::create(path, geo::Projection::spherical, 1);
    ASSERT_TRUE(w.ok());
    std::vector<RunPoint> pts(100);
    ASSERT_TRUE(w->append(pts, {}).ok());
    EXPECT_TRUE(std::filesystem::exists(w->partial_path()));
    EXPECT_FALSE(std::filesystem::exists(path));
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_EQ(files_in(dir), 0u);
  std::filesystem::remove_all(dir);
}

TEST(RunFile, ReaderRefusesIncompleteTruncatedAndForeignFiles) {
  auto dir = scratch("refuse");
  const auto path = dir / "points.run";
  auto w = RunFileWriter::create(path, geo::Projection::spherical, 1);
  ASSERT_TRUE(w.ok());
  std::vector<RunPoint> pts(10);
  ASSERT_TRUE(w->append(pts, {}).ok());
  // A copy of the partial file taken mid-write (as a crash would leave it) is refused.
  std::fflush(nullptr);
  auto partial_copy = dir / "crashed.run";
  ASSERT_TRUE(w->commit().ok());
  auto bytes = slurp(path);
  auto incomplete = bytes;
  incomplete[25] = 0;
  std::ofstream(partial_copy, std::ios::binary)
      .write(reinterpret_cast<const char*>(incomplete.data()),
             static_cast<std::streamsize>(incomplete.size()));
  auto r1 = RunFileReader::open(partial_copy);
  ASSERT_FALSE(r1.ok());
  EXPECT_NE(r1.error().message.find("incomplete"), std::string::npos);

  auto truncated = dir / "truncated.run";
  std::ofstream(truncated, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size() - 5));
  auto r2 = RunFileReader::open(truncated);
  ASSERT_FALSE(r2.ok());
  EXPECT_NE(r2.error().message.find("says 10 points"), std::string::npos) << r2.error().message;

  auto foreign = dir / "foreign.run";
  std::ofstream(foreign) << std::string(200, 'x');
  auto r3 = RunFileReader::open(foreign);
  ASSERT_FALSE(r3.ok());
  EXPECT_NE(r3.error().message.find("magic"), std::string::npos);

  auto r4 = RunFileReader::open(dir / "absent.run");
  ASSERT_FALSE(r4.ok());
  EXPECT_EQ(r4.error().code, ErrorCode::not_found);
  std::filesystem::remove_all(dir);
}

// ---- pass 1 -------------------------------------------------------------------------------

bool have(const char* name) { return std::filesystem::exists(kData / name); }

TEST(Pass1, MixedInputsGiveCountsBoxesAndAReadableRun) {
  if (!have("autzen_trim.las") || !have("luxembourg_elev.tif")) GTEST_SKIP() << "missing data";
  auto dir = scratch("mixed");
  std::vector<InputSpec> inputs(2);
  inputs[0].path = kData / "autzen_trim.las";
  inputs[1].path = kData / "luxembourg_elev.tif";
  inputs[1].weight = 2.0f;
  TransformOptions opt;
  opt.output = dir / "pass1.run";
  opt.batch_size = 5000;
  std::vector<Progress> seen;
  bool visible_early = false;
  auto sink = [&](const Progress& p) {
    seen.push_back(p);
    if (std::filesystem::exists(opt.output)) visible_early = true;
    return true;
  };
  auto s = transform_sources(inputs, opt, sink);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_FALSE(visible_early) << "the run file was visible under its final name mid-run";
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

  auto r = RunFileReader::open(opt.output);
  ASSERT_TRUE(r.ok()) << r.error().message;
  std::vector<RunPoint> pts;
  while (true) {
    auto n = r->read(pts, 7000);
    ASSERT_TRUE(n.ok());
    if (*n == 0) break;
  }
  ASSERT_EQ(pts.size(), 30715u);
  const geo::NormalisedMercator merc(geo::Projection::spherical);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto ll = merc.inverse(geo::MercatorXY{pts[i].x, pts[i].y});
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
  EXPECT_EQ(files_in(dir), 1u);
  std::filesystem::remove_all(dir);
}

TEST(Pass1, AFailingInputLeavesNoRunFileAndNamesTheLine) {
  if (!have("luxembourg_elev.tif")) GTEST_SKIP() << "missing data";
  auto dir = scratch("failing");
  const auto bad = dir / "bad.xyz";
  std::ofstream(bad) << "6.0 49.5 300\n6.1 49.6 oops\n";
  std::vector<InputSpec> inputs(2);
  inputs[0].path = kData / "luxembourg_elev.tif";
  inputs[1].path = bad;
  inputs[1].reproject.crs = "EPSG:4326";
  TransformOptions opt;
  opt.output = dir / "pass1.run";
  auto s = transform_sources(inputs, opt);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find(bad.string() + ": line 2"), std::string::npos)
      << s.error().message;
  EXPECT_FALSE(std::filesystem::exists(opt.output));
  EXPECT_EQ(files_in(dir), 1u);  // only bad.xyz: no partial file left
  std::filesystem::remove_all(dir);
}

TEST(Pass1, CancelLeavesNothing) {
  if (!have("N00E010.hgt")) GTEST_SKIP() << "missing data";
  auto dir = scratch("cancel");
  std::vector<InputSpec> inputs(1);
  inputs[0].path = kData / "N00E010.hgt";
  TransformOptions opt;
  opt.output = dir / "pass1.run";
  opt.batch_size = 1000;
  int calls = 0;
  auto s = transform_sources(inputs, opt, [&](const Progress&) { return ++calls < 1; });
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::cancelled);
  EXPECT_FALSE(std::filesystem::exists(opt.output));
  EXPECT_EQ(files_in(dir), 0u);
  std::filesystem::remove_all(dir);
}

TEST(Pass1, EsriAsciiNeedsACrsAndWorksWithOne) {
  if (!have("boulder_srtmgl3.asc")) GTEST_SKIP() << "missing data";
  auto dir = scratch("ascii");
  std::vector<InputSpec> inputs(1);
  inputs[0].path = kData / "boulder_srtmgl3.asc";
  TransformOptions opt;
  opt.output = dir / "pass1.run";
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
  std::filesystem::remove_all(dir);
}

TEST(Pass1, LatitudeOutsideTheMercatorSquareNamesTheRecord) {
  auto dir = scratch("polar");
  const auto polar = dir / "polar.xyz";
  std::ofstream(polar) << "10 60 1\n10 85.04 2\n10 85.06 3\n10 -89 4\n";
  std::vector<InputSpec> inputs(1);
  inputs[0].path = polar;
  inputs[0].reproject.crs = "EPSG:4326";
  TransformOptions opt;
  opt.output = dir / "pass1.run";
  auto s = transform_sources(inputs, opt);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("record 3"), std::string::npos) << s.error().message;
  EXPECT_FALSE(std::filesystem::exists(opt.output));
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

// Points in UTM 32N around (500 km, 5 000 km); `bad` lines get a northing far beyond the pole's
// latitude limit (outside the Mercator square).
std::filesystem::path utm_points(const std::filesystem::path& dir, int n,
                                 const std::vector<int>& bad = {}) {
  const auto path = dir / "utm.xyz";
  std::ofstream out(path);
  for (int i = 1; i <= n; ++i) {
    const bool is_bad = std::find(bad.begin(), bad.end(), i) != bad.end();
    out << 500000.0 + (i * 7919 % 1000) * 0.37 << ' '
        << (is_bad ? 9'600'000.0 : 5'000'000.0 + (i * 104729 % 1000) * 0.41) << ' '
        << 100.0 + i * 0.001 << '\n';
  }
  return path;
}

TEST(Pass1, HelperThreadWritesTheSameRunFile) {
  auto dir = scratch("helper");
  std::vector<InputSpec> inputs(2);
  inputs[0].path = utm_points(dir, 10'007);
  inputs[0].reproject.crs = "EPSG:32632";
  inputs[1] = inputs[0];  // a second input: the helper's reprojector is made per input
  inputs[1].weight = 3;
  TransformOptions opt;
  opt.batch_size = 1000;  // 11 batches per input: an odd one out at the end
  opt.output = dir / "one.run";
  auto one = transform_sources(inputs, opt);
  ASSERT_TRUE(one.ok()) << one.error().message;
  opt.output = dir / "two.run";
  opt.threads = 2;
  auto two = transform_sources(inputs, opt);
  ASSERT_TRUE(two.ok()) << two.error().message;
  EXPECT_EQ(two->header.point_count, 20'014u);
  EXPECT_EQ(slurp(dir / "one.run"), slurp(dir / "two.run"));
  std::filesystem::remove_all(dir);
}

TEST(Pass1, HelperThreadReportsTheFirstBadRecordInFileOrder) {
  auto dir = scratch("helper_bad");
  std::vector<InputSpec> inputs(1);
  inputs[0].reproject.crs = "EPSG:32632";
  TransformOptions opt;
  opt.batch_size = 1000;
  opt.threads = 2;
  opt.output = dir / "out.run";
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
  EXPECT_FALSE(std::filesystem::exists(opt.output));
  // Skipped instead, both are counted.
  inputs[0].path = utm_points(dir, 3000, {700, 1500, 2999});
  inputs[0].source.invalid = sources::InvalidPolicy::skip;
  auto skipped = transform_sources(inputs, opt);
  ASSERT_TRUE(skipped.ok()) << skipped.error().message;
  EXPECT_EQ(skipped->inputs[0].outside_mercator, 3u);
  EXPECT_EQ(skipped->header.point_count, 2997u);
  std::filesystem::remove_all(dir);
}

// The points handed to on_points are the run file's, in its order, whatever the worker count;
// an error from on_points stops the pass and leaves no run file.
TEST(Pass1, WorkersHandEveryBatchOverInRecordOrder) {
  auto dir = scratch("on_points");
  std::vector<InputSpec> inputs(2);
  inputs[0].path = utm_points(dir, 7'003);
  inputs[0].reproject.crs = "EPSG:32632";
  inputs[1] = inputs[0];
  inputs[1].weight = 2;
  TransformOptions opt;
  opt.batch_size = 500;
  std::vector<unsigned char> first_run;
  for (unsigned threads : {1u, 2u, 3u}) {
    opt.threads = threads;
    opt.output = dir / ("t" + std::to_string(threads) + ".run");
    std::vector<RunPoint> handed;
    opt.on_points = [&](std::span<const RunPoint> points) -> Status {
      handed.insert(handed.end(), points.begin(), points.end());
      return {};
    };
    auto s = transform_sources(inputs, opt);
    ASSERT_TRUE(s.ok()) << s.error().message;
    auto reader = RunFileReader::open(opt.output);
    ASSERT_TRUE(reader.ok());
    std::vector<RunPoint> stored;
    while (true) {
      auto n = reader->read(stored, 4096);
      ASSERT_TRUE(n.ok());
      if (*n == 0) break;
    }
    ASSERT_EQ(handed.size(), 14'006u) << threads;
    ASSERT_EQ(stored.size(), handed.size()) << threads;
    for (std::size_t i = 0; i < handed.size(); ++i) {
      ASSERT_EQ(handed[i].x, stored[i].x) << threads << " " << i;
      ASSERT_EQ(handed[i].y, stored[i].y) << threads << " " << i;
      ASSERT_EQ(handed[i].z, stored[i].z) << threads << " " << i;
      ASSERT_EQ(handed[i].weight, stored[i].weight) << threads << " " << i;
    }
    if (first_run.empty()) {
      first_run = slurp(opt.output);
    } else {
      EXPECT_EQ(slurp(opt.output), first_run) << threads;
    }
  }
  std::size_t calls = 0;
  opt.output = dir / "stopped.run";
  opt.on_points = [&](std::span<const RunPoint>) -> Status {
    if (++calls == 5) return Error(ErrorCode::io_error, "pass 2 is full");
    return {};
  };
  auto stopped = transform_sources(inputs, opt);
  ASSERT_FALSE(stopped.ok());
  EXPECT_EQ(stopped.error().message, "pass 2 is full");
  EXPECT_EQ(calls, 5u);
  EXPECT_FALSE(std::filesystem::exists(opt.output));
  std::filesystem::remove_all(dir);
}

// Without a run file path (the ingest's way) nothing is written, the same points are handed over
// and the header is the one a run file would have had.
TEST(Pass1, WithoutARunFileThePointsAndHeaderAreTheSame) {
  auto dir = scratch("no_run_file");
  std::vector<InputSpec> inputs(2);
  inputs[0].path = utm_points(dir, 5'001);
  inputs[0].reproject.crs = "EPSG:32632";
  inputs[1] = inputs[0];
  inputs[1].weight = 3;
  TransformOptions opt;
  opt.batch_size = 700;
  opt.threads = 2;
  std::vector<RunPoint> with_file, without_file;
  auto collect = [](std::vector<RunPoint>& into) {
    return [&into](std::span<const RunPoint> points) -> Status {
      into.insert(into.end(), points.begin(), points.end());
      return {};
    };
  };
  opt.output = dir / "with.run";
  opt.on_points = collect(with_file);
  auto a = transform_sources(inputs, opt);
  ASSERT_TRUE(a.ok()) << a.error().message;
  std::filesystem::remove(opt.output);
  const std::size_t files_before = files_in(dir);

  opt.output.clear();
  opt.on_points = collect(without_file);
  auto b = transform_sources(inputs, opt);
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_EQ(files_in(dir), files_before) << "a file was written without a run file path";
  EXPECT_TRUE(b->run_file.empty());
  unsigned char ha[kRunHeaderBytes], hb[kRunHeaderBytes];
  encode_run_header(a->header, true, ha);
  encode_run_header(b->header, true, hb);
  EXPECT_EQ(std::memcmp(ha, hb, kRunHeaderBytes), 0);
  EXPECT_EQ(b->header.point_count, 10'002u);
  EXPECT_EQ(b->header.input_count, 2u);
  EXPECT_LT(b->header.mercator.min_x, b->header.mercator.max_x);
  ASSERT_EQ(without_file.size(), with_file.size());
  for (std::size_t i = 0; i < with_file.size(); ++i) {
    ASSERT_EQ(without_file[i].x, with_file[i].x) << i;
    ASSERT_EQ(without_file[i].z, with_file[i].z) << i;
    ASSERT_EQ(without_file[i].weight, with_file[i].weight) << i;
  }
  ASSERT_EQ(b->inputs.size(), 2u);
  EXPECT_EQ(b->inputs[1].points_written, 5'001u);

  // With neither a run file nor a consumer there is nothing to do: refused.
  opt.on_points = nullptr;
  auto c = transform_sources(inputs, opt);
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.error().code, ErrorCode::invalid_argument);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace tinstream::transform

namespace tinstream::transform {
namespace {

// #22: heights far outside the Earth's range (an undeclared NODATA of -3.4e38, a z unit wrong by
// 10^6) were accepted as terrain and published. They are errors naming the record, or invalid
// records under --skip-invalid.
TEST(Pass1, HeightsOutsideTheEarthsRangeAreRejectedOrCountedInvalid) {
  auto dir = scratch("heights");
  const auto path = dir / "h.xyz";
  std::ofstream(path) << "8.5 47.4 420\n8.6 47.4 -3.4e38\n8.5 47.5 100001\n8.6 47.5 -100000\n"
                      << "8.55 47.45 8848\n";
  std::vector<InputSpec> inputs(1);
  inputs[0].path = path;
  inputs[0].reproject.crs = "EPSG:4326";
  TransformOptions opt;
  opt.output = dir / "h.run";
  for (unsigned threads : {1u, 2u}) {
    opt.threads = threads;
    auto s = transform_sources(inputs, opt);
    ASSERT_FALSE(s.ok()) << threads;
    EXPECT_EQ(s.error().code, ErrorCode::corrupt_data);
    EXPECT_NE(s.error().message.find("record 2: height"), std::string::npos) << s.error().message;
    EXPECT_NE(s.error().message.find("outside the Earth's range"), std::string::npos);
    EXPECT_NE(s.error().message.find("--skip-invalid"), std::string::npos);
    EXPECT_FALSE(std::filesystem::exists(opt.output));
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
  TransformOptions opt;
  opt.batch_size = 500;
  opt.output = dir / "out.run";
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
    EXPECT_FALSE(std::filesystem::exists(opt.output));
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
