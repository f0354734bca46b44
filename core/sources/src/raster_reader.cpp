// A GDAL raster as points: one point per cell centre of one band, NODATA and NaN cells
// skipped, read a strip of block-height rows at a time (memory: width × block height doubles).
// What GDAL may open, and how big, is the caller's RasterPolicy (point_source.hpp): checked here
// before GDAL opens a file (the driver, a VRT's XML and every file it names) and before any buffer
// is allocated (the raster's and its blocks' sizes).
#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_minixml.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <set>
#include <string_view>

#include "tinstream/sources/point_source.hpp"

namespace tinstream::sources {
namespace {

struct DatasetCloser {
  void operator()(void* ds) const {
    if (ds != nullptr) GDALClose(static_cast<GDALDatasetH>(ds));
  }
};
using DatasetPtr = std::unique_ptr<void, DatasetCloser>;

// Silences GDAL's default stderr printing for the current thread while in scope; the last
// message is read with CPLGetLastErrorMsg().
class QuietGdalErrors {
 public:
  QuietGdalErrors() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdalErrors() { CPLPopErrorHandler(); }
  QuietGdalErrors(const QuietGdalErrors&) = delete;
  QuietGdalErrors& operator=(const QuietGdalErrors&) = delete;
};

std::string last_gdal_error() {
  const char* m = CPLGetLastErrorMsg();
  return (m != nullptr && *m != 0) ? std::string(m) : std::string("no detail from GDAL");
}

std::optional<LinearUnit> unit_from_gdal(const char* unit) {
  if (unit == nullptr) return std::nullopt;
  const std::string u(unit);
  if (u == "m" || u == "metre" || u == "meter" || u == "metres" || u == "meters") {
    return LinearUnit{"metre", 1.0};
  }
  if (u == "ft" || u == "foot" || u == "feet") return LinearUnit{"foot", 0.3048};
  if (u == "US survey foot" || u == "ftUS" || u == "us-ft") {
    return LinearUnit{"US survey foot", 1200.0 / 3937.0};
  }
  return std::nullopt;
}

// NODATA compared the way GDAL's own nodata mask does: in the band's data type. A Float32 band
// whose NODATA is stored as the text -3.399999952144364e+38 (gdal_translate -of VRT of
// -3.4e38) holds cells equal to that value rounded to float, never to the double itself.
class NodataMatch {
 public:
  NodataMatch() = default;
  NodataMatch(GDALRasterBandH band, GDALDataType type) {
    int has = 0;
    if (type == GDT_Int64 || type == GDT_UInt64) {
      const double v = type == GDT_Int64
                           ? static_cast<double>(GDALGetRasterNoDataValueAsInt64(band, &has))
                           : static_cast<double>(GDALGetRasterNoDataValueAsUInt64(band, &has));
      if (has != 0) kind_ = Kind::exact, value_ = v;
      return;
    }
    const double nd = GDALGetRasterNoDataValue(band, &has);
    if (has == 0 || std::isnan(nd)) return;  // NaN cells are skipped anyway
    if (type == GDT_Float64) {
      kind_ = Kind::exact, value_ = nd;
      return;
    }
    // Out of the type's range (or, for integers, not an integer) no cell can hold it: nothing
    // matches, as in GDAL's mask. Float32 compares with the value rounded to float.
    int clamped = 0, rounded = 0;
    const double in_type = GDALAdjustValueToDataType(type, nd, &clamped, &rounded);
    if (clamped != 0) return;
    if (type == GDT_Float32) {
      kind_ = Kind::as_float, float_ = static_cast<float>(in_type);
    } else if (rounded == 0) {
      kind_ = Kind::exact, value_ = nd;
    }
  }
  // `v`: the cell as read (GDT_Float64, exact for every type but 64-bit integers).
  bool operator()(double v) const {
    switch (kind_) {
      case Kind::none:
        return false;
      case Kind::exact:
        return v == value_;
      case Kind::as_float:
        return static_cast<float>(v) == float_;
    }
    return false;
  }
  bool any() const { return kind_ != Kind::none; }

 private:
  enum class Kind { none, exact, as_float };
  Kind kind_ = Kind::none;
  double value_ = 0;
  float float_ = 0;
};

class RasterSource final : public PointSource {
 public:
  RasterSource(DatasetPtr ds, GDALRasterBandH band, std::array<double, 6> gt, NodataMatch nodata,
               SourceInfo info, SourceOptions options)
      : ds_(std::move(ds)),
        band_(band),
        gt_(gt),
        nodata_(nodata),
        info_(std::move(info)),
        options_(std::move(options)) {
    width_ = GDALGetRasterXSize(static_cast<GDALDatasetH>(ds_.get()));
    height_ = GDALGetRasterYSize(static_cast<GDALDatasetH>(ds_.get()));
    int has = 0;
    const double scale = GDALGetRasterScale(band_, &has);
    if (has != 0 && std::isfinite(scale) && scale != 0) scale_ = scale;
    const double offset = GDALGetRasterOffset(band_, &has);
    if (has != 0 && std::isfinite(offset)) offset_ = offset;
    int bx = 0, by = 0;
    GDALGetBlockSize(band_, &bx, &by);
    strip_rows_ = std::clamp(by, 1, std::max(1, (1 << 22) / std::max(1, width_)));
  }

  const SourceInfo& info() const override { return info_; }
  const SourceCounters& counters() const override { return counters_; }

  Result<std::size_t> read(std::vector<SourcePoint>& batch, std::size_t max_points) override {
    if (failed_) return failure_;
    std::size_t appended = 0;
    while (appended < max_points) {
      if (pos_ == strip_.size()) {
        if (next_row_ >= height_) break;
        if (auto st = load_strip(); !st.ok()) {
          failed_ = true;
          failure_ = st.error();
          return failure_;
        }
      }
      const std::size_t i = pos_++;
      const int row = strip_row0_ + static_cast<int>(i / static_cast<std::size_t>(width_));
      const int col = static_cast<int>(i % static_cast<std::size_t>(width_));
      ++counters_.records_read;
      const double v = strip_[i];
      if (std::isnan(v) || nodata_(v)) {
        ++counters_.rejected_nodata;
        continue;
      }
      if (!std::isfinite(v)) {
        if (options_.invalid == InvalidPolicy::skip) {
          ++counters_.rejected_invalid;
          continue;
        }
        failed_ = true;
        failure_ = corrupt_data(info_.path + ": cell row " + std::to_string(row) + " column " +
                                std::to_string(col) + ": value is infinite");
        return failure_;
      }
      const double cx = col + 0.5, cy = row + 0.5;
      SourcePoint p;
      p.x = gt_[0] + cx * gt_[1] + cy * gt_[2];
      p.y = gt_[3] + cx * gt_[4] + cy * gt_[5];
      p.z = v * scale_ + offset_;  // the band's scale/offset (1 and 0 unless the file says)
      p.record = static_cast<std::uint64_t>(row) * static_cast<std::uint64_t>(width_) +
                 static_cast<std::uint64_t>(col) + 1;
      batch.push_back(p);
      ++counters_.accepted;
      ++appended;
    }
    return appended;
  }

 private:
  Status load_strip() {
    const int rows = std::min(strip_rows_, height_ - next_row_);
    strip_.resize(static_cast<std::size_t>(rows) * static_cast<std::size_t>(width_));
    QuietGdalErrors quiet;
    const CPLErr err = GDALRasterIO(band_, GF_Read, 0, next_row_, width_, rows, strip_.data(),
                                    width_, rows, GDT_Float64, 0, 0);
    if (err != CE_None) {
      return corrupt_data(info_.path + ": rows " + std::to_string(next_row_) + "–" +
                          std::to_string(next_row_ + rows - 1) +
                          ": cannot read: " + last_gdal_error());
    }
    strip_row0_ = next_row_;
    next_row_ += rows;
    pos_ = 0;
    return {};
  }

  DatasetPtr ds_;
  GDALRasterBandH band_;
  std::array<double, 6> gt_;
  NodataMatch nodata_;  // compared with the raw value, before scale/offset
  double scale_ = 1, offset_ = 0;
  SourceInfo info_;
  SourceOptions options_;
  SourceCounters counters_;
  int width_ = 0, height_ = 0, strip_rows_ = 1;
  int next_row_ = 0, strip_row0_ = 0;
  std::vector<double> strip_;
  std::size_t pos_ = 0;
  bool failed_ = false;
  Error failure_;
};

std::string crs_of(GDALDatasetH ds) {
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
  if (srs == nullptr) return {};
  // Prefer an authority code ("EPSG:4326"): short, and PROJ resolves it fully.
  const char* name = OSRGetAuthorityName(srs, nullptr);
  const char* code = OSRGetAuthorityCode(srs, nullptr);
  if (name != nullptr && code != nullptr && std::string(name) == "EPSG") {
    return std::string("EPSG:") + code;
  }
  char* wkt = nullptr;
  const char* opts[] = {"FORMAT=WKT2_2019", nullptr};
  if (OSRExportToWktEx(srs, &wkt, opts) != OGRERR_NONE || wkt == nullptr) {
    CPLFree(wkt);
    return {};
  }
  std::string out(wkt);
  CPLFree(wkt);
  return out;
}

}  // namespace

namespace {

namespace fs = std::filesystem;

// Once per process: every driver registered (the per-open allow-list picks among them), GDAL's
// network file systems limited to no extension at all, Python in VRTs off.
void register_gdal() {
  static std::once_flag registered;
  std::call_once(registered, [] {
    GDALAllRegister();
    CPLSetConfigOption("CPL_VSIL_CURL_ALLOWED_EXTENSIONS", ".tinstream-no-network");
    CPLSetConfigOption("GDAL_VRT_ENABLE_PYTHON", "NO");
  });
}

// A null-terminated list of C strings over `names` (for GDALOpenEx / GDALIdentifyDriverEx).
class DriverList {
 public:
  DriverList(const std::vector<std::string>& names, bool with_vrt) {
    for (const auto& n : names) {
      if (with_vrt || n != "VRT") names_.push_back(n.c_str());
    }
    names_.push_back(nullptr);
  }
  const char* const* get() const { return names_.data(); }
  bool empty() const { return names_.size() == 1; }
  std::string joined() const {
    std::string out;
    for (const char* n : names_) {
      if (n != nullptr) out += (out.empty() ? "" : ", ") + std::string(n);
    }
    return out;
  }

 private:
  std::vector<const char*> names_;
};

bool starts_with(std::string_view s, std::string_view prefix) {
  return s.substr(0, prefix.size()) == prefix;
}

// `file` resolved (symlinks followed) to a regular file, under policy.root when it is set.
// `what` names the file in errors ("ingest source", "VRT source 'x'").
Result<fs::path> confined_file(const fs::path& file, const RasterPolicy& policy,
                               const std::string& what) {
  const std::string text = file.string();
  if (starts_with(text, "/vsi") || text.find("://") != std::string::npos) {
    return unsupported(what + " " + text +
                       ": GDAL virtual file systems and URLs (/vsi…, …://) are not read");
  }
  std::error_code ec;
  const fs::path real = fs::canonical(file, ec);
  if (ec) return not_found(what + " " + text + ": cannot open: no such file");
  if (!fs::is_regular_file(real, ec)) return unsupported(what + " " + text + ": not a file");
  if (!policy.root.empty()) {
    const fs::path root = fs::canonical(policy.root, ec);
    if (ec) return not_found("data root " + policy.root.string() + " does not exist");
    // Inside when every component of the root is the same leading component of the file.
    if (std::mismatch(root.begin(), root.end(), real.begin(), real.end()).first != root.end()) {
      return unsupported(what + " " + text + " lies outside the data root");
    }
  }
  return real;
}

// The raster's and its band's sizes against the policy, before anything is allocated for them.
Status check_size(GDALDatasetH ds, const RasterPolicy& policy, const std::string& what) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  if (w < 1 || h < 1) return unsupported(what + ": the raster is empty");
  if (w > policy.max_width || h > policy.max_height ||
      static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h) > policy.max_cells) {
    return unsupported(what + ": " + std::to_string(w) + " × " + std::to_string(h) +
                       " cells exceed the raster limits (" + std::to_string(policy.max_width) +
                       " × " + std::to_string(policy.max_height) + ", " +
                       std::to_string(policy.max_cells) + " cells)");
  }
  for (int b = 1; b <= GDALGetRasterCount(ds); ++b) {
    GDALRasterBandH band = GDALGetRasterBand(ds, b);
    const GDALDataType type = GDALGetRasterDataType(band);
    if (type == GDT_Unknown || GDALDataTypeIsComplex(type) != 0) {
      return unsupported(what + ": band " + std::to_string(b) + " holds " +
                         GDALGetDataTypeName(type) + " values, not heights");
    }
    int bx = 0, by = 0;
    GDALGetBlockSize(band, &bx, &by);
    const auto bytes = static_cast<std::uint64_t>(std::max(bx, 0)) *
                       static_cast<std::uint64_t>(std::max(by, 0)) *
                       static_cast<std::uint64_t>(GDALGetDataTypeSizeBytes(type));
    if (bytes > policy.max_block_bytes) {
      return unsupported(what + ": band " + std::to_string(b) + " has blocks of " +
                         std::to_string(bx) + " × " + std::to_string(by) + " cells (" +
                         std::to_string(bytes) + " bytes; the limit is " +
                         std::to_string(policy.max_block_bytes) + ")");
    }
  }
  return {};
}

struct XmlCloser {
  void operator()(CPLXMLNode* n) const { CPLDestroyXMLNode(n); }
};
using XmlPtr = std::unique_ptr<CPLXMLNode, XmlCloser>;

// The VRT elements a mosaic or a subset of DEM tiles needs (what gdal_translate -of VRT and
// gdalbuildvrt write); any other element refuses the VRT.
const std::set<std::string, std::less<>>& vrt_elements() {
  static const std::set<std::string, std::less<>> allowed = {
      // dataset
      "VRTDataset", "SRS", "GeoTransform", "Metadata", "MDI", "VRTRasterBand", "OverviewList",
      "BlockXSize", "BlockYSize",
      // band
      "NoDataValue", "HideNoDataValue", "ColorInterp", "Description", "UnitType", "Offset", "Scale",
      "CategoryNames", "Category", "ColorTable", "Entry", "SimpleSource", "ComplexSource",
      "AveragedSource",
      // source
      "SourceFilename", "SourceBand", "SourceProperties", "SrcRect", "DstRect", "NODATA",
      "UseMaskBand", "ScaleOffset", "ScaleRatio", "Exponent", "SrcMin", "SrcMax", "DstMin",
      "DstMax", "LUT", "ColorTableComponent"};
  return allowed;
}

// A VRT SRS element: WKT or an authority code, nothing GDAL would read as a file name or a
// PROJ string with init files and grids.
bool plain_srs(std::string_view srs) {
  const auto bracket = srs.find('[');
  bool wkt = bracket != std::string_view::npos && bracket > 0;
  for (std::size_t i = 0; wkt && i < bracket; ++i) {
    const char c = srs[i];
    wkt = (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  }
  std::string upper(srs);
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (wkt) return upper.find("EXTENSION[") == std::string::npos;
  const auto colon = srs.find(':');
  if (colon == std::string_view::npos || colon == 0) return false;
  for (std::size_t i = 0; i < srs.size(); ++i) {
    const char c = srs[i];
    if (i != colon && !std::isalnum(static_cast<unsigned char>(c)) && c != '+') return false;
  }
  return true;
}

class VrtCheck {
 public:
  VrtCheck(const fs::path& vrt, const RasterPolicy& policy)
      : vrt_(vrt), policy_(policy), sources_(policy.drivers, false) {}

  Status run() {
    std::error_code ec;
    const auto bytes = fs::file_size(vrt_, ec);
    if (ec) return io_error(name() + ": cannot read: " + ec.message());
    if (bytes > policy_.max_vrt_bytes) {
      return unsupported(name() + ": a VRT of " + std::to_string(bytes) + " bytes (the limit is " +
                         std::to_string(policy_.max_vrt_bytes) + ")");
    }
    std::ifstream in(vrt_, std::ios::binary);
    std::string text(static_cast<std::size_t>(bytes), '\0');
    if (!in.read(text.data(), static_cast<std::streamsize>(text.size()))) {
      return io_error(name() + ": cannot read");
    }
    if (text.find('\0') != std::string::npos) return unsupported(name() + ": not a VRT (NUL)");
    XmlPtr root(CPLParseXMLString(text.c_str()));
    if (!root) return corrupt_data(name() + ": not valid XML: " + last_gdal_error());
    bool dataset = false;
    for (const CPLXMLNode* n = root.get(); n != nullptr; n = n->psNext) {
      if (n->eType == CXT_Element && std::strcmp(n->pszValue, "?xml") == 0) continue;
      if (n->eType == CXT_Comment) continue;
      if (n->eType != CXT_Element || std::strcmp(n->pszValue, "VRTDataset") != 0 || dataset) {
        return unsupported(name() + ": a VRT holds one VRTDataset and nothing else");
      }
      dataset = true;
      if (Status s = element(n); !s) return s;
    }
    if (!dataset) return unsupported(name() + ": no VRTDataset element");
    return {};
  }

 private:
  std::string name() const { return vrt_.string(); }

  Status element(const CPLXMLNode* e) {
    const std::string_view tag = e->pszValue;
    if (!vrt_elements().contains(tag)) {
      return unsupported(name() + ": VRT element <" + std::string(tag) +
                         "> is not accepted for ingest (only plain mosaics and subsets: no raw, "
                         "derived, warped or pansharpened bands, masks, overviews, GCPs or open "
                         "options)");
    }
    for (const CPLXMLNode* c = e->psChild; c != nullptr; c = c->psNext) {
      if (c->eType == CXT_Attribute) {
        if (std::strcmp(c->pszValue, "subClass") == 0) {
          return unsupported(name() + ": VRT <" + std::string(tag) + " subClass=\"" +
                             CPLGetXMLValue(c, nullptr, "") +
                             "\"> is not accepted for ingest (only plain VRT bands)");
        }
      } else if (c->eType == CXT_Element) {
        if (Status s = element(c); !s) return s;
      } else if (c->eType == CXT_Literal) {
        return unsupported(name() + ": VRT holds a literal (<!DOCTYPE …>) ");
      }
    }
    if (tag == "SRS" && !plain_srs(CPLGetXMLValue(e, nullptr, ""))) {
      return unsupported(name() + ": VRT <SRS> must be WKT without EXTENSION or an authority code");
    }
    if (tag == "SourceFilename") return source(e);
    return {};
  }

  Status source(const CPLXMLNode* e) {
    const std::string text = CPLGetXMLValue(e, nullptr, "");
    const bool relative = std::strcmp(CPLGetXMLValue(e, "relativeToVRT", "0"), "1") == 0;
    const std::string what = name() + ": VRT source '" + text + "'";
    if (text.empty() || starts_with(text, "/vsi") || text.find("://") != std::string::npos ||
        text.find('<') != std::string::npos) {
      return unsupported(what + ": VRT sources are local files (no /vsi…, URL or inline VRT)");
    }
    fs::path file(text);
    if (relative) {
      file = vrt_.parent_path() / file;
    } else if (!file.is_absolute()) {
      return unsupported(what + ": a source not relative to the VRT must be an absolute path");
    }
    auto real = confined_file(file, policy_, what + ":");
    if (!real) return real.error();
    // GDAL opens the source with every registered driver: the first that recognises it must be
    // one of ours (not VRT: sources are never VRTs themselves).
    QuietGdalErrors quiet;
    GDALDriverH ours = GDALIdentifyDriverEx(real->c_str(), GDAL_OF_RASTER, sources_.get(), nullptr);
    GDALDriverH any = GDALIdentifyDriverEx(real->c_str(), GDAL_OF_RASTER, nullptr, nullptr);
    if (ours == nullptr || ours != any) {
      return unsupported(what + ": not a raster of the formats allowed for ingest (" +
                         sources_.joined() + ")");
    }
    DatasetPtr ds(GDALOpenEx(real->c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, sources_.get(),
                             nullptr, nullptr));
    if (!ds) return unsupported(what + ": GDAL cannot open it: " + last_gdal_error());
    return check_size(static_cast<GDALDatasetH>(ds.get()), policy_, what);
  }

  fs::path vrt_;
  const RasterPolicy& policy_;
  DriverList sources_;  // the policy's drivers but VRT
};

}  // namespace

Result<std::unique_ptr<PointSource>> open_raster(const std::filesystem::path& fs_path,
                                                 const SourceOptions& options) {
  register_gdal();
  const std::string path = fs_path.string();
  const RasterPolicy& policy = options.raster;
  auto real = confined_file(fs_path, policy, "raster");
  if (!real) {
    // Keep the plain message for the common case of a missing file.
    if (real.error().code == ErrorCode::not_found) {
      return not_found(path + ": cannot open: no such file");
    }
    return Error(real.error().code, path + ": " + real.error().message);
  }
  const DriverList drivers(policy.drivers, true);
  if (drivers.empty()) return unsupported(path + ": no GDAL driver is allowed for ingest");

  QuietGdalErrors quiet;
  GDALDriverH driver = GDALIdentifyDriverEx(real->c_str(), GDAL_OF_RASTER, drivers.get(), nullptr);
  if (driver == nullptr) {
    return unsupported(path +
                       ": not a LAS file, and not a raster of the formats allowed for ingest (" +
                       drivers.joined() + ")");
  }
  if (std::strcmp(GDALGetDriverShortName(driver), "VRT") == 0) {
    if (Status s = VrtCheck(*real, policy).run(); !s) return s.error();
  }
  DatasetPtr ds(GDALOpenEx(real->c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, drivers.get(), nullptr,
                           nullptr));
  if (!ds) {
    return unsupported(
        path + ": not a LAS file, and GDAL cannot open it as a raster: " + last_gdal_error());
  }
  auto h = static_cast<GDALDatasetH>(ds.get());
  const int bands = GDALGetRasterCount(h);
  if (options.raster_band < 1 || options.raster_band > bands) {
    return invalid_argument(path + ": band " + std::to_string(options.raster_band) +
                            " requested, the raster has " + std::to_string(bands));
  }
  if (Status s = check_size(h, policy, path); !s) return s.error();
  GDALRasterBandH band = GDALGetRasterBand(h, options.raster_band);
  std::array<double, 6> gt{};
  if (GDALGetGeoTransform(h, gt.data()) != CE_None) {
    return unsupported(path + ": the raster has no geotransform (not georeferenced)");
  }
  const NodataMatch nodata(band, GDALGetRasterDataType(band));

  SourceInfo info;
  info.path = path;
  GDALDriverH opened = GDALGetDatasetDriver(h);
  info.format = std::string("GDAL ") + (opened ? GDALGetDriverShortName(opened) : "raster");
  info.crs = crs_of(h);
  if (!info.crs.empty()) {
    info.crs_origin = "GDAL";
  } else {
    info.notes.emplace_back(
        "the raster has no CRS (ESRI ASCII grids carry none without a .prj): "
        "the caller must give one (--crs)");
  }
  info.z_unit = unit_from_gdal(GDALGetRasterUnitType(band));
  const int w = GDALGetRasterXSize(h), ht = GDALGetRasterYSize(h);
  info.record_count = static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(ht);
  if (gt[2] == 0 && gt[4] == 0) {
    const double x0 = gt[0] + 0.5 * gt[1], x1 = gt[0] + (w - 0.5) * gt[1];
    const double y0 = gt[3] + 0.5 * gt[5], y1 = gt[3] + (ht - 0.5) * gt[5];
    const double unknown = std::numeric_limits<double>::quiet_NaN();
    info.bounds = SourceBounds{std::min(x0, x1), std::min(y0, y1), unknown,
                               std::max(x0, x1), std::max(y0, y1), unknown};
    int ok_min = 0, ok_max = 0;
    const double zmin = GDALGetRasterMinimum(band, &ok_min);
    const double zmax = GDALGetRasterMaximum(band, &ok_max);
    if (ok_min && ok_max) {
      info.bounds->min_z = zmin;
      info.bounds->max_z = zmax;
    }
  }
  auto source =
      std::make_unique<RasterSource>(std::move(ds), band, gt, nodata, std::move(info), options);
  return std::unique_ptr<PointSource>(std::move(source));
}

}  // namespace tinstream::sources
