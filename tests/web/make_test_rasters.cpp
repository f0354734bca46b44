// tinstream-test-rasters: the generated data of the browser tests (tests/web), written with
// GDAL into one folder:
//   dem.tif     Float32 DEM, EPSG:32611 (UTM 11N), 400 × 300 cells of 10 m in the San Gabriel
//               Mountains: smooth hills of an analytic function, 850–1470 m
//   ortho.tif   RGB orthophoto of the same area, 800 × 600 pixels of 5 m: a hypsometric ramp of
//               the same function, shaded, with a dark 500 m grid
//   points.json ground points (cell centres of the DEM, well inside it) with their lon/lat and
//               their exact heights: what a client sampling the terrain there must find
//
//   tinstream-test-rasters --out DIR
#include <cpl_conv.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace {

constexpr int kEpsg = 32611;
constexpr double kOriginX = 390000, kOriginY = 3800000;  // north-west corner
constexpr double kWidthM = 4000, kHeightM = 3000;

double height(double e, double n) {
  const double x = e - kOriginX, y = kOriginY - n;
  return 1100 + 250 * std::sin(2 * M_PI * x / 2000) * std::cos(2 * M_PI * y / 1500) + 0.03 * x;
}

std::string wkt() {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, kEpsg);
  char* text = nullptr;
  OSRExportToWkt(srs, &text);
  std::string out = text;
  CPLFree(text);
  OSRDestroySpatialReference(srs);
  return out;
}

GDALDatasetH create(const std::filesystem::path& p, int w, int h, int bands, GDALDataType type,
                    double pixel) {
  const char* options[] = {"TILED=YES", "COMPRESS=DEFLATE", nullptr};
  GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), p.c_str(), w, h, bands, type,
                               const_cast<char**>(options));
  if (ds == nullptr) throw std::runtime_error("cannot create " + p.string());
  double gt[6] = {kOriginX, pixel, 0, kOriginY, 0, -pixel};
  GDALSetGeoTransform(ds, gt);
  GDALSetProjection(ds, wkt().c_str());
  return ds;
}

void write_band(GDALDatasetH ds, int band, int w, int h, void* data, GDALDataType type) {
  if (GDALRasterIO(GDALGetRasterBand(ds, band), GF_Write, 0, 0, w, h, data, w, h, type, 0, 0) !=
      CE_None) {
    throw std::runtime_error("cannot write a band");
  }
}

void write_dem(const std::filesystem::path& p) {
  const double cell = 10;
  const int w = static_cast<int>(kWidthM / cell), h = static_cast<int>(kHeightM / cell);
  std::vector<float> z(static_cast<std::size_t>(w) * h);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      z[static_cast<std::size_t>(j) * w + i] =
          static_cast<float>(height(kOriginX + (i + 0.5) * cell, kOriginY - (j + 0.5) * cell));
    }
  }
  GDALDatasetH ds = create(p, w, h, 1, GDT_Float32, cell);
  write_band(ds, 1, w, h, z.data(), GDT_Float32);
  GDALClose(ds);
}

void write_ortho(const std::filesystem::path& p) {
  const double pixel = 5;
  const int w = static_cast<int>(kWidthM / pixel), h = static_cast<int>(kHeightM / pixel);
  std::vector<std::uint8_t> rgb[3];
  for (auto& band : rgb) band.resize(static_cast<std::size_t>(w) * h);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const double e = kOriginX + (i + 0.5) * pixel, n = kOriginY - (j + 0.5) * pixel;
      const double t = std::clamp((height(e, n) - 850) / 620, 0.0, 1.0);
      // Shading from the gradient, lit from the north-west.
      const double dx = (height(e + pixel, n) - height(e - pixel, n)) / (2 * pixel);
      const double dy = (height(e, n + pixel) - height(e, n - pixel)) / (2 * pixel);
      const double shade = std::clamp(0.75 + 0.9 * (-dx + dy) / std::sqrt(2.0), 0.35, 1.15);
      const bool grid =
          std::fmod(e - kOriginX, 500) < pixel || std::fmod(kOriginY - n, 500) < pixel;
      const double colour[3] = {60 + 150 * t, 110 + 90 * t - 40 * t * t, 50 + 120 * t * t};
      for (int c = 0; c < 3; ++c) {
        const double v = grid ? 30 : colour[c] * shade;
        rgb[c][static_cast<std::size_t>(j) * w + i] =
            static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
      }
    }
  }
  GDALDatasetH ds = create(p, w, h, 3, GDT_Byte, pixel);
  for (int c = 0; c < 3; ++c) write_band(ds, c + 1, w, h, rgb[c].data(), GDT_Byte);
  GDALClose(ds);
}

void write_points(const std::filesystem::path& p) {
  OGRSpatialReferenceH utm = OSRNewSpatialReference(nullptr);
  OGRSpatialReferenceH wgs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(utm, kEpsg);
  OSRImportFromEPSG(wgs, 4326);
  OSRSetAxisMappingStrategy(utm, OAMS_TRADITIONAL_GIS_ORDER);
  OSRSetAxisMappingStrategy(wgs, OAMS_TRADITIONAL_GIS_ORDER);
  OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(utm, wgs);
  std::ofstream out(p);
  out << "{\"epsg\": " << kEpsg << ", \"points\": [\n";
  // Cell centres on a 3 × 3 lattice well inside the DEM (cells of 10 m).
  bool first = true;
  for (int a = 1; a <= 3; ++a) {
    for (int b = 1; b <= 3; ++b) {
      const double e = kOriginX + 10 * (100 * a + 3 * b) + 5;
      const double n = kOriginY - 10 * (75 * b + 2 * a) - 5;
      double x = e, y = n;
      if (!OCTTransform(ct, 1, &x, &y, nullptr)) throw std::runtime_error("OCTTransform failed");
      char line[200];
      std::snprintf(line, sizeof line, "%s  {\"lon\": %.10f, \"lat\": %.10f, \"height\": %.4f}",
                    first ? "" : ",\n", x, y,
                    static_cast<double>(static_cast<float>(height(e, n))));
      out << line;
      first = false;
    }
  }
  out << "\n]}\n";
  OCTDestroyCoordinateTransformation(ct);
  OSRDestroySpatialReference(utm);
  OSRDestroySpatialReference(wgs);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || std::string(argv[1]) != "--out") {
    std::cerr << "usage: tinstream-test-rasters --out DIR\n"
                 "writes dem.tif, ortho.tif and points.json (the browser tests' data)\n";
    return 2;
  }
  try {
    GDALAllRegister();
    const std::filesystem::path dir = argv[2];
    std::filesystem::create_directories(dir);
    write_dem(dir / "dem.tif");
    write_ortho(dir / "ortho.tif");
    write_points(dir / "points.json");
  } catch (const std::exception& e) {
    std::cerr << "tinstream-test-rasters: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
