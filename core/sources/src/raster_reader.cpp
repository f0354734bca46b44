// Any GDAL raster as points: one point per cell centre of one band, NODATA and NaN cells
// skipped, read a strip of block-height rows at a time (memory: width × block height doubles).
#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <mutex>

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

class RasterSource final : public PointSource {
 public:
  RasterSource(DatasetPtr ds, GDALRasterBandH band, std::array<double, 6> gt,
               std::optional<double> nodata, SourceInfo info, SourceOptions options)
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
      if (std::isnan(v) || (nodata_ && v == *nodata_)) {
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
  std::optional<double> nodata_;  // compared with the raw value, before scale/offset
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

Result<std::unique_ptr<PointSource>> open_raster(const std::filesystem::path& fs_path,
                                                 const SourceOptions& options) {
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  const std::string path = fs_path.string();
  std::error_code ec;
  if (!std::filesystem::exists(fs_path, ec)) return not_found(path + ": cannot open: no such file");

  QuietGdalErrors quiet;
  DatasetPtr ds(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
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
  GDALRasterBandH band = GDALGetRasterBand(h, options.raster_band);
  std::array<double, 6> gt{};
  if (GDALGetGeoTransform(h, gt.data()) != CE_None) {
    return unsupported(path + ": the raster has no geotransform (not georeferenced)");
  }
  int has_nodata = 0;
  const double nd = GDALGetRasterNoDataValue(band, &has_nodata);
  std::optional<double> nodata;
  if (has_nodata != 0 && !std::isnan(nd)) nodata = nd;

  SourceInfo info;
  info.path = path;
  GDALDriverH driver = GDALGetDatasetDriver(h);
  info.format = std::string("GDAL ") + (driver ? GDALGetDriverShortName(driver) : "raster");
  info.crs = crs_of(h);
  if (!info.crs.empty()) {
    info.crs_origin = "GDAL";
  } else {
    info.notes.push_back(
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
