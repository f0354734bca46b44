// LAS 1.0–1.4 public header and GeoKey directory decoding (ASPRS LAS R15 spec), as pure
// functions over bytes so they can be tested without files.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "tinstream/base/result.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources::las {

// Minimum point record length per point data format 0–10 (extra bytes may follow).
inline constexpr std::array<std::uint16_t, 11> kMinRecordLength = {20, 28, 26, 34, 57, 63,
                                                                   30, 36, 38, 59, 67};
// Public header size each minor version needs (1.0–1.2: 227, 1.3: 235, 1.4: 375).
std::size_t required_header_size(std::uint8_t minor);

struct Header {
  std::uint8_t version_major = 0, version_minor = 0;
  std::uint16_t global_encoding = 0;
  std::uint16_t header_size = 0;
  std::uint32_t offset_to_points = 0;
  std::uint32_t vlr_count = 0;
  std::uint8_t point_format = 0;  // with the compression bits masked off
  bool compressed = false;        // bit 7 (or 6) of the format byte: LAZ point data
  std::uint16_t record_length = 0;
  std::uint64_t point_count = 0;  // 64-bit count for 1.4, legacy count otherwise
  std::array<double, 3> scale{}, offset{};
  double max_x = 0, min_x = 0, max_y = 0, min_y = 0, max_z = 0, min_z = 0;
  std::uint64_t evlr_start = 0;
  std::uint32_t evlr_count = 0;
  std::uint64_t points_end = 0;  // first byte after the point records: the EVLRs or the file's end
};

// Decodes and checks the public header. `bytes` holds the first min(375, file_size) bytes.
// Every inconsistency with the file size is an Error naming `path`.
Result<Header> parse_header(std::span<const unsigned char> bytes, std::uint64_t file_size,
                            const std::string& path);

// What the GeoKey directory (LASF_Projection 34735) says, for the keys we use.
struct GeoKeys {
  std::optional<std::uint16_t> model_type;         // 1024
  std::optional<std::uint16_t> geographic_type;    // 2048
  std::optional<std::uint16_t> projected_cs_type;  // 3072
  std::optional<std::uint16_t> proj_linear_units;  // 3076
  std::optional<std::uint16_t> vertical_cs_type;   // 4096
  std::optional<std::uint16_t> vertical_units;     // 4099
};
Result<GeoKeys> parse_geokeys(std::span<const unsigned char> bytes, const std::string& path);

// EPSG unit-of-measure code (9001, 9002, 9003, …) → LinearUnit, if it is a known linear unit.
std::optional<LinearUnit> linear_unit_from_epsg(std::uint16_t code);

// Class byte and withheld flag of one record of the given format.
inline std::uint8_t record_class(const unsigned char* rec, std::uint8_t format) {
  return format >= 6 ? rec[16] : static_cast<std::uint8_t>(rec[15] & 0x1f);
}
inline bool record_withheld(const unsigned char* rec, std::uint8_t format) {
  return format >= 6 ? (rec[15] & 0x04) != 0 : (rec[15] & 0x80) != 0;
}

}  // namespace tinstream::sources::las
