// What the sources suites share: the real datasets' folder, and a whole source read in batches.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <filesystem>
#include <vector>

#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources::testing {

inline const std::filesystem::path kData = TINSTREAM_SHARED_DATA;

// Every point of `src`, read in batches of `batch` points (no read returns more).
inline Result<std::vector<SourcePoint>> read_all(PointSource& src, std::size_t batch) {
  std::vector<SourcePoint> all;
  while (true) {
    auto n = src.read(all, batch);
    if (!n.ok()) return n.error();
    if (*n == 0) break;
    EXPECT_LE(*n, batch);
  }
  return all;
}

}  // namespace tinstream::sources::testing
