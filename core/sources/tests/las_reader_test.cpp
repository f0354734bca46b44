#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "las_writer.hpp"
#include "read_all.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {
namespace {

using testing::kData;
using testing::read_all;

using testing::build_las;
using testing::LasSpec;
using testing::TestPoint;
using testing::TestVlr;

std::vector<TestPoint> sample_points() {
  // Classes 1, 2, 7, 18 and 6, with distinct coordinates.
  std::vector<TestPoint> pts;
  const std::uint8_t classes[] = {1, 2, 7, 18, 6, 2, 1};
  pts.reserve(std::size(classes));
  for (int i = 0; i < 7; ++i) {
    pts.push_back(TestPoint{1000 * i - 3000, -250 * i + 17, 31 * i + 5, classes[i], false});
  }
  return pts;
}

class LasFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path write(const std::vector<unsigned char>& bytes,
                              const std::string& name = "t.las") {
    auto p = dir_ / name;
    testing::write_file(p, bytes);
    return p;
  }
  std::filesystem::path dir_;
};

SourceOptions all_classes() {
  SourceOptions o;
  std::vector<std::uint8_t> every(256);
  for (int i = 0; i < 256; ++i) every[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(i);
  o.class_filter.classes = every;
  return o;
}

TEST_F(LasFile, EveryPointFormatAndVersionDecodesCoordinatesAndClasses) {
  for (std::uint8_t minor = 0; minor <= 4; ++minor) {
    for (std::uint8_t format = 0; format <= 10; ++format) {
      SCOPED_TRACE("LAS 1." + std::to_string(minor) + " format " + std::to_string(format));
      LasSpec s;
      s.minor = minor;
      s.format = format;
      s.extra_bytes = format == 3 ? 5 : 0;  // extra bytes after the record must be skipped
      s.points = sample_points();
      auto path = write(build_las(s));
      auto src = open_las(path, all_classes());
      ASSERT_TRUE(src.ok()) << src.error().message;
      EXPECT_EQ((*src)->info().record_count, 7u);
      EXPECT_EQ((*src)->info().format,
                "LAS 1." + std::to_string(minor) + " PDF " + std::to_string(format));
      auto pts = read_all(**src, 3);
      ASSERT_TRUE(pts.ok()) << pts.error().message;
      ASSERT_EQ(pts->size(), 7u);
      for (std::size_t i = 0; i < 7; ++i) {
        const auto& e = s.points[i];
        const auto& p = (*pts)[i];
        // Expected values straight from the integers written: X*0.01+1000 etc.
        EXPECT_DOUBLE_EQ(p.x, e.X * 0.01 + 1000);
        EXPECT_DOUBLE_EQ(p.y, e.Y * 0.01 + 2000);
        EXPECT_DOUBLE_EQ(p.z, e.Z * 0.01);
        EXPECT_EQ(p.classification, e.cls);
        EXPECT_EQ(p.record, i + 1);
      }
      EXPECT_EQ((*src)->counters().records_read, 7u);
      EXPECT_EQ((*src)->counters().accepted, 7u);
    }
  }
}

TEST_F(LasFile, DefaultFilterKeepsOnlyGroundWhenTheFileHasGround) {
  LasSpec s;
  s.format = 1;
  s.points = sample_points();  // classes 1 2 7 18 6 2 1
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok()) << src.error().message;
  auto pts = read_all(**src, 1000);
  ASSERT_TRUE(pts.ok());
  ASSERT_EQ(pts->size(), 2u);
  EXPECT_EQ((*pts)[0].record, 2u);
  EXPECT_EQ((*pts)[1].record, 6u);
  EXPECT_EQ((*src)->counters().rejected_class, 5u);
}

TEST_F(LasFile, DefaultFilterDropsNoiseWhenTheFileHasNoGround) {
  LasSpec s;
  s.format = 6;
  s.minor = 4;
  s.points = sample_points();
  for (auto& p : s.points) {
    if (p.cls == 2) p.cls = 9;
  }  // classes 1 9 7 18 6 9 1
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok()) << src.error().message;
  auto pts = read_all(**src, 1000);
  ASSERT_TRUE(pts.ok());
  std::multiset<int> classes;
  for (const auto& p : *pts) classes.insert(p.classification);
  EXPECT_EQ(classes, (std::multiset<int>{1, 1, 6, 9, 9}));
  EXPECT_EQ((*src)->counters().rejected_class, 2u);
}

TEST_F(LasFile, ExplicitClassListOverridesTheDefault) {
  LasSpec s;
  s.format = 0;
  s.points = sample_points();
  SourceOptions o;
  o.class_filter.classes = std::vector<std::uint8_t>{1, 7};
  auto src = open_las(write(build_las(s)), o);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 1000);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 3u);  // 1, 7, 1
}

TEST_F(LasFile, WithheldPointsAreDropped) {
  for (std::uint8_t format : {std::uint8_t{0}, std::uint8_t{7}}) {
    LasSpec s;
    s.minor = 4;
    s.format = format;
    s.points = sample_points();
    s.points[1].withheld = true;  // a ground point
    auto src = open_las(write(build_las(s)));
    ASSERT_TRUE(src.ok());
    auto pts = read_all(**src, 1000);
    ASSERT_TRUE(pts.ok());
    ASSERT_EQ(pts->size(), 1u) << "format " << int(format);
    EXPECT_EQ((*pts)[0].record, 6u);
    EXPECT_EQ((*src)->counters().rejected_withheld, 1u);
  }
}

TEST_F(LasFile, Las14UsesThe64BitPointCount) {
  LasSpec s;
  s.minor = 4;
  s.format = 8;
  s.points = sample_points();
  s.legacy_count_zero = true;
  auto src = open_las(write(build_las(s)), all_classes());
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().record_count, 7u);
  auto pts = read_all(**src, 1000);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 7u);
}

TEST_F(LasFile, ManyPointsStreamAcrossChunkBoundaries) {
  LasSpec s;
  s.format = 3;
  for (int i = 0; i < 300000; ++i) {
    s.points.push_back(TestPoint{i, -i, i % 1000, static_cast<std::uint8_t>(i % 3 == 0 ? 2 : 1)});
  }
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok());
  std::vector<SourcePoint> batch;
  std::uint64_t n = 0;
  std::int64_t expect_i = 0;
  while (true) {
    batch.clear();
    auto got = (*src)->read(batch, 4096);
    ASSERT_TRUE(got.ok());
    if (*got == 0) break;
    for (const auto& p : batch) {
      ASSERT_DOUBLE_EQ(p.x, static_cast<double>(expect_i) * 0.01 + 1000);
      ASSERT_EQ(p.record, static_cast<std::uint64_t>(expect_i) + 1);
      expect_i += 3;
      ++n;
    }
  }
  EXPECT_EQ(n, 100000u);
  EXPECT_EQ((*src)->counters().records_read, 300000u);
  EXPECT_EQ((*src)->counters().rejected_class, 200000u);
}

TEST_F(LasFile, CrsFromGeoKeysWithUnits) {
  LasSpec s;
  s.points = sample_points();
  s.vlrs.push_back(TestVlr{
      "LASF_Projection", 34735,
      testing::geokey_body({{1024, 1}, {3072, 2903}, {3076, 9003}, {4096, 5703}, {4099, 9003}})});
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok()) << src.error().message;
  const auto& info = (*src)->info();
  EXPECT_EQ(info.crs, "EPSG:2903");
  EXPECT_EQ(info.crs_origin, "LAS GeoKeys");
  EXPECT_EQ(info.vertical_crs, "EPSG:5703");
  ASSERT_TRUE(info.z_unit.has_value());
  EXPECT_DOUBLE_EQ(info.z_unit->to_metre, 1200.0 / 3937.0);
}

TEST_F(LasFile, GeographicGeoKey) {
  LasSpec s;
  s.points = sample_points();
  s.vlrs.push_back(
      TestVlr{"LASF_Projection", 34735, testing::geokey_body({{1024, 2}, {2048, 4326}})});
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok());
  EXPECT_EQ((*src)->info().crs, "EPSG:4326");
}

TEST_F(LasFile, WktVlrWinsOverGeoKeys) {
  LasSpec s;
  s.points = sample_points();
  s.vlrs.push_back(
      TestVlr{"LASF_Projection", 34735, testing::geokey_body({{1024, 1}, {3072, 32767}})});
  s.vlrs.push_back(TestVlr{"LASF_Projection", 2112, testing::text_body("PROJCS[\"x\"]")});
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok());
  EXPECT_EQ((*src)->info().crs, "PROJCS[\"x\"]");
  EXPECT_EQ((*src)->info().crs_origin, "LAS WKT VLR");
}

TEST_F(LasFile, WktInAnExtendedVlr) {
  LasSpec s;
  s.minor = 4;
  s.format = 6;
  s.points = sample_points();
  s.evlrs.push_back(TestVlr{"LASF_Projection", 2112, testing::text_body("GEOGCS[\"evlr\"]")});
  auto src = open_las(write(build_las(s)));
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().crs, "GEOGCS[\"evlr\"]");
}

// ---- broken input -------------------------------------------------------------------------

LasSpec small_spec() {
  LasSpec s;
  s.format = 1;
  s.points = sample_points();
  return s;
}

void expect_error(const Result<std::unique_ptr<PointSource>>& r, ErrorCode code,
                  const std::string& fragment, const std::filesystem::path& path) {
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, code) << r.error().message;
  EXPECT_NE(r.error().message.find(path.string()), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find(fragment), std::string::npos) << r.error().message;
}

TEST_F(LasFile, WrongMagicIsRejected) {
  auto b = build_las(small_spec());
  b[0] = 'X';
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "LASF", p);
}

TEST_F(LasFile, EmptyAndTruncatedHeadersAreRejected) {
  auto b = build_las(small_spec());
  auto p0 = write({}, "empty.las");
  expect_error(open_las(p0), ErrorCode::corrupt_data, "not a LAS file", p0);
  auto p = write(std::vector<unsigned char>(b.begin(), b.begin() + 100), "short.las");
  expect_error(open_las(p), ErrorCode::corrupt_data, "truncated", p);
  LasSpec s14 = small_spec();
  s14.minor = 4;
  auto b14 = build_las(s14);
  auto p14 = write(std::vector<unsigned char>(b14.begin(), b14.begin() + 300), "short14.las");
  expect_error(open_las(p14), ErrorCode::corrupt_data, "truncated", p14);
}

TEST_F(LasFile, TruncatedPointRecordsAreRejected) {
  auto b = build_las(small_spec());
  b.resize(b.size() - 10);  // cut the last record short
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "announces 7 points", p);
}

TEST_F(LasFile, AbsurdPointCountIsRejected) {
  auto b = build_las(small_spec());
  testing::put_value<std::uint32_t>(b, 107, 4000000000u);
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "4000000000 points", p);
  LasSpec s = small_spec();
  s.minor = 4;
  auto b14 = build_las(s);
  testing::put_value<std::uint64_t>(b14, 247, std::numeric_limits<std::uint64_t>::max());
  auto p14 = write(b14, "huge14.las");
  expect_error(open_las(p14), ErrorCode::corrupt_data, "18446744073709551615 points", p14);
}

TEST_F(LasFile, PointCountRunningIntoTheExtendedVlrsIsRejected) {
  LasSpec s;
  s.minor = 4;
  s.format = 6;
  s.points = sample_points();
  s.evlrs.push_back(TestVlr{"LASF_Projection", 2112, testing::text_body(std::string(200, 'W'))});
  auto b = build_las(s);
  testing::put_value<std::uint64_t>(b, 247, 9);  // 2 more than written: would read the EVLR
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "announces 9 points", p);
}

TEST_F(LasFile, OffsetToPointsBeyondTheFileIsRejected) {
  auto b = build_las(small_spec());
  testing::put_value<std::uint32_t>(b, 96, 1u << 30);
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "beyond the end of the file", p);
  testing::put_value<std::uint32_t>(b, 96, 100);
  auto p2 = write(b, "inside.las");
  expect_error(open_las(p2), ErrorCode::corrupt_data, "inside the header", p2);
}

TEST_F(LasFile, AbsurdVlrCountAndHeaderSizeAreRejected) {
  auto b = build_las(small_spec());
  testing::put_value<std::uint32_t>(b, 100, 0xFFFFFFFFu);  // VLR count
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "VLR 1 of 4294967295", p);
  auto b2 = build_las(small_spec());
  testing::put_value<std::uint16_t>(b2, 94, 60000);  // header size beyond the file
  auto p2 = write(b2, "hs.las");
  expect_error(open_las(p2), ErrorCode::corrupt_data, "truncated", p2);
}

TEST_F(LasFile, RecordLengthSmallerThanTheFormatIsRejected) {
  auto b = build_las(small_spec());
  testing::put_value<std::uint16_t>(b, 105, 20);  // format 1 needs 28
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "smaller than the 28 bytes", p);
}

TEST_F(LasFile, HeaderSizeSmallerThanTheVersionNeedsIsRejected) {
  LasSpec s = small_spec();
  s.minor = 4;
  auto b = build_las(s);
  testing::put_value<std::uint16_t>(b, 94, 227);
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "needs 375", p);
}

TEST_F(LasFile, UnknownVersionAndFormatAreUnsupported) {
  auto b = build_las(small_spec());
  b[24] = 2;
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::unsupported, "version 2.2", p);
  b[24] = 1;
  b[104] = 11;
  auto p2 = write(b, "f11.las");
  expect_error(open_las(p2), ErrorCode::unsupported, "format 11", p2);
}

TEST_F(LasFile, CompressionBitWithoutLaszipVlrIsCorrupt) {
  auto b = build_las(small_spec());
  b[104] = static_cast<unsigned char>(b[104] | 0x80);  // how LASzip marks compressed points
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "no LASzip VLR", p);
}

TEST_F(LasFile, ZeroOrNanScaleIsRejected) {
  auto b = build_las(small_spec());
  testing::put_value<double>(b, 139, 0.0);  // y scale
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "y scale factor", p);
  testing::put_value<double>(b, 139, std::nan(""));
  auto p2 = write(b, "nan.las");
  expect_error(open_las(p2), ErrorCode::corrupt_data, "y scale factor", p2);
}

TEST_F(LasFile, InfiniteCoordinateAfterScalingNamesTheRecord) {
  LasSpec s = small_spec();
  s.scale[2] = 1e308;
  s.points[5].Z = 100;  // 1e310: overflows to inf; record 6 is a ground point
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    if (i != 5) s.points[i].Z = 0;
  }
  auto p = write(build_las(s));
  auto src = open_las(p);
  ASSERT_TRUE(src.ok()) << src.error().message;
  auto pts = read_all(**src, 1000);
  ASSERT_FALSE(pts.ok());
  EXPECT_NE(pts.error().message.find("point record 6"), std::string::npos) << pts.error().message;
  EXPECT_NE(pts.error().message.find(p.string()), std::string::npos);
  // The error is sticky.
  std::vector<SourcePoint> more;
  EXPECT_FALSE((*src)->read(more, 10).ok());

  SourceOptions skip;
  skip.invalid = InvalidPolicy::skip;
  auto src2 = open_las(p, skip);
  ASSERT_TRUE(src2.ok());
  auto pts2 = read_all(**src2, 1000);
  ASSERT_TRUE(pts2.ok());
  EXPECT_EQ(pts2->size(), 1u);  // record 2 only
  EXPECT_EQ((*src2)->counters().rejected_invalid, 1u);
}

TEST_F(LasFile, VlrRunningIntoPointDataIsRejected) {
  LasSpec s = small_spec();
  s.vlrs.push_back(TestVlr{"LASF_Projection", 34735, testing::geokey_body({{3072, 2903}})});
  auto b = build_las(s);
  testing::put_value<std::uint16_t>(b, 227 + 20, 5000);  // body length
  auto p = write(b);
  expect_error(open_las(p), ErrorCode::corrupt_data, "VLR 1 of 1", p);
}

TEST_F(LasFile, GeoKeyDirectoryWithTooManyKeysIsRejected) {
  LasSpec s = small_spec();
  auto body = testing::geokey_body({{3072, 2903}});
  body[6] = 200;  // claims 200 keys
  s.vlrs.push_back(TestVlr{"LASF_Projection", 34735, body});
  auto p = write(build_las(s));
  expect_error(open_las(p), ErrorCode::corrupt_data, "announces 200 keys", p);
}

TEST_F(LasFile, MissingFileIsNotFound) {
  auto p = dir_ / "nope.las";
  expect_error(open_source(p), ErrorCode::not_found, "no such file", p);
}

TEST_F(LasFile, OpenSourceDetectsLasByMagicWhateverTheExtension) {
  auto p = write(build_las(small_spec()), "points.bin");
  auto src = open_source(p, all_classes());
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().format, "LAS 1.2 PDF 1");
}

// Mini-fuzz (the libFuzzer target in fuzz/ goes further): random byte flips and truncations of
// valid files must give a clean Error or points, never a crash, hang or huge allocation.
TEST_F(LasFile, MutatedFilesNeverCrash) {
  std::vector<std::vector<unsigned char>> seeds;
  for (std::uint8_t minor : {std::uint8_t{2}, std::uint8_t{4}}) {
    LasSpec s;
    s.minor = minor;
    s.format = minor == 4 ? 7 : 3;
    s.points = sample_points();
    s.vlrs.push_back(TestVlr{"LASF_Projection", 34735,
                             testing::geokey_body({{1024, 1}, {3072, 2903}, {4099, 9003}})});
    s.vlrs.push_back(TestVlr{"LASF_Projection", 2112, testing::text_body("GEOGCS[\"x\"]")});
    if (minor == 4) {
      s.evlrs.push_back(TestVlr{"LASF_Projection", 2112, testing::text_body("GEOGCS[\"y\"]")});
    }
    seeds.push_back(build_las(s));
  }
  std::uint64_t state = 0x9E3779B97F4A7C15ull;  // fixed seed: reproducible
  auto next = [&state] {
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return state;
  };
  int opened = 0, failed = 0;
  for (int iter = 0; iter < 1500; ++iter) {
    auto bytes = seeds[static_cast<std::size_t>(iter) % seeds.size()];
    const int flips = 1 + static_cast<int>(next() % 8);
    for (int f = 0; f < flips; ++f) {
      // Mostly hit the header and VLRs, where the structure is.
      const std::size_t limit =
          (next() % 4 == 0) ? bytes.size() : std::min<std::size_t>(bytes.size(), 700);
      bytes[next() % limit] = static_cast<unsigned char>(next());
    }
    if (next() % 5 == 0) bytes.resize(next() % bytes.size());
    const auto path = write(bytes, "mutant" + std::to_string(iter) + ".las");
    auto src = open_las(path);
    if (!src.ok()) {
      ++failed;
      EXPECT_NE(src.error().message.find(path.string()), std::string::npos) << src.error().message;
      continue;
    }
    ++opened;
    std::vector<SourcePoint> pts;
    for (int guard = 0; guard < 100; ++guard) {
      auto n = (*src)->read(pts, 4);
      if (!n.ok() || *n == 0) break;
    }
    EXPECT_LE(pts.size(), 7u);
  }
  EXPECT_GT(opened, 0);
  EXPECT_GT(failed, 0);
}

// ---- real data ----------------------------------------------------------------------------

TEST(LasRealData, AutzenDefaultFilterKeepsTheGroundPoints) {
  const auto path = kData / "autzen_trim.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  const auto& info = (*src)->info();
  EXPECT_EQ(info.format, "LAS 1.2 PDF 3");
  EXPECT_EQ(info.record_count, 110000u);
  EXPECT_EQ(info.crs_origin, "LAS WKT VLR");  // the GeoKeys are user-defined; the WKT wins
  EXPECT_NE(info.crs.find("Lambert_Conformal_Conic"), std::string::npos);
  ASSERT_TRUE(info.bounds.has_value());
  EXPECT_NEAR(info.bounds->min_x, 636001.76, 0.005);
  EXPECT_NEAR(info.bounds->max_x, 637179.22, 0.005);
  auto pts = read_all(**src, 10000);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  EXPECT_EQ(pts->size(), 26107u);
  double zmin = 1e300, zmax = -1e300, xmin = 1e300, xmax = -1e300;
  for (const auto& p : *pts) {
    EXPECT_EQ(p.classification, 2);
    zmin = std::min(zmin, p.z);
    zmax = std::max(zmax, p.z);
    xmin = std::min(xmin, p.x);
    xmax = std::max(xmax, p.x);
  }
  EXPECT_NEAR(zmin, 406.26, 0.005);
  EXPECT_NEAR(zmax, 434.06, 0.005);
  EXPECT_GE(xmin, 636001.76 - 0.005);
  EXPECT_LE(xmax, 637179.22 + 0.005);
  EXPECT_EQ((*src)->counters().records_read, 110000u);
  EXPECT_EQ((*src)->counters().rejected_class, 83893u);
}

TEST(LasRealData, AutzenClassCountsWithExplicitFilters) {
  const auto path = kData / "autzen_trim.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  SourceOptions o;
  o.class_filter.classes = std::vector<std::uint8_t>{1};
  auto src = open_source(path, o);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 50000);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 83893u);
  o.class_filter.classes = std::vector<std::uint8_t>{1, 2};
  auto all = open_source(path, o);
  ASSERT_TRUE(all.ok());
  auto pts2 = read_all(**all, 50000);
  ASSERT_TRUE(pts2.ok());
  EXPECT_EQ(pts2->size(), 110000u);
  double zmax = -1e300;
  for (const auto& p : *pts2) zmax = std::max(zmax, p.z);
  EXPECT_NEAR(zmax, 520.51, 0.005);
}

TEST(LasRealData, NewMexicoGeoKeysGiveEpsgAndUsSurveyFeet) {
  const auto path = kData / "nm_4_6_crop.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  const auto& info = (*src)->info();
  EXPECT_EQ(info.crs, "EPSG:2903");
  EXPECT_EQ(info.crs_origin, "LAS GeoKeys");
  EXPECT_EQ(info.vertical_crs, "EPSG:5103");
  bool datum_note = false;
  for (const auto& n : info.notes) datum_note |= n.find("datum* code") != std::string::npos;
  EXPECT_TRUE(datum_note) << "5103 is NAVD88's datum code, the file stores it as the vertical CRS";
  ASSERT_TRUE(info.z_unit.has_value());
  EXPECT_EQ(info.z_unit->name, "US survey foot");
  EXPECT_EQ(info.record_count, 23875u);
  auto pts = read_all(**src, 5000);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 9003u);
  for (const auto& p : *pts) {
    ASSERT_GE(p.x, 1639600.00 - 0.005);
    ASSERT_LE(p.x, 1639799.98 + 0.005);
    ASSERT_GE(p.y, 1454500.02 - 0.005);
    ASSERT_LE(p.y, 1454700.00 + 0.005);
    ASSERT_GE(p.z, 7077.92 - 0.005);
    ASSERT_LE(p.z, 7093.86 + 0.005);
  }
}

// LAZ reads exactly like LAS: the same points, records, classes and counters, with the default
// class filter and with every class.
TEST(LasRealData, AutzenLazReadsLikeAutzenLas) {
  const auto laz = kData / "autzen_trim.laz";
  const auto las = kData / "autzen_trim.las";
  if (!std::filesystem::exists(laz)) GTEST_SKIP() << "missing " << laz;
  for (bool every_class : {false, true}) {
    SourceOptions o = every_class ? all_classes() : SourceOptions{};
    auto a = open_source(laz, o);
    auto b = open_source(las, o);
    ASSERT_TRUE(a.ok()) << a.error().message;
    ASSERT_TRUE(b.ok()) << b.error().message;
    EXPECT_EQ((*a)->info().crs, (*b)->info().crs);
    EXPECT_EQ((*a)->info().record_count, (*b)->info().record_count);
    EXPECT_EQ((*a)->info().format, "LAZ 1.2 PDF 3");
    auto pa = read_all(**a, 4321);
    auto pb = read_all(**b, 4321);
    ASSERT_TRUE(pa.ok() && pb.ok());
    ASSERT_EQ(pa->size(), pb->size());
    EXPECT_EQ(pa->size(), every_class ? 110000u : 26107u);
    for (std::size_t i = 0; i < pa->size(); ++i) {
      const SourcePoint &p = (*pa)[i], &q = (*pb)[i];
      ASSERT_TRUE(p.x == q.x && p.y == q.y && p.z == q.z && p.record == q.record &&
                  p.classification == q.classification)
          << "point " << i;
    }
    EXPECT_EQ((*a)->counters().rejected_class, (*b)->counters().rejected_class);
  }
}

}  // namespace
}  // namespace tinstream::sources
