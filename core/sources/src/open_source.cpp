// Format detection and small option parsers.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>

#include "binary_io.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {

namespace {
std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}
}  // namespace

Result<std::unique_ptr<PointSource>> open_source(const std::filesystem::path& path,
                                                 const SourceOptions& options) {
  switch (options.format) {
    case SourceFormat::las:
      return open_las(path, options);
    case SourceFormat::xyz:
      return open_xyz(path, options);
    case SourceFormat::raster:
      return open_raster(path, options);
    case SourceFormat::automatic:
      break;
  }
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return not_found(path.string() + ": cannot open: no such file");
  }
  const std::string ext = lower(path.extension().string());
  if (ext == ".las" || ext == ".laz") return open_las(path, options);
  if (ext == ".xyz" || ext == ".csv" || ext == ".txt" || ext == ".pts") {
    return open_xyz(path, options);
  }
  // By magic.
  detail::FilePtr f(std::fopen(path.string().c_str(), "rb"));
  char magic[4] = {0, 0, 0, 0};
  if (f && std::fread(magic, 1, 4, f.get()) == 4 && std::memcmp(magic, "LASF", 4) == 0) {
    return open_las(path, options);
  }
  return open_raster(path, options);
}

Result<LinearUnit> parse_linear_unit(const std::string& text) {
  const std::string t = lower(text);
  if (t == "m" || t == "metre" || t == "meter" || t == "metres" || t == "meters") {
    return LinearUnit{"metre", 1.0};
  }
  if (t == "ft" || t == "foot" || t == "feet" || t == "international-foot") {
    return LinearUnit{"foot", 0.3048};
  }
  if (t == "us-foot" || t == "ftus" || t == "us-ft" || t == "us survey foot" ||
      t == "us-survey-foot") {
    return LinearUnit{"US survey foot", 1200.0 / 3937.0};
  }
  return invalid_argument("unknown unit '" + text + "' (use metre, foot or us-foot)");
}

Result<std::vector<std::uint8_t>> parse_class_list(const std::string& text) {
  std::vector<std::uint8_t> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find(',', start), text.size());
    const std::string_view item = std::string_view(text).substr(start, end - start);
    unsigned value = 0;
    const auto [p, ec] = std::from_chars(item.data(), item.data() + item.size(), value);
    if (item.empty() || ec != std::errc() || p != item.data() + item.size() || value > 255) {
      return invalid_argument("bad class list '" + text + "': '" + std::string(item) +
                              "' is not a class number 0–255");
    }
    out.push_back(static_cast<std::uint8_t>(value));
    start = end + 1;
  }
  return out;
}

}  // namespace tinstream::sources
