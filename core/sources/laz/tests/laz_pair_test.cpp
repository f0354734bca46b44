// Two chunks decoded in lock step on one thread (ChunkDecoder::decode_pair) give the records
// each gives decoded alone, whichever of the two is longer and however the records are asked
// for. The reader pairs only chunk 2k with 2k + 1 of equal or falling sizes; these tests also
// pair a short chunk with a longer one, which a file with a variable chunk table would give.
// Below them, layered chunks decoded in calls that cut their batches anywhere.
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

// A layered chunk is decoded kLayeredBatch points at a time, layer by layer: the XY/returns
// layer's pass records each point's context (channel, returns, time/angle/source changes, Z
// context) and every other layer's loop takes point i's from there. Calls to decode() that cut a
// chunk anywhere (single records, a batch less one, a batch and one) give the records of one
// call; and one call gives the uncompressed twin's records. A layer decoded with another point's
// context, or with a context or decoder state left over from the previous call, breaks either.
class LazLayered : public ::testing::Test {
 protected:
  struct File {
    LaszipVlr vlr;
    std::vector<ChunkInfo> chunks;
    std::uint16_t record_length = 0;
  };
  static File open_file(const std::filesystem::path& path) {
    File f;
    auto reader = sources::LasRecordReader::open(path, {});
    EXPECT_TRUE(reader.ok());
    if (!reader.ok() || (*reader)->laz() == nullptr) return f;
    f.vlr = (*reader)->laz()->vlr();
    f.chunks = (*reader)->laz()->chunks();
    f.record_length = static_cast<std::uint16_t>((*reader)->summary().record_length);
    return f;
  }
  // Chunk `index` of `path`, decode() called with the sizes in `cuts` (cyclically) until done.
  static std::vector<std::uint8_t> decode_cut(const std::filesystem::path& path, const File& f,
                                              std::size_t index,
                                              const std::vector<std::uint64_t>& cuts) {
    const OpenFile file(path);
    EXPECT_GE(file.fd, 0);
    ChunkDecoder d(f.vlr, f.record_length, {}, file.fd);
    EXPECT_TRUE(d.begin(extent_of(f.chunks[index])).ok());
    std::vector<std::uint8_t> out(f.chunks[index].points * f.record_length);
    std::uint64_t done = 0;
    for (std::size_t k = 0; d.left() > 0; ++k) {
      const std::uint64_t n = std::min(cuts[k % cuts.size()], d.left());
      const Status st = d.decode(out.data() + done * f.record_length, n);
      EXPECT_TRUE(st.ok()) << st.error().message;
      if (!st.ok()) break;
      done += n;
    }
    EXPECT_TRUE(d.finish().ok());
    return out;
  }
};

TEST_F(LazLayered, CallsCuttingTheBatchesAnywhereGiveTheRecordsOfOneCall) {
  const std::filesystem::path path = kData / "laz_las_with_several_extra_byte_bloc.laz";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  const File f = open_file(path);
  ASSERT_EQ(f.vlr.compressor, Compressor::layered_chunked);
  ASSERT_GT(f.chunks.size(), 2u);
  const std::uint64_t b = kLayeredBatch;
  for (const std::size_t index : {std::size_t{0}, f.chunks.size() - 1}) {
    ASSERT_GT(f.chunks[index].points, 3 * b);
    const std::vector<std::uint8_t> whole = decode_cut(path, f, index, {f.chunks[index].points});
    EXPECT_TRUE(decode_cut(path, f, index, {1, 1, b - 1, 2, b, b + 1, 5, 3 * b + 7}) == whole)
        << "chunk " << index;
    EXPECT_TRUE(decode_cut(path, f, index, {b / 2 + 1}) == whole) << "chunk " << index;
  }
}

TEST_F(LazLayered, OneCallGivesTheUncompressedTwinsRecords) {
  const std::filesystem::path path = kData / "laz_1_4_w_evlr.laz";
  const std::filesystem::path twin = kData / "laz_1_4_w_evlr.las";
  if (!std::filesystem::exists(path) || !std::filesystem::exists(twin)) {
    GTEST_SKIP() << "shared data absent: " << path;
  }
  const File f = open_file(path);
  ASSERT_EQ(f.vlr.compressor, Compressor::layered_chunked);
  // The twin's records, straight from its bytes (offset to point data at byte 96).
  std::vector<std::uint8_t> las(std::filesystem::file_size(twin));
  {
    const OpenFile file(twin);
    ASSERT_TRUE(read_at(file.fd, 0, las.data(), las.size()));
  }
  const std::uint32_t offset =
      las[96] | las[97] << 8 | las[98] << 16 | std::uint32_t{las[99]} << 24;
  std::uint64_t first = 0;
  for (std::size_t index = 0; index < f.chunks.size(); ++index) {
    const std::vector<std::uint8_t> one = decode_cut(path, f, index, {f.chunks[index].points});
    const std::vector<std::uint8_t> cut = decode_cut(path, f, index, {1, 2, 3});
    const std::size_t at = offset + first * f.record_length;
    ASSERT_LE(at + one.size(), las.size());
    EXPECT_TRUE(std::equal(one.begin(), one.end(), las.begin() + static_cast<std::ptrdiff_t>(at)))
        << "chunk " << index;
    EXPECT_TRUE(cut == one) << "chunk " << index;
    first += f.chunks[index].points;
  }
  EXPECT_EQ(first, 1000u);
}

}  // namespace
}  // namespace tinstream::laz::detail
