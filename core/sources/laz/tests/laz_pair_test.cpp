// Two chunks decoded in lock step on one thread (ChunkDecoder::decode_pair) give the records
// each gives decoded alone, whichever of the two is longer and however the records are asked
// for. The reader pairs only chunk 2k with 2k + 1 of equal or falling sizes; these tests also
// pair a short chunk with a longer one, which a file with a variable chunk table would give.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "../src/chunk_decoder.hpp"
#include "tinstream/sources/las_records.hpp"

namespace tinstream::laz::detail {
namespace {

const std::filesystem::path kData = TINSTREAM_SHARED_DATA;

struct OpenFile {
  explicit OpenFile(const std::filesystem::path& p) : fd(::open(p.c_str(), O_RDONLY)) {}
  ~OpenFile() {
    if (fd >= 0) ::close(fd);
  }
  OpenFile(const OpenFile&) = delete;
  OpenFile& operator=(const OpenFile&) = delete;
  int fd;
};

ChunkExtent extent_of(const ChunkInfo& c) {
  ChunkExtent e;
  e.offset = c.offset;
  e.bytes = c.bytes;
  e.points = c.points;
  return e;
}

class LazPair : public ::testing::Test {
 protected:
  void SetUp() override {
    // POINT10 v2 + GPSTIME11 v2 (the item list that pairs): ten chunks of 50000, then 18862.
    path_ = kData / "lone_star_tls.laz";
    if (!std::filesystem::exists(path_)) GTEST_SKIP() << "shared data absent: " << path_;
    auto reader = sources::LasRecordReader::open(path_, {});
    ASSERT_TRUE(reader.ok());
    ASSERT_NE((*reader)->laz(), nullptr);
    vlr_ = (*reader)->laz()->vlr();
    chunks_ = (*reader)->laz()->chunks();
    record_length_ = static_cast<std::uint16_t>((*reader)->summary().record_length);
    ASSERT_EQ(chunks_.size(), 11u);
  }

  // Chunk `index` decoded alone, in one call.
  std::vector<std::uint8_t> alone(int fd, std::size_t index) const {
    ChunkDecoder d(vlr_, record_length_, {}, fd);
    EXPECT_TRUE(d.begin(extent_of(chunks_[index])).ok());
    std::vector<std::uint8_t> out(chunks_[index].points * record_length_);
    EXPECT_TRUE(d.decode(out.data(), chunks_[index].points).ok());
    EXPECT_TRUE(d.finish().ok());
    return out;
  }

  // Chunks a and b in lock step, `batch` records of each at a time while both have records;
  // then the rest of the longer one alone.
  void expect_pair_matches(std::size_t a, std::size_t b, std::uint64_t batch) const {
    const OpenFile file(path_);
    ASSERT_GE(file.fd, 0);
    ChunkDecoder da(vlr_, record_length_, {}, file.fd);
    ChunkDecoder db(vlr_, record_length_, {}, file.fd);
    ASSERT_TRUE(da.begin(extent_of(chunks_[a])).ok());
    ASSERT_TRUE(db.begin(extent_of(chunks_[b])).ok());
    ASSERT_TRUE(da.pairs_with(db));
    std::vector<std::uint8_t> out_a(chunks_[a].points * record_length_);
    std::vector<std::uint8_t> out_b(chunks_[b].points * record_length_);
    std::uint64_t done = 0;
    while (da.left() > 0 && db.left() > 0) {
      const std::uint64_t n = std::min({batch, da.left(), db.left()});
      const auto [status_a, status_b] = da.decode_pair(db, out_a.data() + done * record_length_,
                                                       out_b.data() + done * record_length_, n);
      ASSERT_TRUE(status_a.ok()) << status_a.error().message;
      ASSERT_TRUE(status_b.ok()) << status_b.error().message;
      done += n;
    }
    ASSERT_TRUE(da.decode(out_a.data() + done * record_length_, da.left()).ok());
    ASSERT_TRUE(db.decode(out_b.data() + done * record_length_, db.left()).ok());
    EXPECT_TRUE(da.finish().ok());
    EXPECT_TRUE(db.finish().ok());
    EXPECT_TRUE(out_a == alone(file.fd, a)) << "chunk " << a << " paired with " << b;
    EXPECT_TRUE(out_b == alone(file.fd, b)) << "chunk " << b << " paired with " << a;
  }

  std::filesystem::path path_;
  LaszipVlr vlr_;
  std::vector<ChunkInfo> chunks_;
  std::uint16_t record_length_ = 0;
};

TEST_F(LazPair, EqualChunksGiveTheirRecordsAlone) {
  expect_pair_matches(0, 1, 50000);
  expect_pair_matches(0, 1, 777);
}

TEST_F(LazPair, LongerChunkBesideAShorterGivesTheirRecordsAlone) {
  expect_pair_matches(9, 10, 4096);
}

TEST_F(LazPair, ShorterChunkBesideALongerGivesTheirRecordsAlone) {
  expect_pair_matches(10, 0, 1);
  expect_pair_matches(10, 3, 10000);
}

}  // namespace
}  // namespace tinstream::laz::detail
