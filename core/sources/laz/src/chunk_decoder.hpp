// ChunkDecoder: turns one chunk of a LAZ file into point records (the items' bytes in LASzip
// VLR order, record_length bytes each).
//
//   pointwise chunk (compressors 1, 2):  [first record, raw][one arithmetic stream ...........]
//   layered chunk (compressor 3):        [first record, raw][u32 points][u32 size per layer]
//                                        [layer 0 bytes][layer 1 bytes]...
//
// The chunk's bytes are read from the file window by window (ByteSource), so a chunk of any
// size decodes in bounded memory; decode() may be called repeatedly for a few records at a time.
//
// Integrity: every arithmetic stream in a LAZ file is exactly as long as its decoder reads
// (LASzip's encoder pads its last bytes for that; LASzip checks it at every chunk boundary).
// finish() therefore requires each decoded stream to have been read to its last byte, no more
// and no less, whenever its length is known; a damaged chunk almost never passes that.
//
// Threads: one ChunkDecoder per thread; the file descriptor is only used with pread().
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "items.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/laz/laszip_vlr.hpp"

namespace tinstream::laz::detail {

// A window onto [pos, end) of the file, refilled with pread().
class FileWindow final : public ByteSource {
 public:
  static constexpr std::size_t kWindowBytes = std::size_t{1} << 20;
  void open(int fd, std::uint64_t pos, std::uint64_t end) {
    fd_ = fd;
    pos_ = pos;
    end_ = end;
    failed_ = false;
  }
  bool next_window(const std::uint8_t** begin, const std::uint8_t** end) override;
  bool failed() const override { return failed_; }

 private:
  int fd_ = -1;
  std::uint64_t pos_ = 0, end_ = 0;
  bool failed_ = false;
  std::vector<std::uint8_t> buffer_;
};

// Reads exactly n bytes at offset; false on an I/O error or end of file.
bool read_at(int fd, std::uint64_t offset, void* dst, std::size_t n);

struct ChunkExtent {
  std::uint64_t offset = 0;  // first byte of the chunk in the file
  std::uint64_t bytes = 0;   // chunk length; with exact_length false, an upper bound
  std::uint64_t points = 0;
  bool exact_length = true;  // false: compressor 1, or a chunk table being rebuilt
};

class ChunkDecoder {
 public:
  ChunkDecoder(const LaszipVlr& vlr, std::uint16_t record_length, const LayerSelection& layers,
               int fd);
  ~ChunkDecoder();

  // Positions on a chunk and reads its header. Errors are plain phrases; the caller adds the
  // file and chunk.
  Status begin(const ChunkExtent& chunk);
  // Decodes the next n records (n <= records left in the chunk).
  Status decode(std::uint8_t* out, std::uint64_t n);
  // Whether chunks of this file can decode in lock step (decode_pair): pointwise chunks of an
  // item list that decode_pointwise_pair() takes. Known from the construction on.
  bool pairable() const;
  // Whether this decoder and `other` can decode in lock step: both pairable, same records.
  bool pairs_with(const ChunkDecoder& other) const;
  // Decodes the next n records of this chunk into `out` and of other's into `other_out`, the
  // two streams interleaved on this thread; the records are those decode() gives. Returns
  // each chunk's stream health, this one's first. Requires: pairs_with(other) when begun,
  // n <= left() and n <= other.left(), and both decoders at the same record of their chunks.
  std::pair<Status, Status> decode_pair(ChunkDecoder& other, std::uint8_t* out,
                                        std::uint8_t* other_out, std::uint64_t n);
  // After the chunk's last record: checks that every stream ended where the chunk says.
  Status finish();
  // Bytes of the chunk the decoder has taken (header + streams); with a pointwise chunk of
  // unknown length this is where the next chunk starts.
  std::uint64_t consumed() const;
  std::uint64_t left() const { return left_; }

  // The layer table of a layered chunk at `offset`: its point count and total length.
  static Result<std::pair<std::uint64_t, std::uint64_t>> layered_extent(int fd,
                                                                        std::uint64_t offset,
                                                                        std::uint16_t record_length,
                                                                        std::size_t layers);
  std::size_t layer_count() const { return layer_sizes_.size(); }

 private:
  Status stream_health() const;
  std::vector<Layer*> all_layers();

  bool layered_;
  std::uint16_t record_length_;
  int fd_;
  std::vector<std::uint16_t> offsets_;  // item offsets in the record
  std::vector<std::uint16_t> sizes_;
  // pointwise
  std::vector<PointwiseItem> pointwise_;
  ArithmeticDecoder dec_;
  FileWindow window_;
  // layered
  std::unique_ptr<Point14Layered> point14_;
  std::vector<LayeredItem> layered_items_;
  std::vector<std::uint32_t> layer_sizes_;
  std::vector<FileWindow> layer_windows_;

  ChunkExtent chunk_;
  std::vector<std::uint8_t> first_;  // the raw first record
  std::uint64_t left_ = 0;           // records still to hand out
  bool first_pending_ = false;
  std::uint64_t header_bytes_ = 0;
};

}  // namespace tinstream::laz::detail
