// tinstream/transform/run_file.hpp — the binary point run file pass 1 can write.
// The ingest writes none: it hands pass 1's points to pass 2 in memory
// (TransformOptions::on_points), whose sorted runs are its run files of transformed points, and
// keeps only the header (RunHeaderBuilder). RunFileReader reads a run file sequentially (tools,
// tests, any later consumer).
//
// Layout (all little-endian, whatever the host):
//
//   offset size  header (128 bytes)
//      0    8    magic "TINRUN1\0"
//      8    4    u32 header size (128)
//     12    4    u32 record size (32)
//     16    8    u64 point count
//     24    1    u8 projection: 0 spherical, 1 ellipsoidal (normalised Mercator, DESIGN.md §2)
//     25    1    u8 complete: 1 once the writer committed (a file with 0 is refused)
//     26    6    reserved, 0
//     32   32    f64 min x, min y, max x, max y        (normalised Mercator)
//     64   16    f64 min z, max z                      (metres above the WGS84 ellipsoid)
//     80   32    f64 min lon, min lat, max lon, max lat (degrees; no antimeridian wrapping)
//    112    4    u32 number of inputs
//    116   12    reserved, 0
//
//   records (32 bytes each), in input order:
//      0   24    f64 x, f64 y (normalised Mercator), f64 z (metres, ellipsoidal)
//     24    4    f32 weight (importance, DESIGN.md §2; 1 by default)
//     28    2    u16 input index (saturates at 65535)
//     30    1    u8 ASPRS class (0 where the format has none)
//     31    1    reserved, 0
//
// Atomicity: RunFileWriter writes "<path>.partial-<pid>", and commit() (durable) fsyncs and renames
// it to <path>; a writer destroyed without commit() removes its partial file. So a file under the
// final name is always complete. Readers check magic, sizes and the complete flag.
// Threads: writer and reader are thread-compatible (one per thread).
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"

namespace tinstream::transform {

struct RunPoint {
  double x = 0, y = 0;  // normalised Mercator
  double z = 0;         // metres above the WGS84 ellipsoid
  float weight = 1;
  std::uint16_t input = 0;
  std::uint8_t classification = 0;
};

inline constexpr std::size_t kRunHeaderBytes = 128;
inline constexpr std::size_t kRunRecordBytes = 32;

struct Extent {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;
  bool empty() const { return min_x > max_x; }
};

// What a run file's header says.
struct RunFileHeader {
  std::uint64_t point_count = 0;
  geo::Projection projection = geo::Projection::spherical;
  // With no points, the extents are empty() (min = +inf, max = -inf) and so is the z range.
  Extent mercator;  // normalised Mercator
  Extent lonlat;    // x = lon, y = lat, degrees
  double min_z = 0, max_z = 0;
  std::uint32_t input_count = 0;
};

// Accumulates what a run file's header says (count, boxes, z range) over the points appended,
// whether or not they are written anywhere.
class RunHeaderBuilder {
 public:
  RunHeaderBuilder(geo::Projection projection, std::uint32_t input_count);
  // Requires: `lonlat` is empty or as long as `points`.
  void add(std::span<const RunPoint> points, std::span<const geo::LonLat> lonlat);
  const RunFileHeader& header() const { return header_; }

 private:
  RunFileHeader header_;
};

class RunFileWriter {
 public:
  // Creates the partial file next to `path` (same directory, so the rename is atomic).
  static Result<RunFileWriter> create(const std::filesystem::path& path, geo::Projection projection,
                                      std::uint32_t input_count);
  RunFileWriter(RunFileWriter&&) noexcept;
  RunFileWriter& operator=(RunFileWriter&&) noexcept;
  ~RunFileWriter();  // without commit(): removes the partial file

  // Requires: every point has finite x, y, z and lon/lat in `lonlat` (same length) if given.
  Status append(std::span<const RunPoint> points, std::span<const geo::LonLat> lonlat);
  // Writes the final header, fsyncs (unless !durable: a scratch file its writer removes soon,
  // whose data need not reach the disk), renames to the final path. Returns the header.
  Result<RunFileHeader> commit(bool durable = true);

  const std::filesystem::path& partial_path() const { return partial_; }
  std::uint64_t point_count() const { return header_.header().point_count; }

 private:
  RunFileWriter() = default;
  void abandon();
  struct FileCloser {
    void operator()(std::FILE* f) const {
      if (f != nullptr) std::fclose(f);
    }
  };
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::filesystem::path final_, partial_;
  RunHeaderBuilder header_{geo::Projection::spherical, 0};
  std::vector<unsigned char> buffer_;
};

class RunFileReader {
 public:
  static Result<RunFileReader> open(const std::filesystem::path& path);
  RunFileReader(RunFileReader&&) noexcept;
  RunFileReader& operator=(RunFileReader&&) noexcept;
  ~RunFileReader();

  const RunFileHeader& header() const { return header_; }
  // Appends up to max_points records to `out`; returns how many, 0 at the end.
  Result<std::size_t> read(std::vector<RunPoint>& out, std::size_t max_points);
  // Back to the first record.
  Status rewind();

 private:
  RunFileReader() = default;
  struct FileCloser {
    void operator()(std::FILE* f) const {
      if (f != nullptr) std::fclose(f);
    }
  };
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::filesystem::path path_;
  RunFileHeader header_;
  std::uint64_t next_ = 0;
  std::vector<unsigned char> buffer_;
};

// Pure codec, exposed for tests and tools.
void encode_run_header(const RunFileHeader& h, bool complete, unsigned char out[kRunHeaderBytes]);
Result<RunFileHeader> decode_run_header(const unsigned char in[kRunHeaderBytes],
                                        const std::string& path);
void encode_run_point(const RunPoint& p, unsigned char out[kRunRecordBytes]);
RunPoint decode_run_point(const unsigned char in[kRunRecordBytes]);

}  // namespace tinstream::transform
