// address_ranges.hpp — IP addresses and CIDR ranges (config admin_allow). Private to the server.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "tinstream/base/result.hpp"

namespace tinstream::server {

// One address or range, IPv4 or IPv6: "10.0.0.0/8", "127.0.0.1", "::1", "fd00::/8". IPv4
// addresses are kept as IPv4-mapped IPv6 (::ffff:a.b.c.d), so a v4 range also matches a v4 peer
// seen on a dual-stack socket.
struct AddressRange {
  std::array<std::uint8_t, 16> address{};
  unsigned prefix = 128;  // leading bits that must match

  // invalid_argument naming the text when it is neither an address nor a range.
  static Result<AddressRange> parse(std::string_view text);
  bool contains(std::string_view address) const;  // false for text that is no address
};

}  // namespace tinstream::server
