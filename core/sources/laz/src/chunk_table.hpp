// Finding a LAZ file's chunks: the chunk table (read, checked, or rebuilt from the chunks'
// own headers). Pure logic over a file descriptor; no decoding of points.
//
//   point data:  [i64 offset of the chunk table][chunk 0][chunk 1]...[chunk n-1]
//   chunk table: [u32 version = 0][u32 n][arithmetic-coded entries: (points,) bytes per chunk]
//
// Entries are integer-coded against the previous entry (point counts only for variable-size
// chunks, context 0; byte counts context 1). An offset of -1 means the table's offset is in the
// file's last 8 bytes (writers that could not seek back).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/laz/laszip_vlr.hpp"
#include "tinstream/laz/laz_reader.hpp"

namespace tinstream::laz::detail {

struct ChunkLayout {
  std::vector<ChunkInfo> chunks;
  // Pointwise chunks of fixed size without a usable table: their boundaries are found by
  // decoding them in order (chunks fills as that goes).
  bool discover = false;
  std::uint64_t data_start = 0;  // first byte of chunk 0
  std::uint64_t data_end = 0;    // no chunk may reach past this
  std::vector<std::string> notes;
};

// Reads, checks and if needed rebuilds the chunk layout. Errors are phrases naming `path`.
Result<ChunkLayout> find_chunks(int fd, const std::string& path, const PointDataLayout& layout,
                                const LaszipVlr& vlr);

// Layers per chunk of a layered (compressor 3) file.
std::size_t layer_count(const LaszipVlr& vlr);

}  // namespace tinstream::laz::detail
