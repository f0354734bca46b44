// tinstream/laz/laszip_vlr.hpp — the "laszip encoded" VLR (record 22204) that says how a LAZ
// file's point records are compressed (LAZ specification 1.4 R1, section "LASzip VLR").
//
// Contract: parse_laszip_vlr() is a pure function over the VLR's body; it accepts any bytes and
// returns an Error naming `where` for a body that is short, names an unknown compressor, coder,
// item type or item version, or whose items do not add up to the record length. A LaszipVlr it
// returns is one the decoder supports.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::laz {

inline constexpr std::uint16_t kLaszipRecordId = 22204;
inline constexpr const char* kLaszipUserId = "laszip encoded";
inline constexpr std::uint32_t kVariableChunkSize = 0xFFFFFFFFu;

enum class Compressor : std::uint16_t {
  none = 0,
  pointwise = 1,          // one arithmetic stream for all points after the first
  pointwise_chunked = 2,  // independent chunks, each a raw point then one stream
  layered_chunked = 3,    // LAS 1.4 formats 6-10: chunks of separately coded layers
};

enum class ItemType : std::uint16_t {
  byte = 0,  // extra bytes, formats 0-5
  point10 = 6,
  gpstime11 = 7,
  rgb12 = 8,
  wavepacket13 = 9,
  point14 = 10,
  rgb14 = 11,
  rgbnir14 = 12,
  wavepacket14 = 13,
  byte14 = 14,  // extra bytes, formats 6-10
};

struct LaszipItem {
  ItemType type = ItemType::byte;
  std::uint16_t size = 0;     // bytes of the record this item covers
  std::uint16_t version = 0;  // coder version: 1, 2 (pointwise items), 3, 4 (layered items)
};

struct LaszipVlr {
  Compressor compressor = Compressor::none;
  std::uint16_t coder = 0;  // 0 = arithmetic, the only one defined
  std::uint8_t version_major = 0, version_minor = 0;
  std::uint16_t version_revision = 0;
  std::uint32_t options = 0;
  // Points per chunk; kVariableChunkSize when each chunk's count is in the chunk table (a
  // stored 0 reads as variable too). Meaningless for Compressor::pointwise.
  std::uint32_t chunk_size = 0;
  std::vector<LaszipItem> items;

  bool variable_chunks() const { return chunk_size == kVariableChunkSize; }
};

// Largest number of extra bytes per record the decoder accepts: each extra byte carries its own
// adaptive models (about 2.3 KB per byte and scanner channel), so this bounds their memory.
inline constexpr std::uint16_t kMaxExtraBytes = 1024;

// Decodes and checks the VLR body against the LAS header's point format and record length.
// `where` prefixes every error message (e.g. "file.laz: LASzip VLR").
Result<LaszipVlr> parse_laszip_vlr(std::span<const std::uint8_t> body, std::uint8_t point_format,
                                   std::uint16_t record_length, const std::string& where);

std::string to_string(ItemType type);
std::string to_string(Compressor compressor);

}  // namespace tinstream::laz
