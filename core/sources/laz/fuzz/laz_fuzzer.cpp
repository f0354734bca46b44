// libFuzzer target for the LAZ decoder (declared in core/sources/fuzz/CMakeLists.txt).
// Each input is a whole file: the seeds are the real LAZ files of ../shared/data (run.sh) and
// the one-point files of corpus/ (make_seeds.py), which the replay test runs in every build.
//   core/sources/laz/fuzz/run.sh build/bin/laz_fuzzer 300      # seconds
// The reader takes paths, so the input is written to a private temp file. The last byte picks
// one or two decoding threads. Properties: open/read never crash, hang or allocate without
// bound, and never return more records than the header announces.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "tinstream/sources/las_records.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const std::string path = (std::filesystem::temp_directory_path() /
                                   ("tinstream_laz_fuzz_" + std::to_string(::getpid())))
                                      .string();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return 0;
  std::fwrite(data, 1, size, f);
  std::fclose(f);
  tinstream::sources::RecordOptions options;
  options.threads = (data[size - 1] & 1) != 0 ? 2 : 1;
  options.geometry_and_class_only = (data[size - 1] & 2) != 0;
  auto reader = tinstream::sources::LasRecordReader::open(path, options);
  if (!reader.ok()) return 0;
  const std::size_t rl = (*reader)->summary().record_length;
  const std::uint64_t announced = (*reader)->summary().point_count;
  std::vector<std::uint8_t> buf(4096 * rl);
  std::uint64_t total = 0;
  // Bounded work per input: a hostile header may announce billions of points that a few bytes
  // of a highly predictable stream keep decoding.
  while (total < 2'000'000) {
    auto n = (*reader)->read(buf.data(), 4096);
    if (!n.ok() || *n == 0) break;
    total += *n;
    if (total > announced) std::abort();
  }
  if (total < 64) {  // rewinding must work after any state
    (void)(*reader)->rewind();
    (void)(*reader)->read(buf.data(), 16);
  }
  return 0;
}
