// libFuzzer target for imagery::decode (PNG, JPEG, WebP), including libjpeg's longjmp error path.
//   scripts/fuzz.sh --only image_decode_fuzzer        (seeds: core/imagery/fuzz/corpus)
// Properties: decode never crashes, refuses images above its pixel limit before allocating them,
// and what it accepts is consistent (width × height × 4 bytes) and survives a lossless PNG round
// trip unchanged.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "tinstream/imagery/image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace tinstream::imagery;
  constexpr std::uint64_t kMaxPixels = 1u << 20;
  auto image = decode(std::span(data, size), kMaxPixels);
  if (!image) return 0;
  if (image->width == 0 || image->height == 0 ||
      static_cast<std::uint64_t>(image->width) * image->height > kMaxPixels ||
      image->pixels.size() != std::size_t{image->width} * image->height * 4) {
    std::abort();
  }
  auto png = encode(*image, ImageFormat::png, {.fast = true});
  if (!png) std::abort();
  auto back = decode(*png, kMaxPixels);
  if (!back || back->pixels != image->pixels) std::abort();
  return 0;
}
