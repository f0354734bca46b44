#include "address_ranges.hpp"

#include <arpa/inet.h>

#include <charconv>
#include <cstring>
#include <optional>
#include <string>

namespace tinstream::server {
namespace {

// `text` as IPv6 bytes (IPv4 mapped); nullopt when it is neither. `v4`: it was an IPv4 address.
std::optional<std::array<std::uint8_t, 16>> parse_address(std::string_view text, bool& v4) {
  const std::string s(text);
  std::array<std::uint8_t, 16> out{};
  in_addr a4{};
  if (::inet_pton(AF_INET, s.c_str(), &a4) == 1) {
    out[10] = out[11] = 0xff;
    std::memcpy(out.data() + 12, &a4, 4);
    v4 = true;
    return out;
  }
  in6_addr a6{};
  if (::inet_pton(AF_INET6, s.c_str(), &a6) == 1) {
    std::memcpy(out.data(), &a6, 16);
    v4 = false;
    return out;
  }
  return std::nullopt;
}

}  // namespace

Result<AddressRange> AddressRange::parse(std::string_view text) {
  const auto slash = text.find('/');
  bool v4 = false;
  const auto parsed = parse_address(text.substr(0, slash), v4);
  if (!parsed) {
    return invalid_argument("\"" + std::string(text) + "\" is not an IP address or CIDR range");
  }
  AddressRange r;
  r.address = *parsed;
  r.prefix = 128;
  if (slash != std::string_view::npos) {
    const std::string_view bits = text.substr(slash + 1);
    unsigned n = 0;
    const auto [end, ec] = std::from_chars(bits.data(), bits.data() + bits.size(), n);
    if (ec != std::errc() || end != bits.data() + bits.size() || bits.empty() ||
        n > (v4 ? 32u : 128u)) {
      return invalid_argument("\"" + std::string(text) + "\": the prefix length is not valid");
    }
    r.prefix = v4 ? 96 + n : n;
  }
  return r;
}

bool AddressRange::contains(std::string_view text) const {
  bool v4 = false;
  const auto peer = parse_address(text, v4);
  if (!peer) return false;
  for (unsigned bit = 0; bit < prefix; ++bit) {
    const unsigned byte = bit / 8, mask = 0x80u >> (bit % 8);
    if (((*peer)[byte] & mask) != (address[byte] & mask)) return false;
  }
  return true;
}

}  // namespace tinstream::server
