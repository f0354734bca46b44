// `tinstream sample`: writes a synthetic LiDAR-like point cloud (fractal mountain terrain) as a
// LAS 1.2 file in UTM zone 32N (EPSG:32632, metres) — the built-in sample of `make demo` and the
// input generator of the ingest benchmark. Streams: memory does not grow with --points.
// --ortho also writes an "orthophoto" of the same mountains (an RGB GeoTIFF in the same CRS:
// height tint and hillshade from the surface the points sample), the demo's imagery layer.
#include <cpl_conv.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iostream>
#include <random>
#include <vector>

#include "command.hpp"

namespace tinstream::cli {
namespace {

struct SampleArgs {
  std::string out = "sample.las";
  double points = 1e6;
  double density = 4.0;  // points per square metre, like airborne LiDAR
  std::uint64_t seed = 1;
  std::string ortho;                            // an RGB GeoTIFF of the same surface, when given
  double ortho_pixel = 2.0;                     // its pixel size, metres
  double easting = 395000, northing = 5093000;  // near the Matterhorn (45.98 N, 7.65 E)
};

// Smooth value noise from a hashed lattice, summed over octaves (fBm): mountains of ~2 km relief
// with detail down to a few metres.
double lattice(std::int64_t i, std::int64_t j, std::uint64_t seed) {
  std::uint64_t h = static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ull ^
                    static_cast<std::uint64_t>(j) * 0xC2B2AE3D27D4EB4Full ^ seed;
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 29;
  return static_cast<double>(h >> 11) * 0x1p-53;  // [0, 1)
}

double smooth_noise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto i = static_cast<std::int64_t>(fx), j = static_cast<std::int64_t>(fy);
  const double u = x - fx, v = y - fy;
  const double su = u * u * (3 - 2 * u), sv = v * v * (3 - 2 * v);
  const double a = lattice(i, j, seed), b = lattice(i + 1, j, seed);
  const double c = lattice(i, j + 1, seed), d = lattice(i + 1, j + 1, seed);
  return (a + (b - a) * su) * (1 - sv) + (c + (d - c) * su) * sv;
}

double terrain(double e, double n, std::uint64_t seed) {
  double h = 0, amplitude = 1400, wavelength = 3000;
  for (int octave = 0; octave < 10; ++octave) {
    h += amplitude *
         smooth_noise(e / wavelength, n / wavelength, seed + static_cast<std::uint64_t>(octave));
    amplitude *= 0.48;
    wavelength *= 0.5;
  }
  return 1600 + h;
}

template <typename T>
void put(std::vector<char>& buf, std::size_t offset, T value) {
  std::memcpy(buf.data() + offset, &value, sizeof value);
}

// The colour of the ground at relative height t (0 the sample's lowest point, 1 its highest)
// whose surface rises by (dx, dy) per metre east and north: a height tint (forest, meadow, rock,
// snow) lit from the north-west.
std::array<std::uint8_t, 3> ground_colour(double t, double dx, double dy) {
  struct Stop {
    double t, r, g, b;
  };
  static constexpr std::array<Stop, 5> kRamp = {{{0.0, 46, 88, 38},
                                                 {0.3, 98, 130, 62},
                                                 {0.6, 150, 132, 100},
                                                 {0.85, 165, 162, 156},
                                                 {1.0, 248, 248, 252}}};
  std::array<double, 3> c = {kRamp.back().r, kRamp.back().g, kRamp.back().b};
  if (t <= kRamp.front().t) c = {kRamp.front().r, kRamp.front().g, kRamp.front().b};
  for (std::size_t k = 0; k + 1 < kRamp.size(); ++k) {
    const Stop &lo = kRamp[k], &hi = kRamp[k + 1];
    if (t > lo.t && t <= hi.t) {
      const double f = (t - lo.t) / (hi.t - lo.t);
      c = {lo.r + f * (hi.r - lo.r), lo.g + f * (hi.g - lo.g), lo.b + f * (hi.b - lo.b)};
    }
  }
  // Lambert shading: normal (-dx, -dy, 1), light from azimuth 315°, 45° up.
  const double len = std::sqrt(dx * dx + dy * dy + 1);
  const double lx = -0.5, ly = 0.5, lz = std::sqrt(0.5);
  const double shade = std::max(0.0, (-dx * lx - dy * ly + lz) / len);
  std::array<std::uint8_t, 3> out{};
  for (std::size_t k = 0; k < 3; ++k) {
    out[k] = static_cast<std::uint8_t>(std::clamp(c[k] * (0.45 + 0.75 * shade), 0.0, 255.0));
  }
  return out;
}

// Writes the orthophoto of the square [0, side]² (local metres from the LAS offset) row by row,
// tinted over the points' height range [low, high].
int write_ortho(const SampleArgs& a, double side, double low, double high) {
  GDALAllRegister();
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (gtiff == nullptr) {
    std::cerr << "tinstream sample: GDAL has no GTiff driver\n";
    return 1;
  }
  const int n = std::max(1, static_cast<int>(std::ceil(side / a.ortho_pixel)));
  char** options = nullptr;
  options = CSLSetNameValue(options, "COMPRESS", "DEFLATE");
  options = CSLSetNameValue(options, "TILED", "YES");
  options = CSLSetNameValue(options, "PHOTOMETRIC", "RGB");
  GDALDataset* ds = gtiff->Create(a.ortho.c_str(), n, n, 3, GDT_Byte, options);
  CSLDestroy(options);
  if (ds == nullptr) {
    std::cerr << "tinstream sample: cannot create " << a.ortho << ": " << CPLGetLastErrorMsg()
              << "\n";
    return 1;
  }
  const double p = a.ortho_pixel;
  std::array<double, 6> gt = {a.easting, p, 0, a.northing + n * p, 0, -p};
  OGRSpatialReference srs;
  srs.importFromEPSG(32632);
  bool ok = ds->SetGeoTransform(gt.data()) == CE_None && ds->SetSpatialRef(&srs) == CE_None;
  std::vector<std::uint8_t> row(static_cast<std::size_t>(n) * 3);
  const double d = p / 2;  // finite differences over one pixel
  for (int j = 0; ok && j < n; ++j) {
    const double north = (n - j - 0.5) * p;
    for (int i = 0; i < n; ++i) {
      const double east = (i + 0.5) * p;
      const double h = terrain(east, north, a.seed);
      const double dx = (terrain(east + d, north, a.seed) - terrain(east - d, north, a.seed)) / p;
      const double dy = (terrain(east, north + d, a.seed) - terrain(east, north - d, a.seed)) / p;
      const auto c = ground_colour((h - low) / std::max(high - low, 1.0), dx, dy);
      std::copy(c.begin(), c.end(), row.begin() + static_cast<std::ptrdiff_t>(i) * 3);
    }
    ok = ds->RasterIO(GF_Write, 0, j, n, 1, row.data(), n, 1, GDT_Byte, 3, nullptr, 3, 0, 1,
                      nullptr) == CE_None;
  }
  if (!ok)
    std::cerr << "tinstream sample: write to " << a.ortho << " failed: " << CPLGetLastErrorMsg()
              << "\n";
  GDALClose(ds);
  if (!ok) return 1;
  std::cout << "wrote a " << n << " x " << n << " px orthophoto (" << p
            << " m pixels, EPSG:32632) to " << a.ortho << "\n";
  return 0;
}

int run(const SampleArgs& a) {
  if (!(a.points >= 1 && a.points <= 4e9) || !(a.density > 0)) {
    std::cerr << "tinstream sample: --points must be in [1, 4e9] and --density > 0\n";
    return 2;
  }
  const auto count = static_cast<std::uint64_t>(a.points);
  const double side = std::sqrt(static_cast<double>(count) / a.density);
  if (!a.ortho.empty() && (!(a.ortho_pixel >= 0.1) || side / a.ortho_pixel > 16384)) {
    std::cerr << "tinstream sample: --ortho-pixel must be at least 0.1 m and give at most 16384 "
                 "pixels a side (the sample is "
              << std::lround(side) << " m a side)\n";
    return 2;
  }
  // Flight strips along x, as a scanner writes them: about 100 m wide, dividing the square
  // exactly (a clipped last strip would pile its points onto the north edge as one line).
  const auto strips = static_cast<std::uint64_t>(std::max(1.0, std::round(side / 100.0)));
  const double strip = side / static_cast<double>(strips);

  // Header (227 bytes) + one GeoKeyDirectory VLR (54 + 8 + 3·8 bytes).
  constexpr std::size_t kHeader = 227, kVlr = 54 + 32;
  std::vector<char> header(kHeader + kVlr, 0);
  std::memcpy(header.data(), "LASF", 4);
  header[24] = 1;
  header[25] = 2;
  std::memcpy(header.data() + 26, "tinstream sample", 16);
  std::memcpy(header.data() + 58, "tinstream", 9);
  put<std::uint16_t>(header, 94, kHeader);
  put<std::uint32_t>(header, 96, kHeader + kVlr);
  put<std::uint32_t>(header, 100, 1);
  header[104] = 0;  // point format 0
  put<std::uint16_t>(header, 105, 20);
  put<std::uint32_t>(header, 107,
                     static_cast<std::uint32_t>(std::min<std::uint64_t>(count, 0xFFFFFFFFu)));
  put<std::uint32_t>(header, 111,
                     static_cast<std::uint32_t>(std::min<std::uint64_t>(count, 0xFFFFFFFFu)));
  const double scale = 0.001;
  for (int i = 0; i < 3; ++i) put<double>(header, 131 + 8 * static_cast<std::size_t>(i), scale);
  put<double>(header, 155, a.easting);
  put<double>(header, 163, a.northing);
  put<double>(header, 171, 0.0);
  // VLR: LASF_Projection / 34735 GeoKeyDirectory: projected, EPSG:32632, metres.
  std::size_t v = kHeader;
  std::memcpy(header.data() + v + 2, "LASF_Projection", 15);
  put<std::uint16_t>(header, v + 18, 34735);
  put<std::uint16_t>(header, v + 20, 32);
  std::memcpy(header.data() + v + 22, "GeoKeyDirectoryTag", 18);
  const std::uint16_t keys[16] = {1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32632, 3076, 0, 1, 9001};
  std::memcpy(header.data() + v + 54, keys, sizeof keys);

  std::ofstream out(a.out, std::ios::binary);
  if (!out) {
    std::cerr << "tinstream sample: cannot create " << a.out << "\n";
    return 1;
  }
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  std::mt19937_64 rng(a.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double min_x = 1e300, max_x = -1e300, min_y = 1e300, max_y = -1e300, min_z = 1e300,
         max_z = -1e300;
  std::vector<char> records;
  records.reserve(std::size_t{20} * 65536);
  std::uint64_t written = 0;
  for (std::uint64_t s = 0; s < strips && written < count; ++s) {
    const std::uint64_t in_strip = (count - written) / (strips - s);
    for (std::uint64_t k = 0; k < in_strip; ++k) {
      const double e = side * unit(rng),
                   n = std::min(side, (static_cast<double>(s) + unit(rng)) * strip);
      const double h = terrain(e, n, a.seed);
      const auto X = static_cast<std::int32_t>(std::lround(e / scale));
      const auto Y = static_cast<std::int32_t>(std::lround(n / scale));
      const auto Z = static_cast<std::int32_t>(std::lround(h / scale));
      char rec[20] = {};
      std::memcpy(rec, &X, 4);
      std::memcpy(rec + 4, &Y, 4);
      std::memcpy(rec + 8, &Z, 4);
      rec[14] = 0x09;  // return 1 of 1
      rec[15] = 2;     // ground
      records.insert(records.end(), rec, rec + 20);
      const double ex = a.easting + X * scale, ny = a.northing + Y * scale, hz = Z * scale;
      min_x = std::min(min_x, ex), max_x = std::max(max_x, ex);
      min_y = std::min(min_y, ny), max_y = std::max(max_y, ny);
      min_z = std::min(min_z, hz), max_z = std::max(max_z, hz);
      if (records.size() >= std::size_t{20} * 65536) {
        out.write(records.data(), static_cast<std::streamsize>(records.size()));
        records.clear();
      }
    }
    written += in_strip;
  }
  out.write(records.data(), static_cast<std::streamsize>(records.size()));
  // Bounds: MaxX, MinX, MaxY, MinY, MaxZ, MinZ.
  const double bounds[6] = {max_x, min_x, max_y, min_y, max_z, min_z};
  out.seekp(179);
  out.write(reinterpret_cast<const char*>(bounds), sizeof bounds);
  if (!out) {
    std::cerr << "tinstream sample: write to " << a.out << " failed\n";
    return 1;
  }
  std::cout << "wrote " << written << " points (" << std::lround(side) << " m x "
            << std::lround(side) << " m, EPSG:32632, heights " << std::lround(min_z) << "-"
            << std::lround(max_z) << " m) to " << a.out << "\n";
  return a.ortho.empty() ? 0 : write_ortho(a, side, min_z, max_z);
}

const CommandRegistration kRegistration{
    "sample",
    "Write a synthetic LiDAR-like LAS point cloud (fractal mountains, EPSG:32632) for demos and "
    "benchmarks",
    [](CLI::App& sub) -> CommandRun {
      auto a = std::make_shared<SampleArgs>();
      sub.add_option("--out", a->out, "Output LAS file")->capture_default_str();
      sub.add_option("--points", a->points, "Number of points (e.g. 1e7)")->capture_default_str();
      sub.add_option("--density", a->density, "Points per square metre")->capture_default_str();
      sub.add_option("--seed", a->seed, "Random seed (same seed, same file)")
          ->capture_default_str();
      sub.add_option("--ortho", a->ortho,
                     "Also write an RGB GeoTIFF 'orthophoto' of the same surface (height tint and "
                     "hillshade; imagery for ingest-imagery)");
      sub.add_option("--ortho-pixel", a->ortho_pixel, "Pixel size of --ortho, metres")
          ->capture_default_str();
      return [a] { return run(*a); };
    }};

}  // namespace
}  // namespace tinstream::cli
