#include "chunk_table.hpp"

#include <optional>

#include "chunk_decoder.hpp"

namespace tinstream::laz::detail {
namespace {

std::size_t layers_of(const LaszipItem& item) {
  switch (item.type) {
    case ItemType::point14:
      return kPoint14Layers;
    case ItemType::rgbnir14:
      return 2;
    case ItemType::byte14:
      return item.size;
    default:
      return 1;
  }
}

// Why a stored table cannot be used (a phrase), or the table.
struct TableRead {
  std::vector<ChunkInfo> chunks;
  std::string problem;
  std::optional<std::uint64_t> table_offset;  // where the table starts, when that is plausible
};

TableRead read_table(int fd, const PointDataLayout& layout, const LaszipVlr& vlr,
                     std::uint64_t data_start) {
  TableRead out;
  std::uint8_t raw[8];
  if (!read_at(fd, layout.offset_to_points, raw, 8)) {
    out.problem = "the point data is too short to hold the chunk table's offset";
    return out;
  }
  auto offset = static_cast<std::int64_t>(get64(raw));
  if (offset == -1) {
    if (layout.file_size < 8 || !read_at(fd, layout.file_size - 8, raw, 8)) {
      out.problem = "the chunk table's offset should be in the file's last 8 bytes (it is -1)";
      return out;
    }
    offset = static_cast<std::int64_t>(get64(raw));
  }
  if (offset < static_cast<std::int64_t>(data_start) ||
      static_cast<std::uint64_t>(offset) + 8 > layout.file_size) {
    out.problem = "the chunk table's offset " + std::to_string(offset) +
                  " is not between the point data's start (" + std::to_string(data_start) +
                  ") and the end of the file (" + std::to_string(layout.file_size) + ")";
    return out;
  }
  const auto table = static_cast<std::uint64_t>(offset);
  out.table_offset = table;
  if (!read_at(fd, table, raw, 8)) {
    out.problem = "the chunk table's header cannot be read";
    return out;
  }
  const std::uint32_t version = get32(raw), count = get32(raw + 4);
  if (version != 0) {
    out.problem = "the chunk table has version " + std::to_string(version) + " (0 expected)";
    return out;
  }
  const std::uint64_t max_plausible =
      std::min<std::uint64_t>(layout.point_count, (table - data_start) / layout.record_length);
  if (count == 0 || count > max_plausible || count > kMaxChunks) {
    out.problem = "the chunk table lists " + std::to_string(count) + " chunks for " +
                  std::to_string(layout.point_count) + " points in " +
                  std::to_string(table - data_start) + " bytes";
    return out;
  }
  FileWindow window;
  window.open(fd, table + 8, layout.file_size);
  ArithmeticDecoder dec;
  dec.start(&window);
  IntegerDecoder ic(32, 2);
  const bool variable = vlr.variable_chunks();
  std::int32_t prev_points = 0, prev_bytes = 0;
  std::uint64_t pos = data_start, first_point = 0;
  out.chunks.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    ChunkInfo c;
    if (variable) {
      prev_points = ic.decode(dec, prev_points, 0);
      c.points = static_cast<std::uint32_t>(prev_points);
    } else {
      c.points = std::min<std::uint64_t>(vlr.chunk_size, layout.point_count - first_point);
    }
    prev_bytes = ic.decode(dec, prev_bytes, 1);
    c.bytes = static_cast<std::uint32_t>(prev_bytes);
    c.offset = pos;
    c.first_point = first_point;
    const std::string which = "the chunk table's entry " + std::to_string(i + 1);
    if (dec.overrun() > 0 || dec.io_failed()) {
      out.problem = "the chunk table ends before its " + std::to_string(count) + " entries";
      return out;
    }
    if (c.points == 0 || c.points > layout.point_count - first_point) {
      out.problem = which + " gives " + std::to_string(c.points) + " points where " +
                    std::to_string(layout.point_count - first_point) + " remain";
      return out;
    }
    if (c.bytes < layout.record_length || c.bytes > table - pos) {
      out.problem = which + " gives " + std::to_string(c.bytes) + " bytes at byte " +
                    std::to_string(pos) + ", the chunks end at the table (byte " +
                    std::to_string(table) + ")";
      return out;
    }
    pos += c.bytes;
    first_point += c.points;
    out.chunks.push_back(c);
  }
  if (first_point != layout.point_count) {
    out.problem = "the chunk table's " + std::to_string(count) + " chunks hold " +
                  std::to_string(first_point) + " points, the header announces " +
                  std::to_string(layout.point_count);
    out.chunks.clear();
  }
  return out;
}

// Walks layered chunks by their own layer tables.
Result<std::vector<ChunkInfo>> hop_layered_chunks(int fd, const std::string& path,
                                                  const PointDataLayout& layout,
                                                  const LaszipVlr& vlr, std::uint64_t data_start,
                                                  std::uint64_t data_end) {
  std::vector<ChunkInfo> chunks;
  const std::size_t layers = layer_count(vlr);
  std::uint64_t pos = data_start, first_point = 0;
  while (first_point < layout.point_count) {
    const std::string where = path + ": rebuilding the chunk table: chunk " +
                              std::to_string(chunks.size() + 1) + " at byte " + std::to_string(pos);
    if (chunks.size() >= kMaxChunks) return unsupported(where + ": more than 4194304 chunks");
    auto extent = ChunkDecoder::layered_extent(fd, pos, layout.record_length, layers);
    if (!extent.ok()) return corrupt_data(where + ": " + extent.error().message);
    const std::uint64_t remaining = layout.point_count - first_point;
    auto [stated, bytes] = *extent;
    ChunkInfo c;
    c.offset = pos;
    c.bytes = bytes;
    c.first_point = first_point;
    if (vlr.variable_chunks()) {
      c.points = stated;
    } else {
      c.points = std::min<std::uint64_t>(vlr.chunk_size, remaining);
      if (stated == c.points - 1) stated = c.points;  // "remaining points" wording
    }
    if (stated != c.points || c.points == 0 || c.points > remaining) {
      return corrupt_data(where + ": its header says " + std::to_string(stated) + " points (" +
                          std::to_string(remaining) + " remain)");
    }
    if (bytes > data_end - pos) {
      return corrupt_data(where + ": its layers (" + std::to_string(bytes) +
                          " bytes) run past the end of the point data (byte " +
                          std::to_string(data_end) + ")");
    }
    chunks.push_back(c);
    pos += bytes;
    first_point += c.points;
  }
  return chunks;
}

}  // namespace

std::size_t layer_count(const LaszipVlr& vlr) {
  std::size_t n = 0;
  for (const LaszipItem& item : vlr.items) n += layers_of(item);
  return n;
}

Result<ChunkLayout> find_chunks(int fd, const std::string& path, const PointDataLayout& layout,
                                const LaszipVlr& vlr) {
  ChunkLayout out;
  if (layout.point_count == 0) return out;
  if (vlr.compressor == Compressor::pointwise) {
    // One stream for every point: a single chunk up to the end of the point data.
    out.data_start = layout.offset_to_points;
    out.data_end = layout.points_end;
    if (out.data_end < out.data_start + layout.record_length) {
      return corrupt_data(path + ": the point data is shorter than one point record");
    }
    out.chunks.push_back(
        ChunkInfo{out.data_start, out.data_end - out.data_start, 0, layout.point_count});
    return out;
  }
  out.data_start = layout.offset_to_points + 8;
  if (out.data_start > layout.points_end) {
    return corrupt_data(path + ": the point data is too short to hold the chunk table's offset");
  }
  TableRead table = read_table(fd, layout, vlr, out.data_start);
  if (table.problem.empty()) {
    out.chunks = std::move(table.chunks);
    out.data_end = out.chunks.back().offset + out.chunks.back().bytes;
    return out;
  }
  // No usable table. Chunks end at the table if its position is plausible, else at the end of
  // the point data.
  out.data_end = layout.points_end;
  if (table.table_offset && *table.table_offset < out.data_end) {
    out.data_end = *table.table_offset;
  }
  const std::string why = "chunk table unusable (" + table.problem + ")";
  if (vlr.compressor == Compressor::layered_chunked) {
    auto chunks = hop_layered_chunks(fd, path, layout, vlr, out.data_start, out.data_end);
    if (!chunks.ok()) {
      return Error(chunks.error().code, chunks.error().message + "; " + why);
    }
    out.chunks = std::move(*chunks);
    out.notes.push_back(why + ": rebuilt from the chunks' layer tables (" +
                        std::to_string(out.chunks.size()) + " chunks)");
    return out;
  }
  if (vlr.variable_chunks()) {
    return corrupt_data(path + ": " + why +
                        "; its chunks have variable sizes and only the table says where they "
                        "end, so the points cannot be read");
  }
  out.discover = true;
  out.notes.push_back(why + ": chunk boundaries are found while decoding (on one thread)");
  return out;
}

}  // namespace tinstream::laz::detail
