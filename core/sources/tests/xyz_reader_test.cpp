#include <gtest/gtest.h>

#include <fstream>

#include "las_writer.hpp"
#include "read_all.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {
namespace {

using testing::read_all;

class XyzFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("xyz_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path write(const std::string& text, const std::string& name = "p.xyz") {
    auto p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  std::filesystem::path dir_;
};

TEST_F(XyzFile, WhitespaceSeparatedWithCommentsAndBlankLines) {
  auto p = write("# a comment\n1 2 3\n\n  4\t5   6.5  \r\n# another\n-7e2 +8 9\n");
  auto src = open_source(p);
  ASSERT_TRUE(src.ok()) << src.error().message;
  EXPECT_EQ((*src)->info().format, "XYZ");
  EXPECT_TRUE((*src)->info().crs.empty());
  auto pts = read_all(**src, 2);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  ASSERT_EQ(pts->size(), 3u);
  EXPECT_EQ((*pts)[0].x, 1);
  EXPECT_EQ((*pts)[1].z, 6.5);
  EXPECT_EQ((*pts)[2].x, -700);
  EXPECT_EQ((*pts)[2].y, 8);
  EXPECT_EQ((*pts)[0].record, 2u);  // line numbers
  EXPECT_EQ((*pts)[2].record, 6u);
}

TEST_F(XyzFile, CsvWithHeaderIsDetectedAndColumnsChosen) {
  auto p =
      write("id,z,easting,northing\n1,100.5,500000,4000000\n2,101.5,500001,4000001\n", "p.csv");
  SourceOptions o;
  o.text.delimiter = ',';
  o.text.x_column = 2;
  o.text.y_column = 3;
  o.text.z_column = 1;
  auto src = open_source(p, o);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_TRUE(pts.ok()) << pts.error().message;
  ASSERT_EQ(pts->size(), 2u);
  EXPECT_EQ((*pts)[1].x, 500001);
  EXPECT_EQ((*pts)[1].y, 4000001);
  EXPECT_EQ((*pts)[1].z, 101.5);
}

TEST_F(XyzFile, ExplicitHeaderLinesAreSkipped) {
  auto p = write("title\n0 0 0\n1 1 1\n");
  SourceOptions o;
  o.text.header_lines = 2;  // skips "title" and "0 0 0"
  auto src = open_xyz(p, o);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_TRUE(pts.ok());
  ASSERT_EQ(pts->size(), 1u);
  EXPECT_EQ((*pts)[0].x, 1);
}

TEST_F(XyzFile, MalformedNumberNamesFileAndLine) {
  auto p = write("1 2 3\n4 5 6\n7 8,5 9\n");
  auto src = open_xyz(p);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_FALSE(pts.ok());
  EXPECT_EQ(pts.error().code, ErrorCode::corrupt_data);
  EXPECT_NE(pts.error().message.find(p.string() + ": line 3"), std::string::npos)
      << pts.error().message;
  EXPECT_NE(pts.error().message.find("8,5"), std::string::npos);
}

TEST_F(XyzFile, NanAndInfAreRejected) {
  for (const std::string bad : {"nan", "inf", "-INF", "NaN"}) {
    auto p = write("1 2 3\n4 5 " + bad + "\n");
    auto src = open_xyz(p);
    ASSERT_TRUE(src.ok());
    auto pts = read_all(**src, 2);
    ASSERT_FALSE(pts.ok()) << bad;
    EXPECT_NE(pts.error().message.find("line 2"), std::string::npos) << pts.error().message;
  }
}

TEST_F(XyzFile, TooFewFieldsNamesTheLine) {
  auto p = write("1 2 3\n4 5\n");
  auto src = open_xyz(p);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_FALSE(pts.ok());
  EXPECT_NE(pts.error().message.find("line 2: expected at least 3 fields, found 2"),
            std::string::npos)
      << pts.error().message;
}

TEST_F(XyzFile, SkipPolicyCountsBadLines) {
  auto p = write("1 2 3\nx y z\n4 5\n6 7 nan\n8 9 10\n");
  SourceOptions o;
  o.invalid = InvalidPolicy::skip;
  o.text.header_lines = 0;
  auto src = open_xyz(p, o);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 2u);
  EXPECT_EQ((*src)->counters().rejected_invalid, 3u);
  EXPECT_EQ((*src)->counters().records_read, 5u);
}

TEST_F(XyzFile, ClassColumnFilter) {
  auto p = write("1 1 1 2\n2 2 2 7\n3 3 3 1\n4 4 4 18\n");
  SourceOptions o;
  o.text.class_column = 3;
  auto src = open_xyz(p, o);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 2u);  // noise 7 and 18 dropped
  o.class_filter.classes = std::vector<std::uint8_t>{2};
  auto src2 = open_xyz(p, o);
  ASSERT_TRUE(src2.ok());
  auto pts2 = read_all(**src2, 2);
  ASSERT_TRUE(pts2.ok());
  ASSERT_EQ(pts2->size(), 1u);
  EXPECT_EQ((*pts2)[0].classification, 2);
}

TEST_F(XyzFile, LastLineWithoutNewlineAndEmptyFile) {
  auto p = write("1 2 3\n4 5 6");
  auto src = open_xyz(p);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  ASSERT_TRUE(pts.ok());
  EXPECT_EQ(pts->size(), 2u);
  auto e = write("", "empty.xyz");
  auto src2 = open_xyz(e);
  ASSERT_TRUE(src2.ok());
  auto none = read_all(**src2, 2);
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
}

TEST_F(XyzFile, BinaryGarbageGivesAnErrorNotACrash) {
  std::string garbage;
  for (int i = 0; i < 5000; ++i) garbage.push_back(static_cast<char>((i * 7919) % 256));
  auto p = write(garbage, "garbage.xyz");
  auto src = open_xyz(p);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src, 2);
  EXPECT_FALSE(pts.ok());
}

TEST(ClassList, ParsesAndRejects) {
  auto ok = parse_class_list("2,9,255");
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(*ok, (std::vector<std::uint8_t>{2, 9, 255}));
  EXPECT_FALSE(parse_class_list("2,,3").ok());
  EXPECT_FALSE(parse_class_list("256").ok());
  EXPECT_FALSE(parse_class_list("a").ok());
}

TEST(LinearUnitNames, ParseTheCommonSpellings) {
  EXPECT_DOUBLE_EQ(parse_linear_unit("metre")->to_metre, 1.0);
  EXPECT_DOUBLE_EQ(parse_linear_unit("foot")->to_metre, 0.3048);
  EXPECT_DOUBLE_EQ(parse_linear_unit("us-foot")->to_metre, 0.3048006096012192);
  EXPECT_FALSE(parse_linear_unit("furlong").ok());
}

}  // namespace
}  // namespace tinstream::sources
