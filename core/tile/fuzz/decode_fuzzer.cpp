// libFuzzer target for tile::decode (clang only; see core/tile/CMakeLists.txt).
//   tile_decode_fuzzer core/tile/fuzz/corpus -max_total_time=60
// Properties: decode never crashes, never allocates beyond what the input can describe, and what it
// accepts re-encodes, in its own version, to the same bytes (each version is canonical);
// check_structure must not crash on whatever decode accepts. The same input is also fed through
// decompress() with a small limit, and through compress_runs(), which must inflate back to it.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "tinstream/tile/codec.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const auto tile = tinstream::tile::decode(bytes);
  if (tile.ok()) {
    // Re-encode in the blob's own version (bytes 4–5; decode accepted it, so it is 1 or 2).
    const auto version = static_cast<tinstream::tile::FormatVersion>(data[4] | data[5] << 8);
    const auto again = tinstream::tile::encode(*tile, version);
    if (again.size() != size || !std::equal(again.begin(), again.end(), data)) std::abort();
    (void)tinstream::tile::check_structure(*tile);
  }
  // compress_runs is a deflate encoder of our own: any input must inflate back to itself.
  const auto packed = tinstream::tile::compress_runs(bytes);
  const auto unpacked = tinstream::tile::decompress(packed, size);
  if (!unpacked.ok() || *unpacked != std::vector<std::uint8_t>(data, data + size)) std::abort();
  const auto inflated = tinstream::tile::decompress(bytes, 1u << 20);
  if (inflated.ok()) {
    if (inflated->size() > (1u << 20)) std::abort();
    (void)tinstream::tile::decode(*inflated);
  }
  return 0;
}
