#include "tinstream/transform/run_file.hpp"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <system_error>

namespace tinstream::transform {
namespace {

constexpr char kMagic[8] = {'T', 'I', 'N', 'R', 'U', 'N', '1', '\0'};
constexpr std::size_t kBufferRecords = 8192;

void store_u16(unsigned char* p, std::uint16_t v) {
  p[0] = static_cast<unsigned char>(v);
  p[1] = static_cast<unsigned char>(v >> 8);
}
void store_u32(unsigned char* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<unsigned char>(v >> (8 * i));
}
void store_u64(unsigned char* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<unsigned char>(v >> (8 * i));
}
void store_f64(unsigned char* p, double v) { store_u64(p, std::bit_cast<std::uint64_t>(v)); }
void store_f32(unsigned char* p, float v) { store_u32(p, std::bit_cast<std::uint32_t>(v)); }

std::uint16_t load_u16(const unsigned char* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
std::uint32_t load_u32(const unsigned char* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
std::uint64_t load_u64(const unsigned char* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
double load_f64(const unsigned char* p) { return std::bit_cast<double>(load_u64(p)); }
float load_f32(const unsigned char* p) { return std::bit_cast<float>(load_u32(p)); }

Extent empty_extent() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return Extent{inf, inf, -inf, -inf};
}

}  // namespace

void encode_run_header(const RunFileHeader& h, bool complete, unsigned char out[kRunHeaderBytes]) {
  std::memset(out, 0, kRunHeaderBytes);
  std::memcpy(out, kMagic, 8);
  store_u32(out + 8, kRunHeaderBytes);
  store_u32(out + 12, kRunRecordBytes);
  store_u64(out + 16, h.point_count);
  out[24] = h.projection == geo::Projection::ellipsoidal ? 1 : 0;
  out[25] = complete ? 1 : 0;
  store_f64(out + 32, h.mercator.min_x);
  store_f64(out + 40, h.mercator.min_y);
  store_f64(out + 48, h.mercator.max_x);
  store_f64(out + 56, h.mercator.max_y);
  store_f64(out + 64, h.min_z);
  store_f64(out + 72, h.max_z);
  store_f64(out + 80, h.lonlat.min_x);
  store_f64(out + 88, h.lonlat.min_y);
  store_f64(out + 96, h.lonlat.max_x);
  store_f64(out + 104, h.lonlat.max_y);
  store_u32(out + 112, h.input_count);
}

Result<RunFileHeader> decode_run_header(const unsigned char in[kRunHeaderBytes],
                                        const std::string& path) {
  if (std::memcmp(in, kMagic, 8) != 0) {
    return corrupt_data(path + ": not a tinstream run file (bad magic)");
  }
  if (load_u32(in + 8) != kRunHeaderBytes || load_u32(in + 12) != kRunRecordBytes) {
    return unsupported(path + ": run file header/record sizes " + std::to_string(load_u32(in + 8)) +
                       "/" + std::to_string(load_u32(in + 12)) + " are not 128/32");
  }
  if (in[25] != 1) {
    return corrupt_data(path + ": run file is incomplete (its writer never committed it)");
  }
  if (in[24] > 1) return corrupt_data(path + ": run file has an unknown projection code");
  RunFileHeader h;
  h.point_count = load_u64(in + 16);
  h.projection = in[24] == 1 ? geo::Projection::ellipsoidal : geo::Projection::spherical;
  h.mercator = Extent{load_f64(in + 32), load_f64(in + 40), load_f64(in + 48), load_f64(in + 56)};
  h.min_z = load_f64(in + 64);
  h.max_z = load_f64(in + 72);
  h.lonlat = Extent{load_f64(in + 80), load_f64(in + 88), load_f64(in + 96), load_f64(in + 104)};
  h.input_count = load_u32(in + 112);
  return h;
}

void encode_run_point(const RunPoint& p, unsigned char out[kRunRecordBytes]) {
  store_f64(out, p.x);
  store_f64(out + 8, p.y);
  store_f64(out + 16, p.z);
  store_f32(out + 24, p.weight);
  store_u16(out + 28, p.input);
  out[30] = p.classification;
  out[31] = 0;
}

RunPoint decode_run_point(const unsigned char in[kRunRecordBytes]) {
  RunPoint p;
  p.x = load_f64(in);
  p.y = load_f64(in + 8);
  p.z = load_f64(in + 16);
  p.weight = load_f32(in + 24);
  p.input = load_u16(in + 28);
  p.classification = in[30];
  return p;
}

// ---- header -------------------------------------------------------------------------------

RunHeaderBuilder::RunHeaderBuilder(geo::Projection projection, std::uint32_t input_count) {
  header_.projection = projection;
  header_.input_count = input_count;
  header_.mercator = empty_extent();
  header_.lonlat = empty_extent();
  header_.min_z = std::numeric_limits<double>::infinity();
  header_.max_z = -std::numeric_limits<double>::infinity();
}

void RunHeaderBuilder::add(std::span<const RunPoint> points, std::span<const geo::LonLat> lonlat) {
  Extent& m = header_.mercator;
  for (const RunPoint& p : points) {
    m.min_x = std::min(m.min_x, p.x), m.max_x = std::max(m.max_x, p.x);
    m.min_y = std::min(m.min_y, p.y), m.max_y = std::max(m.max_y, p.y);
    header_.min_z = std::min(header_.min_z, p.z);
    header_.max_z = std::max(header_.max_z, p.z);
  }
  Extent& e = header_.lonlat;
  for (const geo::LonLat& g : lonlat) {
    e.min_x = std::min(e.min_x, g.lon), e.max_x = std::max(e.max_x, g.lon);
    e.min_y = std::min(e.min_y, g.lat), e.max_y = std::max(e.max_y, g.lat);
  }
  header_.point_count += points.size();
}

// ---- writer -------------------------------------------------------------------------------

Result<RunFileWriter> RunFileWriter::create(const std::filesystem::path& path,
                                            geo::Projection projection, std::uint32_t input_count) {
  RunFileWriter w;
  w.final_ = path;
  w.partial_ = path;
  w.partial_ += ".partial-" + std::to_string(::getpid());
  w.file_.reset(std::fopen(w.partial_.c_str(), "wb"));
  if (!w.file_) {
    return io_error(w.partial_.string() + ": cannot create the run file: " + std::strerror(errno));
  }
  w.header_ = RunHeaderBuilder(projection, input_count);
  unsigned char head[kRunHeaderBytes];
  encode_run_header(w.header_.header(), false, head);
  if (std::fwrite(head, 1, sizeof head, w.file_.get()) != sizeof head) {
    w.abandon();
    return io_error(w.partial_.string() + ": cannot write: " + std::strerror(errno));
  }
  return w;
}

RunFileWriter::RunFileWriter(RunFileWriter&& o) noexcept
    : file_(std::move(o.file_)),
      final_(std::move(o.final_)),
      partial_(std::move(o.partial_)),
      header_(o.header_),
      buffer_(std::move(o.buffer_)) {
  o.partial_.clear();
}

RunFileWriter& RunFileWriter::operator=(RunFileWriter&& o) noexcept {
  if (this != &o) {
    abandon();
    file_ = std::move(o.file_);
    final_ = std::move(o.final_);
    partial_ = std::move(o.partial_);
    header_ = o.header_;
    buffer_ = std::move(o.buffer_);
    o.partial_.clear();
  }
  return *this;
}

RunFileWriter::~RunFileWriter() { abandon(); }

void RunFileWriter::abandon() {
  if (file_) {
    file_.reset();
    std::error_code ec;
    std::filesystem::remove(partial_, ec);
  }
}

Status RunFileWriter::append(std::span<const RunPoint> points,
                             std::span<const geo::LonLat> lonlat) {
  if (!file_) return Error(ErrorCode::internal, "run file writer used after commit or failure");
  buffer_.resize(std::min(points.size(), kBufferRecords) * kRunRecordBytes);
  std::size_t i = 0;
  while (i < points.size()) {
    const std::size_t n = std::min(points.size() - i, kBufferRecords);
    for (std::size_t k = 0; k < n; ++k) {
      encode_run_point(points[i + k], buffer_.data() + k * kRunRecordBytes);
    }
    if (std::fwrite(buffer_.data(), kRunRecordBytes, n, file_.get()) != n) {
      const std::string why = std::strerror(errno);
      abandon();
      return io_error(partial_.string() + ": cannot write (disk full?): " + why);
    }
    header_.add(points.subspan(i, n), lonlat.empty() ? lonlat : lonlat.subspan(i, n));
    i += n;
  }
  return {};
}

Result<RunFileHeader> RunFileWriter::commit(bool durable) {
  if (!file_) return Error(ErrorCode::internal, "run file writer committed twice or after failure");
  unsigned char head[kRunHeaderBytes];
  encode_run_header(header_.header(), true, head);
  std::FILE* f = file_.get();
  if (std::fflush(f) != 0 || std::fseek(f, 0, SEEK_SET) != 0 ||
      std::fwrite(head, 1, sizeof head, f) != sizeof head || std::fflush(f) != 0 ||
      (durable && ::fsync(fileno(f)) != 0)) {
    const std::string why = std::strerror(errno);
    abandon();
    return io_error(partial_.string() + ": cannot finish the run file: " + why);
  }
  if (std::fclose(file_.release()) != 0) {
    const std::string why = std::strerror(errno);
    std::error_code ec;
    std::filesystem::remove(partial_, ec);
    return io_error(partial_.string() + ": cannot close the run file: " + why);
  }
  std::error_code ec;
  std::filesystem::rename(partial_, final_, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(partial_, ignored);
    return io_error(final_.string() +
                    ": cannot rename the finished run file into place: " + ec.message());
  }
  return header_.header();
}

// ---- reader -------------------------------------------------------------------------------

RunFileReader::RunFileReader(RunFileReader&&) noexcept = default;
RunFileReader& RunFileReader::operator=(RunFileReader&&) noexcept = default;
RunFileReader::~RunFileReader() = default;

Result<RunFileReader> RunFileReader::open(const std::filesystem::path& path) {
  RunFileReader r;
  r.path_ = path;
  std::error_code ec;
  const std::uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) return not_found(path.string() + ": cannot open the run file: " + ec.message());
  r.file_.reset(std::fopen(path.c_str(), "rb"));
  if (!r.file_) return io_error(path.string() + ": cannot open: " + std::strerror(errno));
  unsigned char head[kRunHeaderBytes];
  if (size < kRunHeaderBytes || std::fread(head, 1, sizeof head, r.file_.get()) != sizeof head) {
    return corrupt_data(path.string() + ": run file shorter than its 128-byte header");
  }
  auto h = decode_run_header(head, path.string());
  if (!h.ok()) return h.error();
  r.header_ = *h;
  const std::uint64_t body = size - kRunHeaderBytes;
  if (body % kRunRecordBytes != 0 || body / kRunRecordBytes != r.header_.point_count) {
    return corrupt_data(path.string() + ": run file header says " +
                        std::to_string(r.header_.point_count) + " points but the file holds " +
                        std::to_string(body) + " bytes of records");
  }
  return r;
}

Result<std::size_t> RunFileReader::read(std::vector<RunPoint>& out, std::size_t max_points) {
  const std::uint64_t left = header_.point_count - next_;
  const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, max_points));
  if (n == 0) return std::size_t{0};
  buffer_.resize(n * kRunRecordBytes);
  if (std::fread(buffer_.data(), kRunRecordBytes, n, file_.get()) != n) {
    return io_error(path_.string() + ": run file record " + std::to_string(next_ + 1) +
                    ": read failed (file changed underneath?)");
  }
  out.reserve(out.size() + n);
  for (std::size_t i = 0; i < n; ++i)
    out.push_back(decode_run_point(buffer_.data() + i * kRunRecordBytes));
  next_ += n;
  return n;
}

Status RunFileReader::rewind() {
  if (std::fseek(file_.get(), static_cast<long>(kRunHeaderBytes), SEEK_SET) != 0) {
    return io_error(path_.string() + ": cannot seek");
  }
  next_ = 0;
  return {};
}

}  // namespace tinstream::transform
