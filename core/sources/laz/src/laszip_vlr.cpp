#include "tinstream/laz/laszip_vlr.hpp"

namespace tinstream::laz {
namespace {

std::uint16_t le16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
std::uint32_t le32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(le16(p)) | (static_cast<std::uint32_t>(le16(p + 2)) << 16);
}

bool known_type(std::uint16_t t) { return t == 0 || (t >= 6 && t <= 14); }

// The size an item must have (0: any, for extra bytes).
std::uint16_t item_size(ItemType t) {
  switch (t) {
    case ItemType::point10:
      return 20;
    case ItemType::gpstime11:
      return 8;
    case ItemType::rgb12:
    case ItemType::rgb14:
      return 6;
    case ItemType::rgbnir14:
      return 8;
    case ItemType::wavepacket13:
    case ItemType::wavepacket14:
      return 29;
    case ItemType::point14:
      return 30;
    case ItemType::byte:
    case ItemType::byte14:
      return 0;
  }
  return 0;
}

bool layered_type(ItemType t) {
  return t == ItemType::point14 || t == ItemType::rgb14 || t == ItemType::rgbnir14 ||
         t == ItemType::wavepacket14 || t == ItemType::byte14;
}

bool supported_version(ItemType t, std::uint16_t v) {
  if (layered_type(t)) return v >= 2 && v <= 4;  // 2 is what lasproto wrote for 3
  return v == 1 || v == 2;
}

}  // namespace

std::string to_string(ItemType type) {
  switch (type) {
    case ItemType::byte:
      return "BYTE";
    case ItemType::point10:
      return "POINT10";
    case ItemType::gpstime11:
      return "GPSTIME11";
    case ItemType::rgb12:
      return "RGB12";
    case ItemType::wavepacket13:
      return "WAVEPACKET13";
    case ItemType::point14:
      return "POINT14";
    case ItemType::rgb14:
      return "RGB14";
    case ItemType::rgbnir14:
      return "RGBNIR14";
    case ItemType::wavepacket14:
      return "WAVEPACKET14";
    case ItemType::byte14:
      return "BYTE14";
  }
  return "item " + std::to_string(static_cast<int>(type));
}

std::string to_string(Compressor compressor) {
  switch (compressor) {
    case Compressor::none:
      return "none";
    case Compressor::pointwise:
      return "pointwise";
    case Compressor::pointwise_chunked:
      return "pointwise chunked";
    case Compressor::layered_chunked:
      return "layered chunked";
  }
  return "compressor " + std::to_string(static_cast<int>(compressor));
}

Result<LaszipVlr> parse_laszip_vlr(std::span<const std::uint8_t> body, std::uint8_t point_format,
                                   std::uint16_t record_length, const std::string& where) {
  const std::string at = where + ": ";
  if (body.size() < 34) {
    return corrupt_data(at + "the body has " + std::to_string(body.size()) +
                        " bytes, its fixed part needs 34");
  }
  const std::uint8_t* p = body.data();
  LaszipVlr v;
  const std::uint16_t compressor = le16(p);
  v.coder = le16(p + 2);
  v.version_major = p[4];
  v.version_minor = p[5];
  v.version_revision = le16(p + 6);
  v.options = le32(p + 8);
  v.chunk_size = le32(p + 12);
  if (v.chunk_size == 0) v.chunk_size = kVariableChunkSize;
  // Bytes 16..31: number of and offset to "special" EVLRs, unused by readers.
  const std::uint16_t count = le16(p + 32);
  if (compressor < 1 || compressor > 3) {
    return unsupported(at + "compressor " + std::to_string(compressor) +
                       " is not known (1 pointwise, 2 pointwise chunked, 3 layered chunked)");
  }
  v.compressor = static_cast<Compressor>(compressor);
  if (v.coder != 0) {
    return unsupported(at + "coder " + std::to_string(v.coder) +
                       " is not known (0, arithmetic, is the only one defined)");
  }
  if (body.size() < 34 + std::size_t{count} * 6) {
    return corrupt_data(at + "announces " + std::to_string(count) + " items but its body holds " +
                        std::to_string((body.size() - 34) / 6));
  }
  if (count == 0) return corrupt_data(at + "lists no items");
  std::uint32_t total = 0;
  for (std::uint16_t i = 0; i < count; ++i) {
    const std::uint8_t* e = p + 34 + std::size_t{6} * i;
    const std::uint16_t type = le16(e);
    LaszipItem item;
    item.size = le16(e + 2);
    item.version = le16(e + 4);
    const std::string which = "item " + std::to_string(i + 1) + " of " + std::to_string(count);
    if (!known_type(type)) {
      return unsupported(at + which + " has unknown type " + std::to_string(type));
    }
    item.type = static_cast<ItemType>(type);
    const std::string name = which + " (" + to_string(item.type) + ")";
    const std::uint16_t want = item_size(item.type);
    if (want != 0 ? item.size != want : item.size == 0) {
      return corrupt_data(at + name + " is " + std::to_string(item.size) + " bytes, it must be " +
                          (want != 0 ? std::to_string(want) : std::string("at least 1")));
    }
    if ((item.type == ItemType::byte || item.type == ItemType::byte14) &&
        item.size > kMaxExtraBytes) {
      return unsupported(at + name + ": " + std::to_string(item.size) +
                         " extra bytes per point; this decoder handles up to " +
                         std::to_string(kMaxExtraBytes));
    }
    if (!supported_version(item.type, item.version)) {
      return unsupported(at + name + " has coder version " + std::to_string(item.version) +
                         ", which is not defined (" +
                         (layered_type(item.type) ? "3 and 4" : "1 and 2") + " are)");
    }
    const bool layered = v.compressor == Compressor::layered_chunked;
    if (layered != layered_type(item.type)) {
      return unsupported(at + name + " cannot be used with the " + to_string(v.compressor) +
                         " compressor");
    }
    if (i == 0 && item.type != ItemType::point10 && item.type != ItemType::point14) {
      return corrupt_data(at + "the first item is " + to_string(item.type) +
                          ", not POINT10 or POINT14");
    }
    if (i > 0 && (item.type == ItemType::point10 || item.type == ItemType::point14)) {
      return corrupt_data(at + name + " repeats the point item");
    }
    total += item.size;
    v.items.push_back(item);
  }
  const bool wants_point14 = point_format >= 6;
  if (wants_point14 != (v.items[0].type == ItemType::point14)) {
    return corrupt_data(at + "point data format " + std::to_string(point_format) + " needs " +
                        (wants_point14 ? "POINT14" : "POINT10") + " as the first item, it has " +
                        to_string(v.items[0].type));
  }
  if (total != record_length) {
    return corrupt_data(at + "its items cover " + std::to_string(total) +
                        " bytes of each point, the header's point record length is " +
                        std::to_string(record_length));
  }
  return v;
}

}  // namespace tinstream::laz
