// PNG (libpng's simplified API), JPEG (libjpeg-turbo through the classic libjpeg API) and WebP
// (libwebp's simple API) for RgbaImage.
// jpeglib.h needs size_t and FILE declared first.
#include <cstddef>
#include <cstdio>
// clang-format off
#include <jpeglib.h>
// clang-format on
#include <png.h>
#include <webp/decode.h>
#include <webp/encode.h>

#include <algorithm>
#include <csetjmp>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "tinstream/imagery/image.hpp"

namespace tinstream::imagery {

namespace {

bool ieq(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

// ---- PNG ------------------------------------------------------------------------------------

Result<std::vector<std::uint8_t>> encode_png(const RgbaImage& image, bool fast) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = image.width;
  png.height = image.height;
  const bool opaque = image.fully_opaque();
  png.format = opaque ? PNG_FORMAT_RGB : PNG_FORMAT_RGBA;
  png.flags = fast ? PNG_IMAGE_FLAG_FAST : 0;
  // RGB: the same pixels without their alpha bytes.
  std::vector<std::uint8_t> rgb;
  const void* buffer = image.pixels.data();
  if (opaque) {
    rgb.resize(static_cast<std::size_t>(image.width) * image.height * 3);
    for (std::size_t i = 0, n = rgb.size() / 3; i < n; ++i) {
      std::memcpy(&rgb[i * 3], &image.pixels[i * 4], 3);
    }
    buffer = rgb.data();
  }
  std::vector<std::uint8_t> out(PNG_IMAGE_PNG_SIZE_MAX(png));
  png_alloc_size_t size = out.size();
  if (png_image_write_to_memory(&png, out.data(), &size, 0, buffer, 0, nullptr) == 0) {
    const std::string message = png.message;
    png_image_free(&png);
    return Error(ErrorCode::internal, "PNG encoding failed: " + message);
  }
  out.resize(size);
  return out;
}

Result<RgbaImage> decode_png(std::span<const std::uint8_t> bytes, std::uint64_t max_pixels) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_memory(&png, bytes.data(), bytes.size()) == 0) {
    const std::string message = png.message;
    png_image_free(&png);
    return corrupt_data("PNG: " + message);
  }
  if (static_cast<std::uint64_t>(png.width) * png.height > max_pixels) {
    png_image_free(&png);
    return invalid_argument("PNG: " + std::to_string(png.width) + " × " +
                            std::to_string(png.height) + " pixels is too large");
  }
  png.format = PNG_FORMAT_RGBA;
  RgbaImage image(png.width, png.height);
  if (png_image_finish_read(&png, nullptr, image.pixels.data(), 0, nullptr) == 0) {
    const std::string message = png.message;
    png_image_free(&png);
    return corrupt_data("PNG: " + message);
  }
  return image;
}

// ---- JPEG -----------------------------------------------------------------------------------

// libjpeg reports fatal errors through error_exit, which must not return: it longjmps back to
// the setjmp in the function that started the (de)compression. Those functions keep only plain C
// objects between setjmp and the last libjpeg call, so the jump skips no destructor.
struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

extern "C" void jpeg_error_exit(j_common_ptr info) {
  auto* error = reinterpret_cast<JpegError*>(info->err);
  (*info->err->format_message)(info, error->message);
  std::longjmp(error->jump, 1);
}

// Counts warnings (e.g. premature end of data, which libjpeg fills with grey) instead of
// printing them; a decode with warnings is refused.
extern "C" void jpeg_silent(j_common_ptr info, int level) {
  if (level < 0) info->err->num_warnings++;
}

// Compresses `rgb` (width × height × 3) into a malloc'd buffer; returns false with `error`.
bool jpeg_compress_rgb(const std::uint8_t* rgb, std::uint32_t width, std::uint32_t height,
                       int quality, unsigned char** out, unsigned long* out_size,
                       JpegError* error) {
  jpeg_compress_struct cinfo;
  cinfo.err = jpeg_std_error(&error->mgr);
  error->mgr.error_exit = jpeg_error_exit;
  error->mgr.emit_message = jpeg_silent;
  if (setjmp(error->jump) != 0) {
    jpeg_destroy_compress(&cinfo);
    return false;
  }
  jpeg_create_compress(&cinfo);
  jpeg_mem_dest(&cinfo, out, out_size);
  cinfo.image_width = width;
  cinfo.image_height = height;
  cinfo.input_components = 3;
  cinfo.in_color_space = JCS_RGB;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row =
        const_cast<JSAMPROW>(rgb + static_cast<std::size_t>(cinfo.next_scanline) * width * 3);
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  jpeg_destroy_compress(&cinfo);
  return true;
}

Result<std::vector<std::uint8_t>> encode_jpeg(const RgbaImage& image, int quality) {
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(image.width) * image.height * 3);
  for (std::size_t i = 0, n = rgb.size() / 3; i < n; ++i) {
    const std::uint8_t* p = &image.pixels[i * 4];
    for (int c = 0; c < 3; ++c) {  // over black
      rgb[i * 3 + static_cast<std::size_t>(c)] =
          static_cast<std::uint8_t>((p[c] * p[3] + 127) / 255);
    }
  }
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  JpegError error{};
  const bool ok = jpeg_compress_rgb(rgb.data(), image.width, image.height,
                                    std::clamp(quality, 1, 100), &buffer, &size, &error);
  std::unique_ptr<unsigned char, decltype(&std::free)> owned(buffer, &std::free);
  if (!ok) return Error(ErrorCode::internal, std::string("JPEG encoding failed: ") + error.message);
  return std::vector<std::uint8_t>(buffer, buffer + size);
}

// Reads the header (dimensions) and, when `pixels` is set, decompresses into it as RGBA.
bool jpeg_decompress(const std::uint8_t* data, std::size_t size, std::uint64_t max_pixels,
                     RgbaImage* image, bool* too_large, JpegError* error) {
  jpeg_decompress_struct cinfo;
  cinfo.err = jpeg_std_error(&error->mgr);
  error->mgr.error_exit = jpeg_error_exit;
  error->mgr.emit_message = jpeg_silent;
  if (setjmp(error->jump) != 0) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  if (static_cast<std::uint64_t>(cinfo.image_width) * cinfo.image_height > max_pixels) {
    *too_large = true;
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  cinfo.out_color_space = JCS_EXT_RGBA;  // libjpeg-turbo extension
  jpeg_start_decompress(&cinfo);
  image->width = cinfo.output_width;
  image->height = cinfo.output_height;
  image->pixels.assign(static_cast<std::size_t>(image->width) * image->height * 4, 0);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row =
        image->pixels.data() + static_cast<std::size_t>(cinfo.output_scanline) * image->width * 4;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  const bool clean = cinfo.err->num_warnings == 0;
  if (!clean)
    std::snprintf(error->message, sizeof error->message, "the data is truncated or damaged");
  jpeg_destroy_decompress(&cinfo);
  return clean;
}

Result<RgbaImage> decode_jpeg(std::span<const std::uint8_t> bytes, std::uint64_t max_pixels) {
  RgbaImage image;
  bool too_large = false;
  JpegError error{};
  if (!jpeg_decompress(bytes.data(), bytes.size(), max_pixels, &image, &too_large, &error)) {
    if (too_large) return invalid_argument("JPEG: the image is too large");
    return corrupt_data(std::string("JPEG: ") + error.message);
  }
  return image;
}

// ---- WebP -----------------------------------------------------------------------------------

Result<std::vector<std::uint8_t>> encode_webp(const RgbaImage& image, const EncodeOptions& o) {
  std::uint8_t* out = nullptr;
  const int stride = static_cast<int>(image.width * 4);
  const auto w = static_cast<int>(image.width), h = static_cast<int>(image.height);
  const std::size_t size =
      o.lossless ? WebPEncodeLosslessRGBA(image.pixels.data(), w, h, stride, &out)
                 : WebPEncodeRGBA(image.pixels.data(), w, h, stride,
                                  static_cast<float>(std::clamp(o.quality, 1, 100)), &out);
  std::unique_ptr<std::uint8_t, decltype(&WebPFree)> owned(out, &WebPFree);
  if (size == 0 || out == nullptr) return Error(ErrorCode::internal, "WebP encoding failed");
  return std::vector<std::uint8_t>(out, out + size);
}

Result<RgbaImage> decode_webp(std::span<const std::uint8_t> bytes, std::uint64_t max_pixels) {
  int w = 0, h = 0;
  if (WebPGetInfo(bytes.data(), bytes.size(), &w, &h) == 0) {
    return corrupt_data("WebP: not a valid WebP image");
  }
  if (static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h) > max_pixels) {
    return invalid_argument("WebP: the image is too large");
  }
  RgbaImage image(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h));
  if (WebPDecodeRGBAInto(bytes.data(), bytes.size(), image.pixels.data(), image.pixels.size(),
                         w * 4) == nullptr) {
    return corrupt_data("WebP: the image data is damaged");
  }
  return image;
}

}  // namespace

bool RgbaImage::fully_transparent() const {
  for (std::size_t i = 3; i < pixels.size(); i += 4) {
    if (pixels[i] != 0) return false;
  }
  return true;
}

bool RgbaImage::fully_opaque() const {
  for (std::size_t i = 3; i < pixels.size(); i += 4) {
    if (pixels[i] != 255) return false;
  }
  return true;
}

std::string_view to_string(ImageFormat f) {
  switch (f) {
    case ImageFormat::png:
      return "png";
    case ImageFormat::jpeg:
      return "jpeg";
    case ImageFormat::webp:
      return "webp";
  }
  return "png";
}

std::string_view mime_type(ImageFormat f) {
  switch (f) {
    case ImageFormat::png:
      return "image/png";
    case ImageFormat::jpeg:
      return "image/jpeg";
    case ImageFormat::webp:
      return "image/webp";
  }
  return "application/octet-stream";
}

std::string_view file_extension(ImageFormat f) {
  return f == ImageFormat::jpeg ? std::string_view("jpg") : to_string(f);
}

Result<ImageFormat> parse_image_format(std::string_view text) {
  if (ieq(text, "png")) return ImageFormat::png;
  if (ieq(text, "jpeg") || ieq(text, "jpg")) return ImageFormat::jpeg;
  if (ieq(text, "webp")) return ImageFormat::webp;
  return invalid_argument("image format '" + std::string(text) + "' is not png, jpeg or webp");
}

Result<ImageFormat> sniff_format(std::span<const std::uint8_t> b) {
  static constexpr std::uint8_t kPng[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (b.size() >= 8 && std::equal(kPng, kPng + 8, b.begin())) return ImageFormat::png;
  if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return ImageFormat::jpeg;
  if (b.size() >= 12 && std::memcmp(b.data(), "RIFF", 4) == 0 &&
      std::memcmp(b.data() + 8, "WEBP", 4) == 0) {
    return ImageFormat::webp;
  }
  return invalid_argument("not a PNG, JPEG or WebP image (" + std::to_string(b.size()) + " bytes)");
}

Result<std::vector<std::uint8_t>> encode(const RgbaImage& image, ImageFormat format,
                                         const EncodeOptions& options) {
  if (image.width == 0 || image.height == 0 ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * image.height * 4) {
    return invalid_argument("cannot encode an image of " + std::to_string(image.width) + " × " +
                            std::to_string(image.height) + " pixels with " +
                            std::to_string(image.pixels.size()) + " bytes");
  }
  switch (format) {
    case ImageFormat::png:
      return encode_png(image, options.fast);
    case ImageFormat::jpeg:
      return encode_jpeg(image, options.quality);
    case ImageFormat::webp:
      return encode_webp(image, options);
  }
  return invalid_argument("unknown image format");
}

Result<RgbaImage> decode(std::span<const std::uint8_t> bytes, std::uint64_t max_pixels) {
  auto format = sniff_format(bytes);
  if (!format) return format.error();
  switch (*format) {
    case ImageFormat::png:
      return decode_png(bytes, max_pixels);
    case ImageFormat::jpeg:
      return decode_jpeg(bytes, max_pixels);
    case ImageFormat::webp:
      return decode_webp(bytes, max_pixels);
  }
  return invalid_argument("unknown image format");
}

}  // namespace tinstream::imagery
