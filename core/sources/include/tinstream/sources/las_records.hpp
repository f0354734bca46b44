// tinstream/sources/las_records.hpp — the point records of a LAS or LAZ file, byte for byte as
// an uncompressed LAS file holds them, in file order (LAZ through tinstream::laz).
//
// Contract:
// - open() parses and checks the public header and the VLR/EVLR directory (every problem is an
//   Error naming the file) and, for LAZ, the "laszip encoded" VLR and the chunk table.
// - read() appends nothing and allocates nothing per record: it fills the caller's buffer with up
//   to max_records records of summary().record_length bytes. Errors name the file and the record
//   (LAS) or the chunk and its points (LAZ); a read() after an Error returns it again.
// - A LasRecordReader is used from one thread; LAZ decoding may run on worker threads it owns
//   (RecordOptions::threads).
// PointSource (open_las) reads through this class; `tinstream las-info` prints its summary.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/laz/laszip_vlr.hpp"
#include "tinstream/laz/laz_reader.hpp"

namespace tinstream::sources {

struct VlrEntry {
  bool extended = false;  // an EVLR (LAS 1.4), after the point data
  std::string user_id;
  std::uint16_t record_id = 0;
  std::uint64_t length = 0;  // body bytes
  std::string description;
};

struct LasFileSummary {
  std::string path;
  std::uint64_t file_size = 0;
  std::uint8_t version_major = 0, version_minor = 0;
  std::uint16_t header_size = 0;
  std::uint32_t offset_to_points = 0;
  std::uint8_t point_format = 0;  // 0-10, without the compression bits
  std::uint16_t record_length = 0;
  std::uint64_t point_count = 0;
  std::array<double, 3> scale{}, offset{};
  std::array<double, 3> min{}, max{};  // as the header states them
  std::vector<VlrEntry> vlrs;
  std::optional<laz::LaszipVlr> laszip;  // set for LAZ files
};

struct RecordOptions {
  // LAZ: decoding threads (0: one per core, at most 8; 1: the calling thread only).
  unsigned threads = 0;
  // LAZ layered chunks: decode only coordinates, returns, class and flags (what the ingest
  // uses); other fields keep each chunk's first value.
  bool geometry_and_class_only = false;
};

class LasRecordReader {
 public:
  static Result<std::unique_ptr<LasRecordReader>> open(const std::filesystem::path& path,
                                                       const RecordOptions& options = {});
  ~LasRecordReader();
  LasRecordReader(const LasRecordReader&) = delete;
  LasRecordReader& operator=(const LasRecordReader&) = delete;

  const LasFileSummary& summary() const;
  // Up to max_records records into `out`; 0 at the end.
  Result<std::size_t> read(std::uint8_t* out, std::size_t max_records);
  // Back to the first record.
  Status rewind();
  // LAZ only (null otherwise): chunk table, threads, notes.
  const laz::LazReader* laz() const;

  struct Impl;

 private:
  explicit LasRecordReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace tinstream::sources
