// Streaming LAS 1.0–1.4 / LAZ reader: header + VLR/EVLR scan at open, then records read (LAS) or
// decoded (LAZ, tinstream::laz) in chunks of at most kChunkBytes. Memory is O(chunk),
// independent of the point count.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <string_view>
#include <system_error>

#include "binary_io.hpp"
#include "las_format.hpp"
#include "tinstream/laz/laz_reader.hpp"
#include "tinstream/sources/las_records.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {
namespace {

using detail::FilePtr;
using detail::load_le16;
using detail::load_le64;
using detail::load_le_i32;

constexpr std::size_t kChunkBytes = std::size_t{4} << 20;
constexpr std::uint64_t kMaxWktBytes = std::uint64_t{16} << 20;

bool seek(std::FILE* f, std::uint64_t offset) {
  return fseeko(f, static_cast<off_t>(offset), SEEK_SET) == 0;
}

bool read_exact(std::FILE* f, void* dst, std::size_t n) { return std::fread(dst, 1, n, f) == n; }

std::string trim_c_string(const unsigned char* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

class LasSource final : public PointSource {
 public:
  LasSource(std::unique_ptr<LasRecordReader::Impl> records, las::Header header, SourceInfo info,
            SourceOptions options, std::optional<std::vector<bool>> keep)
      : records_(std::move(records)),
        h_(header),
        info_(std::move(info)),
        options_(std::move(options)),
        keep_(std::move(keep)) {
    chunk_records_ = std::max<std::size_t>(1, kChunkBytes / h_.record_length);
  }
  ~LasSource() override;

  const SourceInfo& info() const override { return info_; }
  const SourceCounters& counters() const override { return counters_; }

  Result<std::size_t> read(std::vector<SourcePoint>& batch, std::size_t max_points) override {
    if (failed_) return failure_;
    std::size_t appended = 0;
    while (appended < max_points) {
      if (buf_pos_ == buf_count_) {
        if (next_record_ == h_.point_count) break;
        if (auto st = refill(); !st.ok()) return fail(st.error());
      }
      const unsigned char* rec = buffer_.data() + buf_pos_ * h_.record_length;
      const std::uint64_t record = buf_first_record_ + buf_pos_ + 1;  // 1-based
      ++buf_pos_;
      ++counters_.records_read;
      if (las::record_withheld(rec, h_.point_format)) {
        ++counters_.rejected_withheld;
        continue;
      }
      const std::uint8_t cls = las::record_class(rec, h_.point_format);
      if (!(*keep_)[cls]) {
        ++counters_.rejected_class;
        continue;
      }
      SourcePoint p;
      p.x = load_le_i32(rec) * h_.scale[0] + h_.offset[0];
      p.y = load_le_i32(rec + 4) * h_.scale[1] + h_.offset[1];
      p.z = load_le_i32(rec + 8) * h_.scale[2] + h_.offset[2];
      p.record = record;
      p.classification = cls;
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        if (options_.invalid == InvalidPolicy::skip) {
          ++counters_.rejected_invalid;
          continue;
        }
        return fail(
            corrupt_data(info_.path + ": point record " + std::to_string(record) +
                         ": coordinate is not finite after scale/offset (x=" + std::to_string(p.x) +
                         ", y=" + std::to_string(p.y) + ", z=" + std::to_string(p.z) + ")"));
      }
      batch.push_back(p);
      ++counters_.accepted;
      ++appended;
    }
    return appended;
  }

  // Decides the default class filter: scans class bytes until the first ground point.
  Status choose_default_filter() {
    bool has_ground = false;
    std::uint64_t first_ground = 0;  // 1-based record number
    while (next_record_ < h_.point_count && !has_ground) {
      if (auto st = refill(); !st.ok()) return st;
      for (std::size_t i = 0; i < buf_count_; ++i) {
        const unsigned char* rec = buffer_.data() + i * h_.record_length;
        if (las::record_class(rec, h_.point_format) == 2 &&
            !las::record_withheld(rec, h_.point_format)) {
          has_ground = true;
          first_ground = buf_first_record_ + i + 1;
          break;
        }
      }
    }
    std::vector<bool> keep(256, false);
    if (has_ground) {
      keep[2] = true;
      info_.notes.push_back(
          "class filter: the file has ground points (class 2; the first is "
          "record " +
          std::to_string(first_ground) + "): keeping class 2 only");
    } else {
      std::fill(keep.begin(), keep.end(), true);
      keep[7] = keep[18] = false;
      info_.notes.emplace_back(
          "class filter: no ground points (class 2): keeping every class except noise 7 and 18");
    }
    keep_ = std::move(keep);
    // Rewind to the first record.
    next_record_ = 0;
    buf_pos_ = buf_count_ = 0;
    return rewind_records();
  }

 private:
  Status refill();
  Status rewind_records();

  Result<std::size_t> fail(Error e) {
    failed_ = true;
    failure_ = e;
    return e;
  }

  std::unique_ptr<LasRecordReader::Impl> records_;
  las::Header h_;
  SourceInfo info_;
  SourceOptions options_;
  std::optional<std::vector<bool>> keep_;  // indexed by class byte
  SourceCounters counters_;
  std::vector<unsigned char> buffer_;
  std::size_t chunk_records_ = 1;
  std::uint64_t next_record_ = 0;       // first record not yet in the buffer (0-based)
  std::uint64_t buf_first_record_ = 0;  // 0-based index of buffer_[0]
  std::size_t buf_pos_ = 0, buf_count_ = 0;
  bool failed_ = false;
  Error failure_;
};

// What the VLR/EVLR scan keeps: the CRS records, the LASzip VLR body, and the directory.
struct CrsRecords {
  std::string wkt;  // from LASF_Projection 2112 (or another user's 2112 as a fallback)
  std::string wkt_fallback;
  std::optional<las::GeoKeys> geokeys;
  std::optional<std::vector<unsigned char>> laszip;  // "laszip encoded" 22204 body
  std::vector<VlrEntry> directory;
};

// The error about one (E)VLR: "<path>: <what><detail>", e.g. "a.las: VLR 2 of 3: truncated header".
Error record_error(const std::string& path, const std::string& what, const std::string& detail) {
  return corrupt_data(path + ": " + what + detail);
}

Status inspect_record(std::FILE* f, const std::string& path, const std::string& what,
                      std::string_view user, std::uint16_t id, std::uint64_t body_offset,
                      std::uint64_t body_length, CrsRecords& out) {
  const bool projection = user == "LASF_Projection";
  if (user == laz::kLaszipUserId && id == laz::kLaszipRecordId && body_length <= 65535) {
    std::vector<unsigned char> body(static_cast<std::size_t>(body_length));
    if (!seek(f, body_offset) || !read_exact(f, body.data(), body.size())) {
      return record_error(path, what, ": cannot read the LASzip VLR body");
    }
    out.laszip = std::move(body);
  } else if (id == 2112 && body_length <= kMaxWktBytes) {
    std::vector<unsigned char> body(static_cast<std::size_t>(body_length));
    if (!seek(f, body_offset) || !read_exact(f, body.data(), body.size())) {
      return record_error(path, what, ": cannot read the WKT body");
    }
    std::string wkt = trim_c_string(body.data(), body.size());
    if (projection) {
      out.wkt = std::move(wkt);
    } else if (out.wkt_fallback.empty()) {
      out.wkt_fallback = std::move(wkt);
    }
  } else if (projection && id == 34735 && body_length <= 65535) {
    std::vector<unsigned char> body(static_cast<std::size_t>(body_length));
    if (!seek(f, body_offset) || !read_exact(f, body.data(), body.size())) {
      return record_error(path, what, ": cannot read the GeoKey directory");
    }
    auto keys = las::parse_geokeys(body, path);
    if (!keys.ok()) return keys.error();
    out.geokeys = *keys;
  }
  return {};
}

Status scan_vlrs(std::FILE* f, const las::Header& h, std::uint64_t file_size,
                 const std::string& path, CrsRecords& out) {
  std::uint64_t pos = h.header_size;
  for (std::uint32_t i = 0; i < h.vlr_count; ++i) {
    const std::string what = "VLR " + std::to_string(i + 1) + " of " + std::to_string(h.vlr_count);
    if (pos + 54 > h.offset_to_points) {
      return record_error(path, what,
                          ": its 54-byte header at byte " + std::to_string(pos) +
                              " runs past the start of point data (" +
                              std::to_string(h.offset_to_points) + ")");
    }
    unsigned char vh[54];
    if (!seek(f, pos) || !read_exact(f, vh, sizeof vh)) {
      return record_error(path, what, ": truncated header");
    }
    const std::string user = trim_c_string(vh + 2, 16);
    const std::uint16_t id = load_le16(vh + 18);
    const std::uint16_t length = load_le16(vh + 20);
    if (pos + 54 + length > h.offset_to_points) {
      return record_error(path, what,
                          " (" + user + " " + std::to_string(id) + "): its " +
                              std::to_string(length) +
                              "-byte body runs past the start of point data");
    }
    if (auto st = inspect_record(f, path, what, user, id, pos + 54, length, out); !st.ok()) {
      return st;
    }
    out.directory.push_back(VlrEntry{false, user, id, length, trim_c_string(vh + 22, 32)});
    pos += 54 + length;
  }
  if (h.version_minor >= 4 && h.evlr_count > 0) {
    pos = h.evlr_start;
    for (std::uint32_t i = 0; i < h.evlr_count; ++i) {
      const std::string what =
          "EVLR " + std::to_string(i + 1) + " of " + std::to_string(h.evlr_count);
      if (pos > file_size || file_size - pos < 60) {
        return record_error(path, what,
                            ": its 60-byte header at byte " + std::to_string(pos) +
                                " is beyond the end of the file");
      }
      unsigned char vh[60];
      if (!seek(f, pos) || !read_exact(f, vh, sizeof vh)) {
        return record_error(path, what, ": truncated header");
      }
      const std::string user = trim_c_string(vh + 2, 16);
      const std::uint16_t id = load_le16(vh + 18);
      const std::uint64_t length = load_le64(vh + 20);
      if (length > file_size - pos - 60) {
        return record_error(path, what,
                            " (" + user + " " + std::to_string(id) + "): its " +
                                std::to_string(length) +
                                "-byte body runs past the end of the file");
      }
      if (auto st = inspect_record(f, path, what, user, id, pos + 60, length, out); !st.ok()) {
        return st;
      }
      out.directory.push_back(VlrEntry{true, user, id, length, trim_c_string(vh + 28, 32)});
      pos += 60 + length;
    }
  }
  return {};
}

}  // namespace

// The records of one LAS or LAZ file: the header, what the VLR scan found, and where records
// come from (the FILE for LAS, a LazReader for LAZ).
struct LasRecordReader::Impl {
  FilePtr file;
  las::Header header;
  CrsRecords crs;
  LasFileSummary summary;
  std::unique_ptr<laz::LazReader> laz;
  std::uint64_t next_record = 0;  // LAS: first record not read yet (0-based)
  std::optional<Error> failure;

  Result<std::size_t> read(std::uint8_t* out, std::size_t max_records) {
    if (failure) return *failure;
    if (laz) {
      auto got = laz->read(out, max_records);
      if (!got.ok()) failure = got.error();
      return got;
    }
    const std::uint16_t rl = header.record_length;
    const auto n = static_cast<std::size_t>(
        std::min<std::uint64_t>(header.point_count - next_record, max_records));
    if (n == 0) return std::size_t{0};
    const std::uint64_t offset = header.offset_to_points + next_record * rl;
    if (!seek(file.get(), offset)) {
      failure = io_error(summary.path + ": point record " + std::to_string(next_record + 1) +
                         ": cannot seek to byte " + std::to_string(offset));
      return *failure;
    }
    const std::size_t got = std::fread(out, 1, n * rl, file.get());
    if (got != n * rl) {
      const std::uint64_t bad = next_record + got / rl + 1;
      failure = corrupt_data(summary.path + ": point record " + std::to_string(bad) +
                             ": file ends inside the record (truncated while being read; " +
                             std::to_string(header.point_count) + " records announced)");
      return *failure;
    }
    next_record += n;
    return n;
  }

  Status rewind() {
    failure.reset();
    next_record = 0;
    if (laz) return laz->rewind();
    return {};
  }
};

namespace {

RecordOptions record_options(const SourceOptions& options) {
  RecordOptions r;
  r.threads = options.decode_threads;
  r.geometry_and_class_only = true;  // x, y, z, class, withheld and returns are all a source uses
  return r;
}

Result<std::unique_ptr<LasRecordReader::Impl>> open_records(const std::filesystem::path& fs_path,
                                                            const RecordOptions& options) {
  const std::string path = fs_path.string();
  std::error_code ec;
  const std::uint64_t file_size = std::filesystem::file_size(fs_path, ec);
  if (ec) return not_found(path + ": cannot open: " + ec.message());
  auto r = std::make_unique<LasRecordReader::Impl>();
  r->file.reset(std::fopen(path.c_str(), "rb"));
  if (!r->file) return io_error(path + ": cannot open: " + std::strerror(errno));

  std::vector<unsigned char> head(
      static_cast<std::size_t>(std::min<std::uint64_t>(375, file_size)));
  if (!read_exact(r->file.get(), head.data(), head.size())) {
    return io_error(path + ": cannot read the LAS header");
  }
  auto header = las::parse_header(head, file_size, path);
  if (!header.ok()) return header.error();
  r->header = *header;
  const las::Header& h = r->header;
  if (auto st = scan_vlrs(r->file.get(), h, file_size, path, r->crs); !st.ok()) return st.error();

  LasFileSummary& s = r->summary;
  s.path = path;
  s.file_size = file_size;
  s.version_major = h.version_major;
  s.version_minor = h.version_minor;
  s.header_size = h.header_size;
  s.offset_to_points = h.offset_to_points;
  s.point_format = h.point_format;
  s.record_length = h.record_length;
  s.point_count = h.point_count;
  s.scale = h.scale;
  s.offset = h.offset;
  s.min = {h.min_x, h.min_y, h.min_z};
  s.max = {h.max_x, h.max_y, h.max_z};
  s.vlrs = r->crs.directory;

  if (h.compressed) {
    if (!r->crs.laszip) {
      return corrupt_data(path +
                          ": the point data format byte marks the points as LAZ-compressed, "
                          "but the file has no LASzip VLR (\"laszip encoded\" 22204)");
    }
    auto vlr = laz::parse_laszip_vlr(*r->crs.laszip, h.point_format, h.record_length,
                                     path + ": LASzip VLR");
    if (!vlr.ok()) return vlr.error();
    s.laszip = *vlr;
    laz::PointDataLayout layout;
    layout.offset_to_points = h.offset_to_points;
    layout.point_count = h.point_count;
    layout.points_end = h.points_end;
    layout.file_size = file_size;
    layout.point_format = h.point_format;
    layout.record_length = h.record_length;
    laz::ReaderOptions lo;
    lo.threads = options.threads;
    if (options.geometry_and_class_only) lo.layers = laz::LayerSelection::geometry_and_class();
    auto reader = laz::LazReader::open(fs_path, layout, *vlr, lo);
    if (!reader.ok()) return reader.error();
    r->laz = std::move(*reader);
  }
  return r;
}

}  // namespace

LasSource::~LasSource() = default;

Status LasSource::refill() {
  const std::uint64_t remaining = h_.point_count - next_record_;
  const std::size_t n =
      static_cast<std::size_t>(std::min<std::uint64_t>(remaining, chunk_records_));
  buffer_.resize(n * h_.record_length);
  std::size_t have = 0;
  while (have < n) {
    auto got = records_->read(buffer_.data() + have * h_.record_length, n - have);
    if (!got.ok()) return got.error();
    if (*got == 0) {
      return corrupt_data(info_.path + ": point record " + std::to_string(next_record_ + have + 1) +
                          ": the point data ends after " + std::to_string(next_record_ + have) +
                          " of the " + std::to_string(h_.point_count) + " records announced");
    }
    have += *got;
  }
  buf_first_record_ = next_record_;
  buf_pos_ = 0;
  buf_count_ = n;
  next_record_ += n;
  return {};
}

Status LasSource::rewind_records() { return records_->rewind(); }

LasRecordReader::LasRecordReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LasRecordReader::~LasRecordReader() = default;

Result<std::unique_ptr<LasRecordReader>> LasRecordReader::open(const std::filesystem::path& path,
                                                               const RecordOptions& options) {
  auto impl = open_records(path, options);
  if (!impl.ok()) return impl.error();
  return std::unique_ptr<LasRecordReader>(new LasRecordReader(std::move(*impl)));
}

const LasFileSummary& LasRecordReader::summary() const { return impl_->summary; }
Result<std::size_t> LasRecordReader::read(std::uint8_t* out, std::size_t max_records) {
  return impl_->read(out, max_records);
}
Status LasRecordReader::rewind() { return impl_->rewind(); }
const laz::LazReader* LasRecordReader::laz() const { return impl_->laz.get(); }

PointSource::~PointSource() = default;

Result<std::unique_ptr<PointSource>> open_las(const std::filesystem::path& fs_path,
                                              const SourceOptions& options) {
  const std::string path = fs_path.string();
  auto opened = open_records(fs_path, record_options(options));
  if (!opened.ok()) return opened.error();
  std::unique_ptr<LasRecordReader::Impl> records = std::move(*opened);
  const las::Header& h = records->header;
  CrsRecords& crs = records->crs;

  SourceInfo info;
  info.path = path;
  info.format = std::string(h.compressed ? "LAZ" : "LAS") + " " + std::to_string(h.version_major) +
                "." + std::to_string(h.version_minor) + " PDF " + std::to_string(h.point_format);
  if (const laz::LazReader* lz = records->laz.get()) {
    info.notes.push_back("LAZ: " + laz::to_string(lz->vlr().compressor) + " compressor, " +
                         std::to_string(lz->chunks().size()) + " chunk(s), decoded on " +
                         std::to_string(lz->threads()) + " thread(s)");
    for (const std::string& note : lz->notes()) info.notes.push_back("LAZ: " + note);
  }
  info.record_count = h.point_count;
  if (h.min_x <= h.max_x && h.min_y <= h.max_y && h.min_z <= h.max_z &&
      std::isfinite(h.min_x + h.max_x + h.min_y + h.max_y + h.min_z + h.max_z)) {
    info.bounds = SourceBounds{h.min_x, h.min_y, h.min_z, h.max_x, h.max_y, h.max_z};
  }
  // CRS rule: an OGC WKT VLR wins over GeoKeys (LAS 1.4 makes WKT normative for PDF 6–10, and
  // files such as autzen_trim.las carry a user-defined GeoKey set that only the WKT resolves).
  if (crs.wkt.empty() && !crs.wkt_fallback.empty()) crs.wkt = std::move(crs.wkt_fallback);
  if (crs.geokeys) {
    const las::GeoKeys& k = *crs.geokeys;
    if (k.vertical_units) {
      if (auto unit = las::linear_unit_from_epsg(*k.vertical_units)) info.z_unit = unit;
    }
    if (k.vertical_cs_type && *k.vertical_cs_type > 0 && *k.vertical_cs_type < 32767) {
      info.vertical_crs = "EPSG:" + std::to_string(*k.vertical_cs_type);
      if (*k.vertical_cs_type >= 5100 && *k.vertical_cs_type <= 5199) {
        info.notes.push_back("VerticalCSTypeGeoKey " + info.vertical_crs +
                             " is an EPSG vertical *datum* code, not a vertical CRS (a common "
                             "writer mistake; NAVD88's height CRS is EPSG:5703, or 6360 in US "
                             "feet)");
      }
    }
  }
  if (!crs.wkt.empty()) {
    info.crs = crs.wkt;
    info.crs_origin = "LAS WKT VLR";
  } else if (crs.geokeys) {
    const las::GeoKeys& k = *crs.geokeys;
    auto valid = [](const std::optional<std::uint16_t>& v) { return v && *v > 0 && *v < 32767; };
    if (valid(k.projected_cs_type)) {
      info.crs = "EPSG:" + std::to_string(*k.projected_cs_type);
    } else if (valid(k.geographic_type) && !(k.model_type && *k.model_type == 1)) {
      info.crs = "EPSG:" + std::to_string(*k.geographic_type);
    } else {
      info.notes.emplace_back(
          "GeoKeys describe a user-defined CRS that this reader does not decode; give the CRS "
          "explicitly (--crs)");
    }
    if (!info.crs.empty()) info.crs_origin = "LAS GeoKeys";
  }

  std::optional<std::vector<bool>> keep;
  if (options.class_filter.classes) {
    std::vector<bool> k(256, false);
    for (std::uint8_t c : *options.class_filter.classes) k[c] = true;
    keep = std::move(k);
  }
  const las::Header header = h;
  auto source = std::make_unique<LasSource>(std::move(records), header, std::move(info), options,
                                            std::move(keep));
  if (!options.class_filter.classes) {
    if (auto st = source->choose_default_filter(); !st.ok()) return st.error();
  }
  return std::unique_ptr<PointSource>(std::move(source));
}

}  // namespace tinstream::sources
