#include "test_rasters.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <gdal_utils.h>
#include <ogr_srs_api.h>

#include <atomic>
#include <cmath>
#include <fstream>
#include <mutex>
#include <stdexcept>

namespace tinstream::imagery::testing {

namespace {

void register_once() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

std::string wkt_of(int epsg) {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, epsg);
  char* wkt = nullptr;
  OSRExportToWkt(srs, &wkt);
  std::string out = wkt;
  CPLFree(wkt);
  OSRDestroySpatialReference(srs);
  return out;
}

std::array<double, 2> transform(int from_epsg, int to_epsg, double x, double y) {
  OGRSpatialReferenceH from = OSRNewSpatialReference(nullptr);
  OGRSpatialReferenceH to = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(from, from_epsg);
  OSRImportFromEPSG(to, to_epsg);
  OSRSetAxisMappingStrategy(from, OAMS_TRADITIONAL_GIS_ORDER);
  OSRSetAxisMappingStrategy(to, OAMS_TRADITIONAL_GIS_ORDER);
  OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(from, to);
  if (ct == nullptr || !OCTTransform(ct, 1, &x, &y, nullptr)) {
    throw std::runtime_error("OGR cannot transform a test coordinate");
  }
  OCTDestroyCoordinateTransformation(ct);
  OSRDestroySpatialReference(from);
  OSRDestroySpatialReference(to);
  return {x, y};
}

GDALDatasetH create_gtiff(const std::filesystem::path& path, int width, int height, int bands) {
  register_once();
  GDALDriverH gtiff = GDALGetDriverByName("GTiff");
  char** options = CSLSetNameValue(nullptr, "TILED", "YES");
  options = CSLSetNameValue(options, "PHOTOMETRIC", "RGB");
  if (bands == 4) options = CSLSetNameValue(options, "ALPHA", "YES");
  GDALDatasetH ds = GDALCreate(gtiff, path.c_str(), width, height, bands, GDT_Byte, options);
  CSLDestroy(options);
  if (ds == nullptr) throw std::runtime_error("cannot create " + path.string());
  return ds;
}

}  // namespace

Orthophoto write_marker_orthophoto(const std::filesystem::path& path, int epsg, double origin_x,
                                   double origin_y, double pixel, int width, int height,
                                   bool alpha) {
  Orthophoto o;
  o.path = path;
  o.epsg = epsg;
  o.origin_x = origin_x;
  o.origin_y = origin_y;
  o.pixel = pixel;
  o.width = width;
  o.height = height;
  o.marker_half = 4;
  const std::array<std::array<std::uint8_t, 3>, 5> colours = {
      {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {255, 255, 0}, {255, 0, 255}}};
  const std::array<std::array<double, 2>, 5> where = {
      {{0.3, 0.3}, {0.7, 0.3}, {0.5, 0.5}, {0.3, 0.7}, {0.7, 0.7}}};
  for (std::size_t i = 0; i < colours.size(); ++i) {
    o.markers.push_back({std::floor(where[i][0] * width) + 0.5,
                         std::floor(where[i][1] * height) + 0.5, colours[i]});
  }
  const int bands = alpha ? 4 : 3;
  std::vector<std::uint8_t> plane(static_cast<std::size_t>(width) * height);
  GDALDatasetH ds = create_gtiff(path, width, height, bands);
  double gt[6] = {origin_x, pixel, 0, origin_y, 0, -pixel};
  GDALSetGeoTransform(ds, gt);
  GDALSetProjection(ds, wkt_of(epsg).c_str());
  for (int b = 0; b < bands; ++b) {
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        std::uint8_t v = 0;
        if (b == 3) {
          v = x < width / 10 ? 0 : 255;
        } else {
          // A dull gradient that never looks like a saturated marker colour.
          const int base[3] = {60 + (100 * x) / width, 70 + (90 * y) / height,
                               90 + (40 * (x + y)) / (width + height)};
          v = static_cast<std::uint8_t>(base[b]);
          for (const Marker& m : o.markers) {
            if (std::abs(x + 0.5 - m.column) <= o.marker_half &&
                std::abs(y + 0.5 - m.row) <= o.marker_half) {
              v = m.rgb[static_cast<std::size_t>(b)];
            }
          }
        }
        plane[static_cast<std::size_t>(y) * width + x] = v;
      }
    }
    if (GDALRasterIO(GDALGetRasterBand(ds, b + 1), GF_Write, 0, 0, width, height, plane.data(),
                     width, height, GDT_Byte, 0, 0) != CE_None) {
      throw std::runtime_error("cannot write " + path.string());
    }
  }
  GDALClose(ds);
  return o;
}

bool write_orthophoto_from_dem(const std::filesystem::path& dem, const std::filesystem::path& out) {
  register_once();
  GDALDatasetH src = GDALOpen(dem.c_str(), GA_ReadOnly);
  if (src == nullptr) return false;
  static std::atomic<int> counter{0};
  const std::string tag = std::to_string(counter++);
  const std::string ramp_path = "/vsimem/ramp" + tag + ".txt";
  const std::string ramp =
      "300 40 90 40\n900 110 140 60\n1400 150 130 80\n1900 170 160 140\n"
      "2300 240 240 240\n";
  VSILFILE* f = VSIFOpenL(ramp_path.c_str(), "wb");
  VSIFWriteL(ramp.data(), 1, ramp.size(), f);
  VSIFCloseL(f);
  const auto dem_processing = [&](const char* mode, const std::vector<const char*>& args,
                                  const char* colours) {
    std::vector<char*> argv;
    argv.reserve(args.size() + 1);
    for (const char* a : args) argv.push_back(const_cast<char*>(a));
    argv.push_back(nullptr);
    GDALDEMProcessingOptions* o = GDALDEMProcessingOptionsNew(argv.data(), nullptr);
    const std::string target = std::string("/vsimem/") + mode + tag + ".tif";
    GDALDatasetH ds = GDALDEMProcessing(target.c_str(), src, mode, colours, o, nullptr);
    GDALDEMProcessingOptionsFree(o);
    return ds;
  };
  GDALDatasetH hillshade = dem_processing("hillshade", {"-compute_edges"}, nullptr);
  GDALDatasetH colour = dem_processing("color-relief", {}, ramp_path.c_str());
  const int w = GDALGetRasterXSize(src), h = GDALGetRasterYSize(src);
  bool ok = hillshade != nullptr && colour != nullptr;
  if (ok) {
    std::vector<std::uint8_t> shade(static_cast<std::size_t>(w) * h), plane(shade.size());
    ok = GDALRasterIO(GDALGetRasterBand(hillshade, 1), GF_Read, 0, 0, w, h, shade.data(), w, h,
                      GDT_Byte, 0, 0) == CE_None;
    GDALDatasetH dst = create_gtiff(out, w, h, 3);
    double gt[6];
    GDALGetGeoTransform(src, gt);
    GDALSetGeoTransform(dst, gt);
    GDALSetProjection(dst, GDALGetProjectionRef(src));
    for (int b = 1; ok && b <= 3; ++b) {
      ok = GDALRasterIO(GDALGetRasterBand(colour, b), GF_Read, 0, 0, w, h, plane.data(), w, h,
                        GDT_Byte, 0, 0) == CE_None;
      for (std::size_t i = 0; i < plane.size(); ++i) {
        plane[i] = static_cast<std::uint8_t>(plane[i] * (0.25 + 0.75 * shade[i] / 255.0));
      }
      ok = ok && GDALRasterIO(GDALGetRasterBand(dst, b), GF_Write, 0, 0, w, h, plane.data(), w, h,
                              GDT_Byte, 0, 0) == CE_None;
    }
    GDALClose(dst);
  }
  if (hillshade != nullptr) GDALClose(hillshade);
  if (colour != nullptr) GDALClose(colour);
  GDALClose(src);
  VSIUnlink(ramp_path.c_str());
  VSIUnlink(("/vsimem/hillshade" + tag + ".tif").c_str());
  VSIUnlink(("/vsimem/color-relief" + tag + ".tif").c_str());
  return ok;
}

std::array<double, 2> to_lonlat(int epsg, double x, double y) {
  return transform(epsg, 4326, x, y);
}

std::array<double, 2> from_lonlat(int epsg, double lon, double lat) {
  return transform(4326, epsg, lon, lat);
}

std::array<double, 2> pixel_in_tile(const geo::TileId& id, geo::Projection projection, double lon,
                                    double lat, std::uint32_t size) {
  const geo::NormalisedMercator m(projection);
  const geo::MercatorXY p = m.forward({lon, lat});
  const geo::MercatorRect r = id.bounds();
  return {(p.x - r.min_x) / r.width() * size, (r.max_y - p.y) / r.height() * size};
}

DecodedImage gdal_decode(const std::vector<std::uint8_t>& bytes) {
  register_once();
  static std::atomic<int> counter{0};
  const std::string name = "/vsimem/decode" + std::to_string(counter++);
  VSILFILE* f = VSIFileFromMemBuffer(name.c_str(), const_cast<GByte*>(bytes.data()),
                                     static_cast<vsi_l_offset>(bytes.size()), FALSE);
  VSIFCloseL(f);
  DecodedImage out;
  GDALDatasetH ds = GDALOpen(name.c_str(), GA_ReadOnly);
  if (ds != nullptr) {
    out.width = GDALGetRasterXSize(ds);
    out.height = GDALGetRasterYSize(ds);
    const int bands = GDALGetRasterCount(ds);
    out.rgba.assign(static_cast<std::size_t>(out.width) * out.height * 4, 255);
    std::vector<std::uint8_t> plane(static_cast<std::size_t>(out.width) * out.height);
    for (int c = 0; c < 4; ++c) {
      const int band = c < 3 ? (bands >= 3 ? c + 1 : 1) : (bands == 4 || bands == 2 ? bands : 0);
      if (band == 0) continue;
      if (GDALRasterIO(GDALGetRasterBand(ds, band), GF_Read, 0, 0, out.width, out.height,
                       plane.data(), out.width, out.height, GDT_Byte, 0, 0) != CE_None) {
        out = DecodedImage();
        break;
      }
      for (std::size_t i = 0; i < plane.size(); ++i)
        out.rgba[i * 4 + static_cast<std::size_t>(c)] = plane[i];
    }
    GDALClose(ds);
  }
  VSIUnlink(name.c_str());
  return out;
}

std::vector<std::uint8_t> read_pixel(const std::filesystem::path& raster, int column, int row) {
  register_once();
  GDALDatasetH ds = GDALOpen(raster.c_str(), GA_ReadOnly);
  if (ds == nullptr) throw std::runtime_error("cannot open " + raster.string());
  std::vector<std::uint8_t> out(static_cast<std::size_t>(GDALGetRasterCount(ds)));
  for (int b = 0; b < GDALGetRasterCount(ds); ++b) {
    if (GDALRasterIO(GDALGetRasterBand(ds, b + 1), GF_Read, column, row, 1, 1,
                     &out[static_cast<std::size_t>(b)], 1, 1, GDT_Byte, 0, 0) != CE_None) {
      throw std::runtime_error("cannot read " + raster.string());
    }
  }
  GDALClose(ds);
  return out;
}

}  // namespace tinstream::imagery::testing
