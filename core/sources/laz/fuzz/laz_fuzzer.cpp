// libFuzzer target for the LAZ decoder (declared in core/sources/fuzz/CMakeLists.txt).
// Each input is a whole file: the seeds are the real LAZ files of ../shared/data (run.sh) and
// the one-point files of corpus/ (make_seeds.py), which the replay test runs in every build.
//   core/sources/laz/fuzz/run.sh build/bin/laz_fuzzer 300      # seconds
// The reader takes paths, so the input is written to a memory file (InputFile). The last byte picks
// one or two decoding threads. Properties: open/read never crash, hang or allocate without
// bound, and never return more records than the header announces.
//
// Bounded work per input (the long run's rate, docs/SECURITY.md): at most kMaxPoints records are
// read (more than one chunk of the default 50,000 points, so a real file's first chunk boundary
// is crossed; a hostile header may announce billions of points that a few bytes of a highly
// predictable stream keep decoding), and two threads only when the whole chunk table holds at
// most kMaxPoints (the pipeline decodes whole chunks ahead of the reader, which a cap on reading
// would not bound). Every input announcing at most kMaxPoints is still read to its end.
#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "tinstream/laz/laz_reader.hpp"
#include "tinstream/sources/las_records.hpp"

namespace {

constexpr std::uint64_t kMaxPoints = 1 << 16;
// The read buffer holds 4096 records, fewer when records are long (up to 65,535 bytes: 4096 of
// them made a 256 MiB buffer that was zeroed for every input, half of the run's time).
constexpr std::size_t kMaxBufferBytes = 1 << 20;

std::uint64_t table_points(const tinstream::sources::LasRecordReader& reader) {
  std::uint64_t points = 0;
  if (reader.laz() != nullptr) {
    for (const auto& c : reader.laz()->chunks()) points += c.points;
  }
  return points;
}

// The reader takes a path: the input goes into a memory file (memfd, opened again through
// /proc/self/fd/N), or a private temp file where there is none. A file in /tmp cost a quarter of
// the time: truncating and closing a file on ext4 starts its write-back, on every input.
class InputFile {
 public:
  InputFile() {
    fd_ = ::memfd_create("tinstream_laz_fuzz", 0);
    if (fd_ >= 0) {
      path_ = "/proc/self/fd/" + std::to_string(fd_);
    } else {
      path_ = (std::filesystem::temp_directory_path() /
               ("tinstream_laz_fuzz_" + std::to_string(::getpid())))
                  .string();
      fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_TRUNC, 0600);
    }
  }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  ~InputFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  const std::string& path() const { return path_; }
  bool write(const std::uint8_t* data, std::size_t size) const {
    if (fd_ < 0 || ::ftruncate(fd_, 0) != 0) return false;
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = ::pwrite(fd_, data + done, size - done, static_cast<off_t>(done));
      if (n <= 0) return false;
      done += static_cast<std::size_t>(n);
    }
    return true;
  }

 private:
  int fd_ = -1;
  std::string path_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const InputFile file;
  if (!file.write(data, size)) return 0;
  const std::string& path = file.path();
  tinstream::sources::RecordOptions options;
  options.threads = (data[size - 1] & 1) != 0 ? 2 : 1;
  options.geometry_and_class_only = (data[size - 1] & 2) != 0;
  auto reader = tinstream::sources::LasRecordReader::open(path, options);
  if (!reader.ok()) return 0;
  const tinstream::laz::LazReader* laz = (*reader)->laz();
  if (laz != nullptr && laz->threads() > 1 && table_points(**reader) > kMaxPoints) {
    options.threads = 1;
    reader = tinstream::sources::LasRecordReader::open(path, options);
    if (!reader.ok()) return 0;
  }
  const std::size_t rl = std::max<std::size_t>(1, (*reader)->summary().record_length);
  const std::size_t batch = std::clamp<std::size_t>(kMaxBufferBytes / rl, 1, 4096);
  const std::uint64_t announced = (*reader)->summary().point_count;
  std::vector<std::uint8_t> buf(batch * rl);
  std::uint64_t total = 0;
  while (total < kMaxPoints) {
    auto n = (*reader)->read(buf.data(), batch);
    if (!n.ok() || *n == 0) break;
    total += *n;
    if (total > announced) std::abort();
  }
  if (total < 64) {  // rewinding must work after any state
    (void)(*reader)->rewind();
    (void)(*reader)->read(buf.data(), std::min<std::size_t>(16, batch));
  }
  return 0;
}
