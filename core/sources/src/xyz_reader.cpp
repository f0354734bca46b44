// Streaming XYZ/CSV text reader: one line at a time through a 1 MiB stdio buffer.
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string_view>

#include "binary_io.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {
namespace {

using detail::FilePtr;

constexpr std::size_t kMaxLineBytes = std::size_t{1} << 20;

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) {
    s.remove_prefix(1);
  }
  while (!s.empty() &&
         (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n')) {
    s.remove_suffix(1);
  }
  return s;
}

// Splits `line` into fields (views into `line`); returns the field count.
std::size_t split(std::string_view line, const std::optional<char>& delimiter,
                  std::vector<std::string_view>& fields) {
  fields.clear();
  if (delimiter) {
    std::size_t start = 0;
    while (true) {
      const std::size_t pos = line.find(*delimiter, start);
      fields.push_back(trim(line.substr(start, pos == std::string_view::npos ? pos : pos - start)));
      if (pos == std::string_view::npos) break;
      start = pos + 1;
    }
  } else {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      if (i >= line.size()) break;
      const std::size_t start = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
      fields.push_back(line.substr(start, i - start));
    }
  }
  return fields.size();
}

std::optional<double> parse_number(std::string_view s) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || s.empty()) return std::nullopt;
  return v;
}

class XyzSource final : public PointSource {
 public:
  XyzSource(FilePtr file, SourceInfo info, SourceOptions options)
      : file_(std::move(file)), info_(std::move(info)), options_(std::move(options)) {
    keep_.assign(256, false);
    if (options_.class_filter.classes) {
      for (std::uint8_t c : *options_.class_filter.classes) keep_[c] = true;
    } else {
      keep_.assign(256, true);
      keep_[7] = keep_[18] = false;
    }
    line_.reserve(256);
  }

  const SourceInfo& info() const override { return info_; }
  const SourceCounters& counters() const override { return counters_; }

  Result<std::size_t> read(std::vector<SourcePoint>& batch, std::size_t max_points) override {
    if (failed_) return failure_;
    std::size_t appended = 0;
    const TextLayout& t = options_.text;
    while (appended < max_points) {
      auto got = next_line();
      if (!got.ok()) return fail(got.error());
      if (!*got) break;
      const std::string_view line = trim(line_);
      if (line.empty() || line.front() == t.comment) continue;
      if (headers_left_ > 0) {
        --headers_left_;
        continue;
      }
      split(line, t.delimiter, fields_);
      const std::size_t need =
          std::max({t.x_column, t.y_column, t.z_column, t.class_column.value_or(0)}) + 1;
      const auto where = [&] { return info_.path + ": line " + std::to_string(line_no_) + ": "; };
      if (!t.header_lines && !first_data_seen_) {
        first_data_seen_ = true;
        // Automatic header detection: skip the first data line when no x/y/z field is numeric.
        bool any_numeric = false;
        for (std::size_t c : {t.x_column, t.y_column, t.z_column}) {
          if (c < fields_.size() && parse_number(fields_[c])) any_numeric = true;
        }
        if (!any_numeric) {
          info_.notes.push_back("skipped line " + std::to_string(line_no_) + " as a header");
          continue;
        }
      }
      ++counters_.records_read;
      Error bad;
      bool ok = true;
      double xyz[3] = {0, 0, 0};
      std::uint8_t cls = 0;
      if (fields_.size() < need) {
        ok = false;
        bad = corrupt_data(where() + "expected at least " + std::to_string(need) +
                           " fields, found " + std::to_string(fields_.size()));
      } else {
        const std::size_t cols[3] = {t.x_column, t.y_column, t.z_column};
        for (int a = 0; a < 3 && ok; ++a) {
          const std::string_view f = fields_[cols[a]];
          auto v = parse_number(f);
          if (!v) {
            ok = false;
            bad = corrupt_data(where() + "field " + std::to_string(cols[a] + 1) + " (" + "xyz"[a] +
                               ") is not a number: \"" + std::string(f.substr(0, 40)) + "\"");
          } else if (!std::isfinite(*v)) {
            ok = false;
            bad = corrupt_data(where() + "field " + std::to_string(cols[a] + 1) + " (" + "xyz"[a] +
                               ") is " + std::string(f.substr(0, 40)) + " (not finite)");
          } else {
            xyz[a] = *v;
          }
        }
        if (ok && t.class_column) {
          auto v = parse_number(fields_[*t.class_column]);
          if (!v || *v < 0 || *v > 255 || *v != std::floor(*v)) {
            ok = false;
            bad = corrupt_data(where() + "class field " + std::to_string(*t.class_column + 1) +
                               " is not an integer 0–255");
          } else {
            cls = static_cast<std::uint8_t>(*v);
          }
        }
      }
      if (!ok) {
        if (options_.invalid == InvalidPolicy::skip) {
          ++counters_.rejected_invalid;
          continue;
        }
        return fail(bad);
      }
      if (t.class_column && !keep_[cls]) {
        ++counters_.rejected_class;
        continue;
      }
      batch.push_back(SourcePoint{xyz[0], xyz[1], xyz[2], line_no_, cls});
      ++counters_.accepted;
      ++appended;
    }
    return appended;
  }

 private:
  // Reads the next line into line_; false at end of file.
  Result<bool> next_line() {
    line_.clear();
    std::FILE* f = file_.get();
    int c = 0;
    bool any = false;
    while ((c = getc_unlocked(f)) != EOF) {
      any = true;
      if (c == '\n') break;
      if (c == 0) {
        return corrupt_data(info_.path + ": line " + std::to_string(line_no_ + 1) +
                            ": contains a NUL byte (binary data, not text)");
      }
      line_.push_back(static_cast<char>(c));
      if (line_.size() > kMaxLineBytes) {
        return corrupt_data(info_.path + ": line " + std::to_string(line_no_ + 1) +
                            ": longer than 1 MiB (is this a text file?)");
      }
    }
    if (std::ferror(f)) {
      return io_error(info_.path + ": read error after line " + std::to_string(line_no_));
    }
    if (any) ++line_no_;
    return any;
  }

  Result<std::size_t> fail(Error e) {
    failed_ = true;
    failure_ = e;
    return e;
  }

  FilePtr file_;
  SourceInfo info_;
  SourceOptions options_;
  SourceCounters counters_;
  std::vector<bool> keep_;
  std::string line_;
  std::vector<std::string_view> fields_;
  std::uint64_t line_no_ = 0;
  std::size_t headers_left_ = 0;
  bool first_data_seen_ = false;
  bool failed_ = false;
  Error failure_;

 public:
  void set_header_lines(std::size_t n) { headers_left_ = n; }
};

}  // namespace

Result<std::unique_ptr<PointSource>> open_xyz(const std::filesystem::path& fs_path,
                                              const SourceOptions& options) {
  const std::string path = fs_path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(fs_path, ec)) {
    return not_found(path + ": cannot open: no such file");
  }
  FilePtr file(std::fopen(path.c_str(), "rb"));
  if (!file) return io_error(path + ": cannot open: " + std::strerror(errno));
  std::setvbuf(file.get(), nullptr, _IOFBF, std::size_t{1} << 20);
  SourceInfo info;
  info.path = path;
  info.format = "XYZ";
  info.notes.emplace_back("text has no CRS: the caller must give one");
  auto source = std::make_unique<XyzSource>(std::move(file), std::move(info), options);
  if (options.text.header_lines) source->set_header_lines(*options.text.header_lines);
  return std::unique_ptr<PointSource>(std::move(source));
}

}  // namespace tinstream::sources
