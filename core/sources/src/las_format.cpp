#include "las_format.hpp"

#include <cmath>
#include <cstring>

#include "binary_io.hpp"

namespace tinstream::sources::las {

using detail::load_le16;
using detail::load_le32;
using detail::load_le64;
using detail::load_le_double;

std::size_t required_header_size(std::uint8_t minor) {
  if (minor >= 4) return 375;
  if (minor == 3) return 235;
  return 227;
}

Result<Header> parse_header(std::span<const unsigned char> bytes, std::uint64_t file_size,
                            const std::string& path) {
  const std::string where = path + ": LAS header: ";
  if (bytes.size() < 4 || std::memcmp(bytes.data(), "LASF", 4) != 0) {
    return corrupt_data(path + ": not a LAS file (the first 4 bytes are not \"LASF\")");
  }
  if (bytes.size() < 227) {
    return corrupt_data(where + "truncated: the file has " + std::to_string(file_size) +
                        " bytes, a LAS public header needs at least 227");
  }
  const unsigned char* p = bytes.data();
  Header h;
  h.global_encoding = load_le16(p + 6);
  h.version_major = p[24];
  h.version_minor = p[25];
  if (h.version_major != 1 || h.version_minor > 4) {
    return unsupported(where + "LAS version " + std::to_string(h.version_major) + "." +
                       std::to_string(h.version_minor) + " is not supported (1.0–1.4 are)");
  }
  h.header_size = load_le16(p + 94);
  h.offset_to_points = load_le32(p + 96);
  h.vlr_count = load_le32(p + 100);
  const std::uint8_t raw_format = p[104];
  h.record_length = load_le16(p + 105);
  const std::uint32_t legacy_count = load_le32(p + 107);
  for (std::size_t i = 0; i < 3; ++i) {
    h.scale[i] = load_le_double(p + 131 + 8 * i);
    h.offset[i] = load_le_double(p + 155 + 8 * i);
  }
  h.max_x = load_le_double(p + 179);
  h.min_x = load_le_double(p + 187);
  h.max_y = load_le_double(p + 195);
  h.min_y = load_le_double(p + 203);
  h.max_z = load_le_double(p + 211);
  h.min_z = load_le_double(p + 219);

  const std::size_t needed = required_header_size(h.version_minor);
  if (h.header_size < needed) {
    return corrupt_data(where + "header size field is " + std::to_string(h.header_size) +
                        " bytes, LAS 1." + std::to_string(h.version_minor) + " needs " +
                        std::to_string(needed));
  }
  if (file_size < h.header_size || bytes.size() < needed) {
    return corrupt_data(where + "truncated: the file has " + std::to_string(file_size) +
                        " bytes, the header says it is " + std::to_string(h.header_size));
  }
  if (h.version_minor >= 4) {
    h.evlr_start = load_le64(p + 235);
    h.evlr_count = load_le32(p + 243);
    const std::uint64_t count64 = load_le64(p + 247);
    h.point_count = count64 != 0 ? count64 : legacy_count;
  } else {
    h.point_count = legacy_count;
  }
  // LASzip sets bit 7 of the format byte (some writers bit 6): the records are LAZ-compressed.
  h.compressed = (raw_format & 0xC0) != 0;
  h.point_format = static_cast<std::uint8_t>(raw_format & 0x3F);
  if (h.point_format > 10) {
    return unsupported(where + "point data format " + std::to_string(h.point_format) +
                       " is not defined (0–10 are)");
  }
  if (h.record_length < kMinRecordLength[h.point_format]) {
    return corrupt_data(where + "point record length " + std::to_string(h.record_length) +
                        " is smaller than the " + std::to_string(kMinRecordLength[h.point_format]) +
                        " bytes point data format " + std::to_string(h.point_format) + " needs");
  }
  if (h.offset_to_points < h.header_size) {
    return corrupt_data(where + "offset to point data (" + std::to_string(h.offset_to_points) +
                        ") lies inside the header (" + std::to_string(h.header_size) + " bytes)");
  }
  if (h.offset_to_points > file_size) {
    return corrupt_data(where + "offset to point data (" + std::to_string(h.offset_to_points) +
                        ") is beyond the end of the file (" + std::to_string(file_size) +
                        " bytes)");
  }
  // Point records end at the first EVLR (LAS 1.4) or at the end of the file.
  std::uint64_t points_end = file_size;
  if (h.evlr_count > 0 && h.evlr_start >= h.offset_to_points && h.evlr_start <= file_size) {
    points_end = h.evlr_start;
  }
  h.points_end = points_end;
  const std::uint64_t available = points_end - h.offset_to_points;
  // Compressed records have no fixed size: the LAZ chunk table and decoder check their count.
  if (!h.compressed && h.point_count > available / h.record_length) {
    return corrupt_data(where + "the header announces " + std::to_string(h.point_count) +
                        " points of " + std::to_string(h.record_length) + " bytes, but only " +
                        std::to_string(available) + " bytes lie between the offset to point data " +
                        "and the end of the point records " + "(room for " +
                        std::to_string(available / h.record_length) +
                        " records): the file is truncated or the count is wrong");
  }
  const char* axis = "xyz";
  for (std::size_t i = 0; i < 3; ++i) {
    if (!std::isfinite(h.scale[i]) || h.scale[i] == 0.0) {
      return corrupt_data(where + axis[i] + " scale factor is " + std::to_string(h.scale[i]) +
                          " (must be finite and non-zero)");
    }
    if (!std::isfinite(h.offset[i])) {
      return corrupt_data(where + axis[i] + " offset is not finite");
    }
  }
  return h;
}

Result<GeoKeys> parse_geokeys(std::span<const unsigned char> bytes, const std::string& path) {
  const std::string where = path + ": GeoKeyDirectory VLR (LASF_Projection 34735): ";
  if (bytes.size() < 8) return corrupt_data(where + "shorter than its 8-byte header");
  const std::uint16_t key_count = load_le16(bytes.data() + 6);
  if (8 + std::size_t{key_count} * 8 > bytes.size()) {
    return corrupt_data(where + "announces " + std::to_string(key_count) + " keys but holds " +
                        std::to_string((bytes.size() - 8) / 8));
  }
  GeoKeys keys;
  for (std::size_t k = 0; k < key_count; ++k) {
    const unsigned char* e = bytes.data() + 8 + 8 * k;
    const std::uint16_t id = load_le16(e);
    const std::uint16_t location = load_le16(e + 2);
    const std::uint16_t value = load_le16(e + 6);
    if (location != 0) continue;  // the keys we use are all SHORT values stored inline
    switch (id) {
      case 1024:
        keys.model_type = value;
        break;
      case 2048:
        keys.geographic_type = value;
        break;
      case 3072:
        keys.projected_cs_type = value;
        break;
      case 3076:
        keys.proj_linear_units = value;
        break;
      case 4096:
        keys.vertical_cs_type = value;
        break;
      case 4099:
        keys.vertical_units = value;
        break;
      default:
        break;
    }
  }
  return keys;
}

std::optional<LinearUnit> linear_unit_from_epsg(std::uint16_t code) {
  switch (code) {
    case 9001:
      return LinearUnit{"metre", 1.0};
    case 9002:
      return LinearUnit{"foot", 0.3048};
    case 9003:
      return LinearUnit{"US survey foot", 1200.0 / 3937.0};
    case 9036:
      return LinearUnit{"kilometre", 1000.0};
    default:
      return std::nullopt;
  }
}

}  // namespace tinstream::sources::las
