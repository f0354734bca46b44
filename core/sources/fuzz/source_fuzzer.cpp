// libFuzzer target for the LAS and XYZ readers (clang only; see core/sources/CMakeLists.txt).
//   build/bin/sources_fuzzer core/sources/fuzz/corpus -max_total_time=60
// The readers take paths (they stream from files), so each input is written to a private temp
// file. The first byte picks the reader: even → LAS, odd → XYZ text.
// Properties: open/read never crash, never hang, and never return more points than the input
// could describe (LAS: 20 bytes per record at least; XYZ: one point per line).
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "tinstream/sources/point_source.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  // In memory when /dev/shm exists (a file per input: the disk would bound the rate).
  static const std::string path =
      ((std::filesystem::is_directory("/dev/shm") ? std::filesystem::path("/dev/shm")
                                                  : std::filesystem::temp_directory_path()) /
       ("tinstream_fuzz_" + std::to_string(::getpid())))
          .string();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return 0;
  std::fwrite(data + 1, 1, size - 1, f);
  std::fclose(f);
  tinstream::sources::SourceOptions options;
  options.format = (data[0] % 2 == 0) ? tinstream::sources::SourceFormat::las
                                      : tinstream::sources::SourceFormat::xyz;
  auto source = tinstream::sources::open_source(path, options);
  if (source.ok()) {
    std::vector<tinstream::sources::SourcePoint> points;
    while (true) {
      auto n = (*source)->read(points, 64);
      if (!n.ok() || *n == 0) break;
      if (points.size() > size) std::abort();
    }
  }
  return 0;
}
