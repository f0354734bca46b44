// Image codecs and the pyramid's downsampling.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "test_rasters.hpp"
#include "tinstream/imagery/image.hpp"

namespace tinstream::imagery {
namespace {

RgbaImage noise_image(std::uint32_t w, std::uint32_t h, std::uint64_t seed, bool alpha) {
  std::mt19937_64 rng(seed);
  RgbaImage image(w, h);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    image.pixels[i] = static_cast<std::uint8_t>(rng());
    if (i % 4 == 3 && !alpha) image.pixels[i] = 255;
  }
  return image;
}

TEST(ImageCodec, PngAndLosslessWebpRoundTripExactlyWithAlpha) {
  const RgbaImage image = noise_image(37, 23, 1, true);
  for (const auto format : {ImageFormat::png, ImageFormat::webp}) {
    EncodeOptions options;
    options.lossless = true;
    auto bytes = encode(image, format, options);
    ASSERT_TRUE(bytes.ok()) << bytes.error().message;
    EXPECT_EQ(*sniff_format(*bytes), format);
    auto back = decode(*bytes);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->width, 37u);
    EXPECT_EQ(back->height, 23u);
    if (format == ImageFormat::png) {
      EXPECT_EQ(back->pixels, image.pixels);
    } else {
      // Lossless WebP may change the colour of fully transparent pixels (it does not store them).
      for (std::size_t i = 0; i < image.pixels.size(); i += 4) {
        ASSERT_EQ(back->pixels[i + 3], image.pixels[i + 3]) << i;
        if (image.pixels[i + 3] != 0) {
          for (std::size_t c = 0; c < 3; ++c) ASSERT_EQ(back->pixels[i + c], image.pixels[i + c]);
        }
      }
    }
    // An independent decoder (GDAL's drivers) reads the same pixels.
    const auto gdal = testing::gdal_decode(*bytes);
    ASSERT_EQ(gdal.width, 37);
    EXPECT_EQ(gdal.rgba, back->pixels);
  }
}

TEST(ImageCodec, OpaquePngIsWrittenAsRgb) {
  const RgbaImage image = noise_image(16, 16, 2, false);
  auto bytes = encode(image, ImageFormat::png);
  ASSERT_TRUE(bytes.ok());
  // IHDR colour type (byte 25): 2 = RGB, 6 = RGBA.
  ASSERT_GT(bytes->size(), 26u);
  EXPECT_EQ((*bytes)[25], 2);
  auto back = decode(*bytes);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->pixels, image.pixels);
}

TEST(ImageCodec, JpegKeepsASmoothImageCloseAndDropsAlphaOverBlack) {
  RgbaImage image(64, 48);
  for (std::uint32_t y = 0; y < 48; ++y) {
    for (std::uint32_t x = 0; x < 64; ++x) {
      std::uint8_t* p = image.at(x, y);
      p[0] = static_cast<std::uint8_t>(x * 3);
      p[1] = static_cast<std::uint8_t>(y * 4);
      p[2] = 128;
      p[3] = x < 32 ? 255 : 0;
    }
  }
  EncodeOptions options;
  options.quality = 95;
  auto bytes = encode(image, ImageFormat::jpeg, options);
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto back = decode(*bytes);
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (std::uint32_t y = 4; y < 44; ++y) {
    for (std::uint32_t x = 4; x < 28; ++x) {
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(back->at(x, y)[c], image.at(x, y)[c], 6);
      ASSERT_EQ(back->at(x, y)[3], 255);
    }
    for (std::uint32_t x = 36; x < 60; ++x) {
      for (int c = 0; c < 3; ++c) ASSERT_LE(back->at(x, y)[c], 6) << x << "," << y;
    }
  }
}

TEST(ImageCodec, DamagedBytesGiveErrorsNotCrashes) {
  const RgbaImage image = noise_image(32, 32, 3, true);
  for (const auto format : {ImageFormat::png, ImageFormat::jpeg, ImageFormat::webp}) {
    auto bytes = encode(image, format);
    ASSERT_TRUE(bytes.ok());
    for (const std::size_t keep : {std::size_t{0}, std::size_t{5}, bytes->size() / 2}) {
      std::vector<std::uint8_t> cut(bytes->begin(),
                                    bytes->begin() + static_cast<std::ptrdiff_t>(keep));
      auto back = decode(cut);
      EXPECT_FALSE(back.ok()) << to_string(format) << " cut at " << keep;
    }
  }
  const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', ' ',
                                          'w', 'o', 'r', 'l', 'd', '!'};
  auto garbage = decode(text);
  ASSERT_FALSE(garbage.ok());
  EXPECT_NE(garbage.error().message.find("not a PNG, JPEG or WebP"), std::string::npos);
  // A big image is refused from its header.
  auto big = encode(noise_image(300, 200, 4, false), ImageFormat::png);
  ASSERT_TRUE(big.ok());
  EXPECT_EQ(decode(*big, 1000).error().code, ErrorCode::invalid_argument);
  EXPECT_FALSE(encode(RgbaImage(), ImageFormat::png).ok());
}

TEST(ImageCodec, FormatNames) {
  EXPECT_EQ(*parse_image_format("JPG"), ImageFormat::jpeg);
  EXPECT_EQ(*parse_image_format("webp"), ImageFormat::webp);
  EXPECT_FALSE(parse_image_format("gif").ok());
  EXPECT_EQ(file_extension(ImageFormat::jpeg), "jpg");
  EXPECT_EQ(mime_type(ImageFormat::webp), "image/webp");
}

// Expected values computed from the sRGB definition, not from the code's tables.
double srgb_to_linear(double c) {
  c /= 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
double linear_to_srgb(double l) {
  return 255.0 * (l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055);
}

TEST(Downsample, CheckerboardBecomesItsLinearLightMeanNotOneOfItsPixels) {
  RgbaImage child(8, 8);
  for (std::uint32_t y = 0; y < 8; ++y) {
    for (std::uint32_t x = 0; x < 8; ++x) {
      const std::uint8_t v = (x + y) % 2 == 0 ? 255 : 0;
      std::uint8_t* p = child.at(x, y);
      p[0] = p[1] = p[2] = v;
      p[3] = 255;
    }
  }
  const RgbaImage out = downsample_children({&child, &child, &child, &child});
  ASSERT_EQ(out.width, 8u);
  const double expected = linear_to_srgb(0.5);  // ≈ 187.5: the mean light of black and white
  for (std::size_t i = 0; i < out.pixels.size(); i += 4) {
    EXPECT_NEAR(out.pixels[i], expected, 0.51);
    EXPECT_EQ(out.pixels[i + 3], 255);
  }
}

TEST(Downsample, ChildrenGoToTheirQuadrantsAndTransparencyDoesNotDarken) {
  std::mt19937_64 rng(5);
  std::array<RgbaImage, 4> children;
  for (auto& c : children) c = noise_image(16, 16, rng(), true);
  // Child 1 (NE) absent; child 3 (SE) half transparent at its first pixel block.
  std::uint8_t* p = children[3].at(0, 0);
  p[0] = 200, p[1] = 100, p[2] = 50, p[3] = 255;
  p = children[3].at(1, 0);
  p[0] = 0, p[1] = 0, p[2] = 0, p[3] = 0;
  p = children[3].at(0, 1);
  p[0] = 200, p[1] = 100, p[2] = 50, p[3] = 255;
  p = children[3].at(1, 1);
  p[0] = 0, p[1] = 0, p[2] = 0, p[3] = 0;
  const RgbaImage out = downsample_children({&children[0], nullptr, &children[2], &children[3]});
  for (std::uint32_t y = 0; y < 16; ++y) {
    for (std::uint32_t x = 0; x < 16; ++x) {
      const std::size_t k = (x >= 8 ? 1u : 0u) + (y >= 8 ? 2u : 0u);
      const std::uint8_t* o = out.at(x, y);
      if (k == 1) {
        EXPECT_EQ(o[3], 0);
        continue;
      }
      const RgbaImage& c = children[k];
      const std::uint32_t cx = (x % 8) * 2, cy = (y % 8) * 2;
      double alpha = 0, colour[3] = {0, 0, 0};
      for (const auto& [dx, dy] : {std::pair{0u, 0u}, {1u, 0u}, {0u, 1u}, {1u, 1u}}) {
        const std::uint8_t* s = c.at(cx + dx, cy + dy);
        alpha += s[3];
        for (int ch = 0; ch < 3; ++ch) colour[ch] += s[3] * srgb_to_linear(s[ch]);
      }
      EXPECT_NEAR(o[3], alpha == 0 ? 0 : std::max(1.0, alpha / 4), 0.51);
      for (int ch = 0; ch < 3; ++ch) {
        const double expected = alpha == 0 ? 0 : linear_to_srgb(colour[ch] / alpha);
        EXPECT_NEAR(o[ch], expected, 1.01) << x << "," << y << " channel " << ch;
      }
    }
  }
  // The half-transparent block keeps its colour (straight alpha), with half the opacity.
  const std::uint8_t* edge = out.at(8, 8);
  EXPECT_EQ(edge[0], 200);
  EXPECT_EQ(edge[1], 100);
  EXPECT_EQ(edge[2], 50);
  EXPECT_EQ(edge[3], 128);
}

}  // namespace
}  // namespace tinstream::imagery
