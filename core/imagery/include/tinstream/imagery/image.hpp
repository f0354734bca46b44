// tinstream/imagery/image.hpp — 8-bit RGBA images, their encodings and their downsampling.
//
// An RgbaImage is width × height pixels of 4 bytes (R, G, B, A), rows top (north) to bottom,
// straight (not premultiplied) alpha. Imagery tiles and raster-DEM tiles travel as PNG, JPEG or
// WebP through encode()/decode(), built on libpng, libjpeg(-turbo) and libwebp.
//
// All functions are pure and thread-safe. Bad bytes give an Error naming what was wrong.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::imagery {

struct RgbaImage {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<std::uint8_t> pixels;  // width * height * 4

  RgbaImage() = default;
  RgbaImage(std::uint32_t w, std::uint32_t h)
      : width(w), height(h), pixels(static_cast<std::size_t>(w) * h * 4, 0) {}

  // Requires x < width, y < height.
  std::uint8_t* at(std::uint32_t x, std::uint32_t y) {
    return pixels.data() + (static_cast<std::size_t>(y) * width + x) * 4;
  }
  const std::uint8_t* at(std::uint32_t x, std::uint32_t y) const {
    return pixels.data() + (static_cast<std::size_t>(y) * width + x) * 4;
  }
  bool fully_transparent() const;
  bool fully_opaque() const;
};

enum class ImageFormat { png, jpeg, webp };

std::string_view to_string(ImageFormat f);       // "png", "jpeg", "webp"
std::string_view mime_type(ImageFormat f);       // "image/png", …
std::string_view file_extension(ImageFormat f);  // "png", "jpg", "webp"
// Accepts "png", "jpeg"/"jpg", "webp" (any case).
Result<ImageFormat> parse_image_format(std::string_view text);

struct EncodeOptions {
  int quality = 85;       // JPEG and lossy WebP, 1–100
  bool lossless = false;  // WebP only
  bool fast = false;      // PNG: faster, weaker compression (tiles made per request)
};

// PNG keeps alpha (and drops it when every pixel is opaque); WebP keeps alpha; JPEG has none:
// pixels are composited over black first.
Result<std::vector<std::uint8_t>> encode(const RgbaImage& image, ImageFormat format,
                                         const EncodeOptions& options = {});

// Decodes PNG, JPEG or WebP (told apart by their signatures) into RGBA. Images above
// `max_pixels` are refused before their pixels are allocated.
Result<RgbaImage> decode(std::span<const std::uint8_t> bytes, std::uint64_t max_pixels = 1u << 26);

// The format of encoded bytes from their signature, or an Error.
Result<ImageFormat> sniff_format(std::span<const std::uint8_t> bytes);

// One level of an image pyramid: the four children of a tile (quadkey digit order NW, NE, SW, SE;
// null where a child is absent, i.e. transparent) downsampled 2:1 into one image of the
// children's size. Each output pixel is the box filter of its 2 × 2 source pixels, averaged in
// linear light (sRGB decoded) and weighted by alpha, so transparent pixels do not darken edges
// and a fine checkerboard keeps its brightness. Requires: present children are square, all of
// the same even size.
RgbaImage downsample_children(const std::array<const RgbaImage*, 4>& children);

}  // namespace tinstream::imagery
