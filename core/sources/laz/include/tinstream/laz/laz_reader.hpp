// tinstream/laz/laz_reader.hpp — decodes the point records of a LAZ file (LASzip-compressed
// LAS 1.0-1.4, point formats 0-10 with extra bytes; COPC files are LAZ files) into the bytes an
// uncompressed LAS file would hold, in file order.
//
// Contract:
// - The caller has parsed the LAS header and the "laszip encoded" VLR (it owns LAS parsing);
//   LazReader::open() reads the chunk table (its offset is the first 8 bytes of the point data;
//   -1 means "in the last 8 bytes of the file"), checks it against the header's point count and
//   the file size, and rebuilds it when it is missing or damaged and the chunks can be found
//   without it (layered chunks carry their own sizes; fixed-size pointwise chunks are found by
//   decoding them one after the other). A variable-size pointwise file without a usable table is
//   an Error.
// - read() hands out records in file order. With ReaderOptions::threads > 1 whole chunks are
//   decoded ahead on worker threads, at most 2 per thread in flight, each at most
//   kMaxParallelChunkBytes of records; files whose chunks are bigger decode on the calling
//   thread, window by window, in bounded memory. On one thread, POINT10 v2 + GPSTIME11 v2
//   chunks (point format 1) are decoded two at a time, their streams interleaved: the second
//   chunk's records (at most kMaxParallelChunkBytes) wait in a buffer for their turn.
// - Bad input never crashes and never allocates beyond those bounds: every Error names the file,
//   the chunk (1-based, "of N") and the point numbers it holds, and says what was wrong. A read()
//   after an Error returns the same Error.
// - Layers not asked for (LayerSelection) are skipped in layered chunks (compressor 3): their
//   fields keep the value of the chunk's first point. Pointwise chunks are always fully decoded.
// Threads: a LazReader is used from one thread at a time; it owns its worker threads (started by
// the first read()) and its file descriptor, and joins the workers in rewind() and its
// destructor.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/laz/laszip_vlr.hpp"

namespace tinstream::laz {

// What the LAS public header says about the point records.
struct PointDataLayout {
  std::uint64_t offset_to_points = 0;
  std::uint64_t point_count = 0;
  std::uint64_t points_end = 0;  // first byte after the point data: the EVLRs, or the file's end
  std::uint64_t file_size = 0;
  std::uint8_t point_format = 0;
  std::uint16_t record_length = 0;
};

// Which parts of layered chunks to decode. X, Y, return numbers and scanner channel are always
// decoded (all other layers are predicted from them).
struct LayerSelection {
  bool z = true, classification = true, flags = true, intensity = true, scan_angle = true,
       user_data = true, point_source = true, gps_time = true, rgb = true, nir = true,
       wavepacket = true, extra_bytes = true;
  // What a terrain reader needs: coordinates, class, the withheld flag and return numbers.
  static LayerSelection geometry_and_class() {
    LayerSelection s;
    s.intensity = s.scan_angle = s.user_data = s.point_source = s.gps_time = false;
    s.rgb = s.nir = s.wavepacket = s.extra_bytes = false;
    return s;
  }
};

struct ReaderOptions {
  unsigned threads = 0;  // 0: one per core, at most 8; 1: decode on the calling thread
  LayerSelection layers;
};

struct ChunkInfo {
  std::uint64_t offset = 0;  // first byte in the file
  std::uint64_t bytes = 0;   // 0 when not known yet (a table being rebuilt while decoding)
  std::uint64_t first_point = 0;
  std::uint64_t points = 0;
};

// Bound on the records of one chunk that a worker decodes whole (50,000 points of 67 bytes,
// LASzip's default chunk of format 10, take 3.4 MB).
inline constexpr std::uint64_t kMaxParallelChunkBytes = std::uint64_t{32} << 20;
// Bound on the number of chunks a file may have (each costs a table entry in memory).
inline constexpr std::uint64_t kMaxChunks = std::uint64_t{1} << 22;

class LazReader {
 public:
  static Result<std::unique_ptr<LazReader>> open(const std::filesystem::path& path,
                                                 const PointDataLayout& layout,
                                                 const LaszipVlr& vlr,
                                                 const ReaderOptions& options = {});
  ~LazReader();
  LazReader(const LazReader&) = delete;
  LazReader& operator=(const LazReader&) = delete;

  // Decodes up to max_records records (layout.record_length bytes each) into `out`. Returns how
  // many; 0 at the end of the points.
  Result<std::size_t> read(std::uint8_t* out, std::size_t max_records);
  // Starts again from the first record (and clears an Error).
  Status rewind();

  const LaszipVlr& vlr() const;
  // The chunk table as read or rebuilt (entries of a table rebuilt while decoding appear as
  // their chunks are reached).
  const std::vector<ChunkInfo>& chunks() const;
  unsigned threads() const;  // decoding threads actually used (1: the calling thread)
  // Remarks for the user: a table rebuilt, why decoding runs on one thread.
  const std::vector<std::string>& notes() const;

 private:
  struct State;
  explicit LazReader(std::unique_ptr<State> state);
  std::unique_ptr<State> s_;
};

}  // namespace tinstream::laz
