// tinstream/client/png.hpp — writing and reading RGBA8 images as PNG (libpng), for snapshots and
// the tests that look at them.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::client {

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // rows top to bottom, 4 bytes per pixel
};

Status write_png(const std::filesystem::path& path, const Image& image);
Result<Image> read_png(const std::filesystem::path& path);

}  // namespace tinstream::client
