// libFuzzer target for tile::decode (clang only; see core/tile/CMakeLists.txt).
//   tile_decode_fuzzer core/tile/fuzz/corpus -max_total_time=60
// Properties: decode never crashes, never allocates beyond what the input can describe, and what it
// accepts re-encodes to the same bytes (the format is canonical); check_structure must not crash on
// whatever decode accepts. The same input is also fed through decompress() with a small limit.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "tinstream/tile/codec.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const auto tile = tinstream::tile::decode(bytes);
  if (tile.ok()) {
    const auto again = tinstream::tile::encode(*tile);
    if (again.size() != size || !std::equal(again.begin(), again.end(), data)) std::abort();
    (void)tinstream::tile::check_structure(*tile);
  }
  const auto inflated = tinstream::tile::decompress(bytes, 1u << 20);
  if (inflated.ok()) {
    if (inflated->size() > (1u << 20)) std::abort();
    (void)tinstream::tile::decode(*inflated);
  }
  return 0;
}
