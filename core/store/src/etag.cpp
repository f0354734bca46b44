#include "tinstream/store/etag.hpp"

#include <cstdio>

namespace tinstream::store {

std::uint64_t fnv1a64(std::span<const std::uint8_t> bytes) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (const std::uint8_t b : bytes) {
    h ^= b;
    h *= 0x100000001b3ull;
  }
  return h;
}

std::string make_etag(std::span<const std::uint8_t> compressed) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "\"%016llx-%llx\"",
                static_cast<unsigned long long>(fnv1a64(compressed)),
                static_cast<unsigned long long>(compressed.size()));
  return buf;
}

}  // namespace tinstream::store
