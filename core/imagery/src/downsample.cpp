// The 2:1 box filter of an image pyramid, in linear light with alpha weighting.
//
// For the 2 × 2 source pixels p_k (sRGB colour c_k, alpha a_k in [0, 1]) of one output pixel:
//   alpha  = Σ a_k / 4, rounded, but at least 1/255 when Σ a_k > 0
//   colour = srgb( Σ a_k · linear(c_k) / Σ a_k )      (0 when Σ a_k = 0)
// i.e. premultiplied averaging: a half-transparent edge keeps its colour instead of fading to
// the black of the transparent pixels beside it.
#include <algorithm>
#include <array>
#include <cmath>

#include "tinstream/imagery/image.hpp"

namespace tinstream::imagery {

namespace {

double srgb_to_linear(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
double linear_to_srgb(double l) {
  return l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055;
}

// sRGB byte → linear light, and linear light quantised to 16 bits → nearest sRGB byte.
struct Tables {
  std::array<float, 256> to_linear{};
  std::array<std::uint8_t, 65536> to_srgb{};
  Tables() {
    for (int i = 0; i < 256; ++i)
      to_linear[static_cast<std::size_t>(i)] = static_cast<float>(srgb_to_linear(i / 255.0));
    for (int i = 0; i < 65536; ++i) {
      const double s = linear_to_srgb(i / 65535.0) * 255.0;
      to_srgb[static_cast<std::size_t>(i)] =
          static_cast<std::uint8_t>(std::lround(std::clamp(s, 0.0, 255.0)));
    }
  }
};

const Tables& tables() {
  static const Tables t;
  return t;
}

// Writes the half-size image of `child` into the quadrant of `out` at (ox, oy).
void downsample_into(const RgbaImage& child, RgbaImage& out, std::uint32_t ox, std::uint32_t oy) {
  const Tables& t = tables();
  const std::uint32_t half = child.width / 2;
  for (std::uint32_t y = 0; y < half; ++y) {
    for (std::uint32_t x = 0; x < half; ++x) {
      const std::uint8_t* p[4] = {child.at(2 * x, 2 * y), child.at(2 * x + 1, 2 * y),
                                  child.at(2 * x, 2 * y + 1), child.at(2 * x + 1, 2 * y + 1)};
      unsigned alpha_sum = 0;
      float colour[3] = {0, 0, 0};
      for (const std::uint8_t* s : p) {
        alpha_sum += s[3];
        for (int c = 0; c < 3; ++c) colour[c] += static_cast<float>(s[3]) * t.to_linear[s[c]];
      }
      std::uint8_t* d = out.at(ox + x, oy + y);
      // Rounded, but never to 0 over some coverage: a source far below a pixel still leaves
      // its (invisible) trace, so every ancestor of a stored tile is stored too.
      d[3] = static_cast<std::uint8_t>(alpha_sum == 0 ? 0 : std::max(1u, (alpha_sum + 2) / 4));
      for (int c = 0; c < 3; ++c) {
        const float linear = alpha_sum == 0 ? 0.0f : colour[c] / static_cast<float>(alpha_sum);
        d[c] = t.to_srgb[static_cast<std::size_t>(
            std::lround(std::clamp(linear, 0.0f, 1.0f) * 65535.0f))];
      }
    }
  }
}

}  // namespace

RgbaImage downsample_children(const std::array<const RgbaImage*, 4>& children) {
  std::uint32_t size = 0;
  for (const RgbaImage* c : children) {
    if (c != nullptr) size = c->width;
  }
  RgbaImage out(size, size);
  const std::uint32_t half = size / 2;
  for (std::size_t k = 0; k < 4; ++k) {
    if (children[k] == nullptr) continue;
    downsample_into(*children[k], out, (k & 1u) != 0 ? half : 0, (k & 2u) != 0 ? half : 0);
  }
  return out;
}

}  // namespace tinstream::imagery
