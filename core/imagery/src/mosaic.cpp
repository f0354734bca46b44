// The imagery mosaic through GDAL: each source is first wrapped in an in-memory VRT that shows
// it as 8-bit R, G, B (and alpha when it has one) with its CRS — grey and palette files
// included —, then GDALWarp reprojects those VRTs into each tile.
#include "mosaic.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal.h>
#include <gdal_alg.h>
#include <gdal_utils.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <list>
#include <mutex>

namespace tinstream::imagery {

namespace {

struct DatasetCloser {
  void operator()(void* ds) const {
    if (ds != nullptr) GDALClose(static_cast<GDALDatasetH>(ds));
  }
};
using Dataset = std::unique_ptr<void, DatasetCloser>;

struct SrsDeleter {
  void operator()(void* srs) const {
    if (srs != nullptr) OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(srs));
  }
};
using Srs = std::unique_ptr<void, SrsDeleter>;

// Silences GDAL's stderr printing on this thread while in scope; the last message stays
// readable through gdal_message().
class QuietGdal {
 public:
  QuietGdal() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdal() { CPLPopErrorHandler(); }
  QuietGdal(const QuietGdal&) = delete;
  QuietGdal& operator=(const QuietGdal&) = delete;
};

std::string gdal_message() {
  const char* m = CPLGetLastErrorMsg();
  return (m != nullptr && *m != 0) ? std::string(m) : std::string("no detail from GDAL");
}

void register_gdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// A NULL-terminated argv for the GDAL utilities, owning its strings.
class Argv {
 public:
  explicit Argv(std::vector<std::string> args) : args_(std::move(args)) {
    for (auto& a : args_) ptrs_.push_back(a.data());
    ptrs_.push_back(nullptr);
  }
  char** get() { return ptrs_.data(); }

 private:
  std::vector<std::string> args_;
  std::vector<char*> ptrs_;
};

Result<std::string> target_wkt(geo::Projection projection) {
  Srs srs(OSRNewSpatialReference(nullptr));
  const int epsg = projection == geo::Projection::spherical ? 3857 : 3395;
  if (OSRImportFromEPSG(static_cast<OGRSpatialReferenceH>(srs.get()), epsg) != OGRERR_NONE) {
    return unsupported("PROJ does not know EPSG:" + std::to_string(epsg) +
                       " (is proj-data installed?)");
  }
  char* wkt = nullptr;
  if (OSRExportToWkt(static_cast<OGRSpatialReferenceH>(srs.get()), &wkt) != OGRERR_NONE) {
    CPLFree(wkt);
    return Error(ErrorCode::internal, "cannot write EPSG:" + std::to_string(epsg) + " as WKT");
  }
  std::string out = wkt;
  CPLFree(wkt);
  return out;
}

// The CRS given on the command line as WKT, or an error naming it.
Result<std::string> crs_override_wkt(const std::string& crs) {
  Srs srs(OSRNewSpatialReference(nullptr));
  if (OSRSetFromUserInput(static_cast<OGRSpatialReferenceH>(srs.get()), crs.c_str()) !=
      OGRERR_NONE) {
    return invalid_argument("--crs '" + crs + "': not a CRS that PROJ knows");
  }
  char* wkt = nullptr;
  OSRExportToWkt(static_cast<OGRSpatialReferenceH>(srs.get()), &wkt);
  std::string out = wkt != nullptr ? wkt : "";
  CPLFree(wkt);
  return out;
}

struct BandLayout {
  std::vector<std::string> args;  // gdal_translate arguments that make the RGB(A) VRT
  std::string description;
};

Result<BandLayout> band_layout(GDALDatasetH ds, const std::string& path) {
  const int count = GDALGetRasterCount(ds);
  if (count < 1) return invalid_argument(path + ": the raster has no bands");
  for (int b = 1; b <= count; ++b) {
    const GDALDataType type = GDALGetRasterDataType(GDALGetRasterBand(ds, b));
    if (type != GDT_Byte) {
      return unsupported(path + ": band " + std::to_string(b) + " is " + GDALGetDataTypeName(type) +
                         "; imagery needs 8-bit colour bands (convert first, e.g. "
                         "gdal_translate -ot Byte -scale)");
    }
  }
  const auto interp = [&](int b) {
    return GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, b));
  };
  BandLayout l;
  if (count <= 2 && interp(1) == GCI_PaletteIndex &&
      GDALGetRasterColorTable(GDALGetRasterBand(ds, 1)) != nullptr) {
    l.args = {"-expand", "rgba"};
    l.description = "palette";
    return l;
  }
  if (count <= 2) {
    const bool alpha = count == 2 && interp(2) == GCI_AlphaBand;
    l.args = {"-b", "1", "-b", "1", "-b", "1"};
    if (alpha) l.args.insert(l.args.end(), {"-b", "2"});
    l.args.insert(l.args.end(),
                  {"-colorinterp", alpha ? "red,green,blue,alpha" : "red,green,blue"});
    l.description = alpha ? "gray+alpha" : "gray";
    return l;
  }
  int red = 0, green = 0, blue = 0, alpha = 0;
  for (int b = 1; b <= count; ++b) {
    switch (interp(b)) {
      case GCI_RedBand:
        red = red == 0 ? b : red;
        break;
      case GCI_GreenBand:
        green = green == 0 ? b : green;
        break;
      case GCI_BlueBand:
        blue = blue == 0 ? b : blue;
        break;
      case GCI_AlphaBand:
        alpha = alpha == 0 ? b : alpha;
        break;
      default:
        break;
    }
  }
  if (red == 0 || green == 0 || blue == 0) red = 1, green = 2, blue = 3;  // untagged: 1, 2, 3
  for (const int b : {red, green, blue}) l.args.insert(l.args.end(), {"-b", std::to_string(b)});
  if (alpha != 0) l.args.insert(l.args.end(), {"-b", std::to_string(alpha)});
  l.args.insert(l.args.end(),
                {"-colorinterp", alpha != 0 ? "red,green,blue,alpha" : "red,green,blue"});
  l.description = alpha != 0 ? "RGBA" : "RGB";
  return l;
}

// A source file and the RGB(A) VRT over it; the VRT reads through the file's handle, so the file
// is closed after it.
struct OpenSource {
  Dataset file;
  Dataset vrt;  // declared after `file`, so destroyed before it
};

Result<OpenSource> open_source(const std::string& path, const std::string& crs_wkt,
                               BandLayout* layout_out) {
  register_gdal();
  QuietGdal quiet;
  Dataset file(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
  if (!file) return invalid_argument(path + ": GDAL cannot open it as a raster: " + gdal_message());
  auto ds = static_cast<GDALDatasetH>(file.get());
  auto layout = band_layout(ds, path);
  if (!layout) return layout.error();
  std::vector<std::string> args = {"-of", "VRT"};
  args.insert(args.end(), layout->args.begin(), layout->args.end());
  if (!crs_wkt.empty()) args.insert(args.end(), {"-a_srs", crs_wkt});
  Argv argv(args);
  GDALTranslateOptions* options = GDALTranslateOptionsNew(argv.get(), nullptr);
  if (options == nullptr) {
    return Error(ErrorCode::internal, path + ": gdal_translate options: " + gdal_message());
  }
  int usage_error = 0;
  Dataset vrt(GDALTranslate("", ds, options, &usage_error));
  GDALTranslateOptionsFree(options);
  if (!vrt) return invalid_argument(path + ": cannot read its colour bands: " + gdal_message());
  if (layout_out != nullptr) *layout_out = *layout;
  OpenSource out;
  out.vrt = std::move(vrt);
  out.file = std::move(file);
  return out;
}

std::string crs_name(GDALDatasetH ds) {
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
  if (srs == nullptr) return {};
  const char* name = OSRGetName(srs);
  const char* code = OSRGetAuthorityCode(srs, nullptr);
  const char* authority = OSRGetAuthorityName(srs, nullptr);
  std::string out = name != nullptr ? name : "unnamed CRS";
  if (code != nullptr && authority != nullptr)
    out += std::string(" (") + authority + ":" + code + ")";
  return out;
}

geo::MercatorRect clamp_to_map(geo::MercatorRect r) {
  const auto c = [](double v) { return std::clamp(v, -1.0, 1.0); };
  return {c(r.min_x), c(r.min_y), c(r.max_x), c(r.max_y)};
}

}  // namespace

Status check_resampling(const std::string& name) {
  static const char* const kNames[] = {"near",    "bilinear", "cubic", "cubicspline",
                                       "lanczos", "average",  "mode"};
  for (const char* n : kNames) {
    if (name == n) return {};
  }
  return invalid_argument("--resampling '" + name +
                          "': use near, bilinear, cubic, cubicspline, lanczos, average or mode");
}

Result<MosaicPlan> plan_mosaic(const std::vector<std::filesystem::path>& paths,
                               const std::string& crs, geo::Projection projection,
                               std::uint32_t tile_size) {
  if (paths.empty()) return invalid_argument("no imagery sources given");
  auto wkt = target_wkt(projection);
  if (!wkt) return wkt.error();
  std::string override_wkt;
  if (!crs.empty()) {
    auto o = crs_override_wkt(crs);
    if (!o) return o.error();
    override_wkt = *o;
  }
  MosaicPlan plan;
  plan.projection = projection;
  double finest = std::numeric_limits<double>::infinity();
  for (const auto& p : paths) {
    const std::string path = p.string();
    BandLayout layout;
    auto source = open_source(path, override_wkt, &layout);
    if (!source) return source.error();
    auto vrt = static_cast<GDALDatasetH>(source->vrt.get());
    QuietGdal quiet;
    SourcePlan s;
    s.path = path;
    GDALDriverH driver = GDALGetDatasetDriver(static_cast<GDALDatasetH>(source->file.get()));
    s.driver = driver != nullptr ? GDALGetDriverShortName(driver) : "raster";
    s.crs = crs_name(vrt);
    s.crs_wkt = override_wkt;
    s.width = GDALGetRasterXSize(vrt);
    s.height = GDALGetRasterYSize(vrt);
    s.bands = layout.description;
    if (GDALGetSpatialRef(vrt) == nullptr && GDALGetGCPCount(vrt) == 0) {
      return invalid_argument(path + ": the raster has no CRS; give one with --crs");
    }
    double gt[6];
    if (GDALGetGeoTransform(vrt, gt) != CE_None && GDALGetGCPCount(vrt) == 0) {
      return invalid_argument(path + ": the raster is not georeferenced (no geotransform or GCPs)");
    }
    if (GDALGetSpatialRef(vrt) == nullptr) {
      return invalid_argument(path + ": the raster has no CRS; give one with --crs");
    }
    char** to = CSLSetNameValue(nullptr, "DST_SRS", wkt->c_str());
    void* transformer = GDALCreateGenImgProjTransformer2(vrt, nullptr, to);
    CSLDestroy(to);
    if (transformer == nullptr) {
      return invalid_argument(
          path + ": cannot reproject from " + s.crs + " to " +
          (projection == geo::Projection::spherical ? "EPSG:3857" : "EPSG:3395") + ": " +
          gdal_message());
    }
    double out_gt[6];
    int pixels = 0, lines = 0;
    double extent[4];
    const CPLErr err = GDALSuggestedWarpOutput2(vrt, GDALGenImgProjTransform, transformer, out_gt,
                                                &pixels, &lines, extent, 0);
    GDALDestroyGenImgProjTransformer(transformer);
    if (err != CE_None || !(out_gt[1] > 0) || !std::isfinite(out_gt[1])) {
      return invalid_argument(path +
                              ": its footprint cannot be reprojected to Mercator (is it "
                              "beyond ±85° latitude, or is the CRS wrong?): " +
                              gdal_message());
    }
    s.resolution = out_gt[1];
    s.bounds =
        clamp_to_map({extent[0] / kMercatorMetresPerUnit, extent[1] / kMercatorMetresPerUnit,
                      extent[2] / kMercatorMetresPerUnit, extent[3] / kMercatorMetresPerUnit});
    if (!(s.bounds.max_x > s.bounds.min_x && s.bounds.max_y > s.bounds.min_y)) {
      return invalid_argument(path + ": its footprint lies outside the Mercator map");
    }
    finest = std::min(finest, s.resolution);
    if (plan.sources.empty()) {
      plan.bounds = s.bounds;
    } else {
      plan.bounds = {
          std::min(plan.bounds.min_x, s.bounds.min_x), std::min(plan.bounds.min_y, s.bounds.min_y),
          std::max(plan.bounds.max_x, s.bounds.max_x), std::max(plan.bounds.max_y, s.bounds.max_y)};
    }
    plan.sources.push_back(std::move(s));
  }
  // The level whose tile pixel is closest (in log scale) to the finest source pixel.
  const double world = 2.0 * kMercatorMetresPerUnit;
  const double level = std::log2(world / (static_cast<double>(tile_size) * finest));
  plan.native_level = static_cast<std::uint32_t>(
      std::clamp(std::lround(level), 0L, static_cast<long>(geo::kMaxLevel)));
  return plan;
}

// ---------------------------------------------------------------------------------------------

struct TileRenderer::Impl {
  const MosaicPlan* plan = nullptr;
  std::string resampling;
  std::uint32_t tile_size = 256;
  std::string wkt;
  // Sources opened on this thread, most recently used first, at most kOpenLimit of them.
  static constexpr std::size_t kOpenLimit = 32;
  std::list<std::pair<std::size_t, OpenSource>> open;

  Result<GDALDatasetH> source(std::size_t i) {
    for (auto it = open.begin(); it != open.end(); ++it) {
      if (it->first == i) {
        open.splice(open.begin(), open, it);
        return static_cast<GDALDatasetH>(open.front().second.vrt.get());
      }
    }
    auto s = open_source(plan->sources[i].path, plan->sources[i].crs_wkt, nullptr);
    if (!s) return s.error();
    open.emplace_front(i, std::move(*s));
    if (open.size() > kOpenLimit) open.pop_back();
    return static_cast<GDALDatasetH>(open.front().second.vrt.get());
  }
};

TileRenderer::TileRenderer(const MosaicPlan& plan, std::string resampling, std::uint32_t tile_size)
    : impl_(std::make_unique<Impl>()) {
  impl_->plan = &plan;
  impl_->resampling = std::move(resampling);
  impl_->tile_size = tile_size;
  auto wkt = target_wkt(plan.projection);
  if (wkt) impl_->wkt = *wkt;  // plan_mosaic has already checked that it exists
}

TileRenderer::~TileRenderer() = default;

Result<RgbaImage> TileRenderer::render(const geo::TileId& id) {
  const std::uint32_t size = impl_->tile_size;
  RgbaImage image(size, size);
  const geo::MercatorRect tile = id.bounds();
  std::vector<GDALDatasetH> sources;
  std::vector<std::string> names;
  for (std::size_t i = 0; i < impl_->plan->sources.size(); ++i) {
    if (!impl_->plan->sources[i].bounds.overlaps(tile)) continue;
    auto ds = impl_->source(i);
    if (!ds) return ds.error();
    sources.push_back(*ds);
    names.push_back(impl_->plan->sources[i].path);
  }
  if (sources.empty()) return image;

  QuietGdal quiet;
  GDALDriverH mem = GDALGetDriverByName("MEM");
  Dataset dst(
      GDALCreate(mem, "", static_cast<int>(size), static_cast<int>(size), 4, GDT_Byte, nullptr));
  if (!dst) return Error(ErrorCode::internal, "cannot create an in-memory tile: " + gdal_message());
  auto d = static_cast<GDALDatasetH>(dst.get());
  const double pixel = tile.width() * kMercatorMetresPerUnit / size;
  double gt[6] = {tile.min_x * kMercatorMetresPerUnit, pixel, 0,
                  tile.max_y * kMercatorMetresPerUnit, 0,     -pixel};
  GDALSetGeoTransform(d, gt);
  GDALSetProjection(d, impl_->wkt.c_str());
  const GDALColorInterp interp[4] = {GCI_RedBand, GCI_GreenBand, GCI_BlueBand, GCI_AlphaBand};
  for (int b = 0; b < 4; ++b)
    GDALSetRasterColorInterpretation(GDALGetRasterBand(d, b + 1), interp[b]);

  Argv argv({"-r", impl_->resampling, "-dstalpha"});
  GDALWarpAppOptions* options = GDALWarpAppOptionsNew(argv.get(), nullptr);
  if (options == nullptr) {
    return Error(ErrorCode::internal, "gdalwarp options: " + gdal_message());
  }
  int usage_error = 0;
  GDALDatasetH warped =
      GDALWarp(nullptr, d, static_cast<int>(sources.size()), sources.data(), options, &usage_error);
  GDALWarpAppOptionsFree(options);
  if (warped == nullptr) {
    std::string what;
    for (const auto& n : names) what += (what.empty() ? "" : ", ") + n;
    return io_error(what + ": warping tile " + id.to_string() + " failed: " + gdal_message());
  }
  if (GDALDatasetRasterIO(d, GF_Read, 0, 0, static_cast<int>(size), static_cast<int>(size),
                          image.pixels.data(), static_cast<int>(size), static_cast<int>(size),
                          GDT_Byte, 4, nullptr, 4, static_cast<int>(size) * 4, 1) != CE_None) {
    return Error(ErrorCode::internal,
                 "reading back tile " + id.to_string() + ": " + gdal_message());
  }
  return image;
}

}  // namespace tinstream::imagery
