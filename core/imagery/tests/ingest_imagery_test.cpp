// The imagery ingest on generated and real GeoTIFFs: where pixels land, tile bounds, the
// pyramid, errors, and the store after a failure.
#include "tinstream/imagery/ingest_imagery.hpp"

#include <gdal.h>
#include <gdal_utils.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "test_rasters.hpp"
#include "tinstream/base/fault.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::imagery {
namespace {

namespace fs = std::filesystem;
using testing::Orthophoto;

class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "tinstream-imagery-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  fs::path operator/(const char* name) const { return path_ / name; }

 private:
  fs::path path_;
};

std::string sql_value(const fs::path& db_path, const std::string& sql) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  sqlite3_stmt* stmt = nullptr;
  std::string out;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr) == SQLITE_OK &&
      sqlite3_step(stmt) == SQLITE_ROW && sqlite3_column_text(stmt, 0) != nullptr) {
    out = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
  }
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return out;
}

ImageryIngestOptions options_for(const fs::path& store, const std::string& layer,
                                 std::vector<fs::path> sources) {
  ImageryIngestOptions o;
  o.store_path = store;
  o.layer = layer;
  o.sources = std::move(sources);
  o.threads = 2;
  return o;
}

ImagerySummary ingest_ok(const ImageryIngestOptions& o) {
  auto summary = ingest_imagery(o);
  if (!summary) throw std::runtime_error(summary.error().message);
  return *summary;
}

// The stored tiles of one level pasted into one image (transparent where a tile is absent).
struct Canvas {
  std::uint32_t z = 0, x0 = 0, y0 = 0, columns = 0, rows = 0;
  testing::DecodedImage image;
  // Canvas pixel of a lon/lat; its tile decides nothing, so markers across borders work.
  std::array<double, 2> pixel(geo::Projection projection, double lon, double lat) const {
    const geo::TileId origin{z, x0, y0};
    const auto p = testing::pixel_in_tile(origin, projection, lon, lat);
    return p;
  }
  const std::uint8_t* at(int x, int y) const { return image.at(x, y); }
};

Canvas paste_level(store::TileStore& store, const std::string& layer, std::uint32_t z) {
  auto ids = store.imagery_tile_ids(layer, z);
  if (!ids || ids->empty()) throw std::runtime_error("no tiles at level " + std::to_string(z));
  Canvas c;
  c.z = z;
  std::uint32_t x1 = 0, y1 = 0;
  c.x0 = c.y0 = ~0u;
  for (const auto& id : *ids) {
    c.x0 = std::min(c.x0, id.x), c.y0 = std::min(c.y0, id.y);
    x1 = std::max(x1, id.x), y1 = std::max(y1, id.y);
  }
  c.columns = x1 - c.x0 + 1;
  c.rows = y1 - c.y0 + 1;
  c.image.width = static_cast<int>(c.columns * 256);
  c.image.height = static_cast<int>(c.rows * 256);
  c.image.rgba.assign(static_cast<std::size_t>(c.image.width) * c.image.height * 4, 0);
  for (const auto& id : *ids) {
    auto stored = store.imagery_tile(layer, id);
    if (!stored || !stored->has_value()) throw std::runtime_error("missing " + id.to_string());
    const auto tile = testing::gdal_decode((*stored)->data);
    if (tile.width != 256 || tile.height != 256) throw std::runtime_error("bad tile size");
    for (int y = 0; y < 256; ++y) {
      std::copy_n(tile.at(0, y), 256 * 4,
                  c.image.rgba.begin() +
                      static_cast<std::ptrdiff_t>(
                          ((static_cast<std::size_t>(id.y - c.y0) * 256 + y) * c.image.width +
                           static_cast<std::size_t>(id.x - c.x0) * 256) *
                          4));
    }
  }
  return c;
}

// The level whose 256-pixel tiles come closest to a source pixel of `metres` on the ground at
// `lat` (Mercator stretches it by 1 / cos φ).
std::uint32_t expected_native_level(double metres, double lat) {
  const double mercator = metres / std::cos(lat * M_PI / 180.0);
  return static_cast<std::uint32_t>(std::lround(std::log2(40075016.685578488 / (256 * mercator))));
}

// Checks that every marker of `o` is found in the canvas where its lon/lat says, within
// `tolerance` canvas pixels (the centroid of the pixels of its colour near there).
void expect_markers_in_place(const Orthophoto& o, const Canvas& c, double tolerance,
                             int min_pixels) {
  for (const auto& m : o.markers) {
    const auto crs = o.crs_of(m.column, m.row);
    const auto lonlat = testing::to_lonlat(o.epsg, crs[0], crs[1]);
    const auto p = c.pixel(geo::Projection::spherical, lonlat[0], lonlat[1]);
    double sx = 0, sy = 0, n = 0;
    for (int y = static_cast<int>(p[1]) - 15; y <= static_cast<int>(p[1]) + 15; ++y) {
      for (int x = static_cast<int>(p[0]) - 15; x <= static_cast<int>(p[0]) + 15; ++x) {
        if (x < 0 || y < 0 || x >= c.image.width || y >= c.image.height) continue;
        const std::uint8_t* px = c.at(x, y);
        bool match = px[3] > 200;
        for (int ch = 0; ch < 3; ++ch) match = match && std::abs(px[ch] - m.rgb[ch]) < 40;
        if (match) sx += x + 0.5, sy += y + 0.5, n += 1;
      }
    }
    ASSERT_GE(n, min_pixels) << "marker " << int(m.rgb[0]) << "," << int(m.rgb[1]) << ","
                             << int(m.rgb[2]) << " not found near " << p[0] << "," << p[1];
    EXPECT_NEAR(sx / n, p[0], tolerance) << "marker at lon/lat " << lonlat[0] << "," << lonlat[1];
    EXPECT_NEAR(sy / n, p[1], tolerance) << "marker at lon/lat " << lonlat[0] << "," << lonlat[1];
  }
}

TEST(IngestImagery, GeneratedUtmOrthophotoLandsOnItsGroundControlPoints) {
  TempDir dir;
  // 400 × 300 pixels of 4 m in UTM 11N, in the San Gabriel Mountains (about 34.3° N).
  const Orthophoto o =
      testing::write_marker_orthophoto(dir / "ortho.tif", 32611, 390000, 3800000, 4.0, 400, 300);
  auto options = options_for(dir / "s.db", "ortho", {o.path});
  const ImagerySummary s = ingest_ok(options);
  const auto centre = testing::to_lonlat(32611, 390800, 3799400);
  EXPECT_EQ(s.native_level, expected_native_level(4.0, centre[1]));
  EXPECT_EQ(s.max_level, s.native_level);
  EXPECT_EQ(s.min_level, 0u);
  ASSERT_EQ(s.levels.size(), s.max_level + 1);
  for (const auto& l : s.levels) EXPECT_GE(l.tiles, 1u) << "level " << l.level;
  EXPECT_EQ(s.levels[0].tiles, 1u);
  EXPECT_EQ(s.sources.size(), 1u);
  EXPECT_EQ(s.sources[0].bands, "RGB");
  EXPECT_NE(s.sources[0].crs.find("32611"), std::string::npos) << s.sources[0].crs;
  const auto nw = testing::to_lonlat(32611, 390000, 3800000);
  EXPECT_NEAR(s.bounds.west, nw[0], 0.001);
  EXPECT_NEAR(s.bounds.north, nw[1], 0.001);

  auto store = store::TileStore::open(options.store_path, store::TileStore::Mode::read_only);
  ASSERT_TRUE(store.ok());
  auto info = store->imagery_layer("ortho");
  ASSERT_TRUE(info.ok()) << info.error().message;
  EXPECT_EQ(info->format, "png");
  EXPECT_EQ(info->tile_count, s.tiles);
  EXPECT_EQ(info->max_level, s.max_level);
  // Native level: each marker within 0.6 of a tile pixel (≈ 2.4 m) of where its lon/lat says.
  expect_markers_in_place(o, paste_level(*store, "ortho", s.max_level), 0.6, 40);
  // One level up the markers are still there, within 0.6 of a (2× larger) pixel.
  expect_markers_in_place(o, paste_level(*store, "ortho", s.max_level - 1), 0.6, 8);
}

TEST(IngestImagery, AlphaBandStaysTransparentInWebp) {
  TempDir dir;
  const Orthophoto o = testing::write_marker_orthophoto(dir / "ortho.tif", 32611, 390000, 3800000,
                                                        4.0, 400, 300, true);
  auto options = options_for(dir / "s.db", "ortho", {o.path});
  options.format = ImageFormat::webp;
  options.encode.lossless = true;
  const ImagerySummary s = ingest_ok(options);
  EXPECT_EQ(s.sources[0].bands, "RGBA");
  auto store = store::TileStore::open(options.store_path, store::TileStore::Mode::read_only);
  const Canvas c = paste_level(*store, "ortho", s.max_level);
  expect_markers_in_place(o, c, 0.6, 40);
  // The west tenth of the source (alpha 0) is transparent; the rest opaque.
  for (const double column : {10.0, 30.0}) {
    const auto crs = o.crs_of(column, 150);
    const auto ll = testing::to_lonlat(32611, crs[0], crs[1]);
    const auto p = c.pixel(geo::Projection::spherical, ll[0], ll[1]);
    EXPECT_EQ(c.at(static_cast<int>(p[0]), static_cast<int>(p[1]))[3], 0) << column;
  }
  for (const double column : {60.0, 200.0}) {
    const auto crs = o.crs_of(column, 150);
    const auto ll = testing::to_lonlat(32611, crs[0], crs[1]);
    const auto p = c.pixel(geo::Projection::spherical, ll[0], ll[1]);
    EXPECT_EQ(c.at(static_cast<int>(p[0]), static_cast<int>(p[1]))[3], 255) << column;
  }
}

// A source in EPSG:3857 covering exactly one level-14 tile with 512 × 512 pixels: its four
// level-15 tiles must be its four quadrants pixel for pixel (nearest-neighbour resampling), no
// other level-15 tile may exist, and the level-14 tile is their downsampling. So an imagery
// tile covers exactly the quadtree tile of its quadkey — the rectangle of the terrain tile of
// that quadkey.
TEST(IngestImagery, TileOfAQuadkeyCoversExactlyTheQuadtreeTileOfThatQuadkey) {
  TempDir dir;
  const geo::TileId tile{14, 2625, 6369};
  const geo::MercatorRect r = tile.bounds();
  const double scale = 20037508.342789244;
  const fs::path path = dir / "aligned.tif";
  std::mt19937_64 rng(11);
  std::vector<std::array<std::uint8_t, 3>> pixels(std::size_t{512} * 512);
  for (auto& p : pixels)
    p = {static_cast<std::uint8_t>(rng()), static_cast<std::uint8_t>(rng()),
         static_cast<std::uint8_t>(rng())};
  {
    // Written through the marker writer's GeoTIFF path is not flexible enough: use GDAL here.
    const Orthophoto blank = testing::write_marker_orthophoto(
        path, 3857, r.min_x * scale, r.max_y * scale, r.width() * scale / 512, 512, 512);
    (void)blank;
  }
  // Overwrite the bands with the random pixels.
  {
    GDALAllRegister();
    GDALDatasetH ds = GDALOpen(path.c_str(), GA_Update);
    ASSERT_NE(ds, nullptr);
    std::vector<std::uint8_t> plane(std::size_t{512} * 512);
    for (int b = 0; b < 3; ++b) {
      for (std::size_t i = 0; i < plane.size(); ++i)
        plane[i] = pixels[i][static_cast<std::size_t>(b)];
      ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(ds, b + 1), GF_Write, 0, 0, 512, 512, plane.data(),
                             512, 512, GDT_Byte, 0, 0),
                CE_None);
    }
    GDALClose(ds);
  }
  auto options = options_for(dir / "s.db", "aligned", {path});
  options.resampling = "near";
  options.min_level = 13;
  const ImagerySummary s = ingest_ok(options);
  ASSERT_EQ(s.max_level, 15u);
  auto store = store::TileStore::open(options.store_path, store::TileStore::Mode::read_only);
  auto level15 = store->imagery_tile_ids("aligned", 15);
  ASSERT_TRUE(level15.ok());
  const auto children = tile.children();
  std::vector<geo::TileId> sorted(children.begin(), children.end());
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(*level15, sorted);
  for (std::size_t k = 0; k < 4; ++k) {
    const auto decoded = testing::gdal_decode((**store->imagery_tile("aligned", children[k])).data);
    ASSERT_EQ(decoded.width, 256);
    const int ox = (k & 1u) != 0 ? 256 : 0, oy = (k & 2u) != 0 ? 256 : 0;
    int wrong = 0;
    for (int y = 0; y < 256; ++y) {
      for (int x = 0; x < 256; ++x) {
        const auto& want = pixels[static_cast<std::size_t>(oy + y) * 512 + ox + x];
        const std::uint8_t* got = decoded.at(x, y);
        if (got[0] != want[0] || got[1] != want[1] || got[2] != want[2] || got[3] != 255) ++wrong;
      }
    }
    EXPECT_EQ(wrong, 0) << "child " << k;
  }
  // Level 14 is the 2:1 downsampling of the source (every pixel of a random image differs from
  // each of its four sources, so nearest-neighbour would fail).
  const auto parent = testing::gdal_decode((**store->imagery_tile("aligned", tile)).data);
  ASSERT_EQ(parent.width, 256);
  const auto linear = [](double c) {
    c /= 255;
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
  };
  const auto srgb = [](double l) {
    return 255 * (l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1 / 2.4) - 0.055);
  };
  for (int y = 0; y < 256; y += 7) {
    for (int x = 0; x < 256; x += 5) {
      for (int ch = 0; ch < 3; ++ch) {
        double sum = 0;
        for (int d = 0; d < 4; ++d) {
          sum +=
              linear(pixels[static_cast<std::size_t>(2 * y + d / 2) * 512 +
                            static_cast<std::size_t>(2 * x + d % 2)][static_cast<std::size_t>(ch)]);
        }
        EXPECT_NEAR(parent.at(x, y)[ch], srgb(sum / 4), 1.01) << x << "," << y;
      }
    }
  }
  EXPECT_EQ(store->imagery_tile_ids("aligned", 13)->size(), 1u);
  EXPECT_EQ(store->imagery_tile_ids("aligned", 12)->size(), 0u);  // below --min-level
}

// Big Tujunga (real SRTM DEM in UTM 11N) turned into a shaded colour orthophoto: at points all
// over the footprint the stored tiles show the source's colour of that lon/lat, and clearly less
// so one source pixel (30 m) off in any direction.
TEST(IngestImagery, RealUtmOrthophotoLandsWhereTheSourceHasIt) {
  const fs::path dem = fs::path(TINSTREAM_SHARED_DATA) / "bigtujunga_srtm30m_utm11.tif";
  if (!fs::exists(dem)) GTEST_SKIP() << "shared data absent: " << dem;
  TempDir dir;
  const fs::path ortho = dir / "tujunga_rgb.tif";
  ASSERT_TRUE(testing::write_orthophoto_from_dem(dem, ortho));
  auto options = options_for(dir / "s.db", "tujunga", {ortho});
  options.format = ImageFormat::jpeg;
  options.encode.quality = 92;
  const ImagerySummary s = ingest_ok(options);
  // 30 m pixels at about 34.32° N.
  EXPECT_EQ(s.native_level, expected_native_level(30.0, 34.32));
  EXPECT_EQ(s.sources[0].driver, "GTiff");

  auto store = store::TileStore::open(options.store_path, store::TileStore::Mode::read_only);
  const Canvas c = paste_level(*store, "tujunga", s.max_level);
  // The source raster in memory, sampled bilinearly at UTM coordinates.
  GDALDatasetH ds = GDALOpen(ortho.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  double gt[6];
  GDALGetGeoTransform(ds, gt);
  std::vector<std::uint8_t> green(static_cast<std::size_t>(w) * h);
  ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(ds, 2), GF_Read, 0, 0, w, h, green.data(), w, h,
                         GDT_Byte, 0, 0),
            CE_None);
  GDALClose(ds);
  const auto source_at = [&](double e, double n) {
    const double fx = (e - gt[0]) / gt[1] - 0.5, fy = (n - gt[3]) / gt[5] - 0.5;
    const int x = static_cast<int>(std::floor(fx)), y = static_cast<int>(std::floor(fy));
    const double ax = fx - x, ay = fy - y;
    const auto v = [&](int i, int j) { return double(green[static_cast<std::size_t>(j) * w + i]); };
    return (1 - ay) * ((1 - ax) * v(x, y) + ax * v(x + 1, y)) +
           ay * ((1 - ax) * v(x, y + 1) + ax * v(x + 1, y + 1));
  };
  const auto tile_at = [&](double lon, double lat) {
    const auto p = c.pixel(geo::Projection::spherical, lon, lat);
    // Bilinear between canvas pixel centres.
    const double fx = p[0] - 0.5, fy = p[1] - 0.5;
    const int x = static_cast<int>(std::floor(fx)), y = static_cast<int>(std::floor(fy));
    const double ax = fx - x, ay = fy - y;
    const auto v = [&](int i, int j) { return double(c.at(i, j)[1]); };
    return (1 - ay) * ((1 - ax) * v(x, y) + ax * v(x + 1, y)) +
           ay * ((1 - ax) * v(x, y + 1) + ax * v(x + 1, y + 1));
  };
  const double shifts[5][2] = {{0, 0}, {30, 0}, {-30, 0}, {0, 30}, {0, -30}};
  double error[5] = {0, 0, 0, 0, 0};
  int samples = 0;
  for (int j = 0; j < 40; ++j) {
    for (int i = 0; i < 60; ++i) {
      // Inside the raster, 10 pixels away from its edges.
      const double e = gt[0] + gt[1] * (10 + (w - 20) * (i + 0.5) / 60);
      const double n = gt[3] + gt[5] * (10 + (h - 20) * (j + 0.5) / 40);
      const auto ll = testing::to_lonlat(32611, e, n);
      const double seen = tile_at(ll[0], ll[1]);
      for (int k = 0; k < 5; ++k) {
        error[k] += std::abs(seen - source_at(e + shifts[k][0], n + shifts[k][1]));
      }
      ++samples;
    }
  }
  for (double& e : error) e /= samples;
  EXPECT_LT(error[0], 6.0) << "mean |Δgreen| at the right place";
  for (int k = 1; k < 5; ++k) {
    EXPECT_LT(error[0], 0.6 * error[k]) << "shift " << shifts[k][0] << "," << shifts[k][1] << ": "
                                        << error[0] << " vs " << error[k];
  }
}

// Two files side by side form one mosaic: the tiles are those of the single file they were cut
// from — no transparent seam, no shift — up to resampling at the cut.
TEST(IngestImagery, AdjacentFilesFormOneMosaicWithoutSeam) {
  TempDir dir;
  const Orthophoto whole =
      testing::write_marker_orthophoto(dir / "whole.tif", 32611, 390000, 3800000, 4.0, 400, 300);
  GDALAllRegister();
  GDALDatasetH src = GDALOpen(whole.path.c_str(), GA_ReadOnly);
  ASSERT_NE(src, nullptr);
  for (const auto& [name, x0] : {std::pair{"west.tif", 0}, std::pair{"east.tif", 200}}) {
    std::string x = std::to_string(x0);
    char* argv[] = {const_cast<char*>("-srcwin"), x.data(),
                    const_cast<char*>("0"),       const_cast<char*>("200"),
                    const_cast<char*>("300"),     nullptr};
    GDALTranslateOptions* o = GDALTranslateOptionsNew(argv, nullptr);
    GDALDatasetH part = GDALTranslate((dir / name).c_str(), src, o, nullptr);
    GDALTranslateOptionsFree(o);
    ASSERT_NE(part, nullptr);
    GDALClose(part);
  }
  GDALClose(src);
  const ImagerySummary one = ingest_ok(options_for(dir / "one.db", "o", {whole.path}));
  const ImagerySummary two =
      ingest_ok(options_for(dir / "two.db", "o", {dir / "west.tif", dir / "east.tif"}));
  ASSERT_EQ(two.sources.size(), 2u);
  ASSERT_EQ(two.max_level, one.max_level);
  EXPECT_EQ(two.levels.back().tiles, one.levels.back().tiles);
  auto a = store::TileStore::open(dir / "one.db", store::TileStore::Mode::read_only);
  auto b = store::TileStore::open(dir / "two.db", store::TileStore::Mode::read_only);
  const Canvas ca = paste_level(*a, "o", one.max_level);
  const Canvas cb = paste_level(*b, "o", one.max_level);
  ASSERT_EQ(ca.image.rgba.size(), cb.image.rgba.size());
  int differ = 0, max_diff = 0, holes = 0;
  for (std::size_t i = 0; i < ca.image.rgba.size(); ++i) {
    const int d = std::abs(int(ca.image.rgba[i]) - int(cb.image.rgba[i]));
    max_diff = std::max(max_diff, d);
    differ += d > 2 ? 1 : 0;
    if (i % 4 == 3) holes += ca.image.rgba[i] == 255 && cb.image.rgba[i] < 255 ? 1 : 0;
  }
  EXPECT_EQ(holes, 0) << "pixels the single file covers that the mosaic leaves (partly) open";
  // The cut is one source column: at most a few hundred channel values along it may differ.
  EXPECT_LT(differ, 4 * 300) << "max difference " << max_diff;
  expect_markers_in_place(whole, cb, 0.6, 40);
}

TEST(IngestImagery, BadSourcesGetClearErrors) {
  TempDir dir;
  const fs::path text = dir / "notes.tif";
  std::ofstream(text) << "not a raster\n";
  auto r = ingest_imagery(options_for(dir / "s.db", "x", {text}));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("notes.tif"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("GDAL cannot open"), std::string::npos) << r.error().message;

  r = ingest_imagery(options_for(dir / "s.db", "x", {dir / "missing.tif"}));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("missing.tif"), std::string::npos);

  // A 16-bit raster (a DEM) is not imagery.
  {
    GDALAllRegister();
    GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), (dir / "dem.tif").c_str(), 8, 8, 1,
                                 GDT_Int16, nullptr);
    double gt[6] = {390000, 30, 0, 3800000, 0, -30};
    GDALSetGeoTransform(ds, gt);
    GDALClose(ds);
  }
  r = ingest_imagery(options_for(dir / "s.db", "x", {dir / "dem.tif"}));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::unsupported);
  EXPECT_NE(r.error().message.find("8-bit"), std::string::npos) << r.error().message;

  // No CRS: refused, and accepted with --crs.
  {
    GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), (dir / "nocrs.tif").c_str(), 64, 64,
                                 3, GDT_Byte, nullptr);
    double gt[6] = {390000, 4, 0, 3800000, 0, -4};
    GDALSetGeoTransform(ds, gt);
    std::vector<std::uint8_t> plane(std::size_t{64} * 64, 200);
    for (int b = 1; b <= 3; ++b) {
      ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(ds, b), GF_Write, 0, 0, 64, 64, plane.data(), 64, 64,
                             GDT_Byte, 0, 0),
                CE_None);
    }
    GDALClose(ds);
  }
  r = ingest_imagery(options_for(dir / "s.db", "x", {dir / "nocrs.tif"}));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("no CRS; give one with --crs"), std::string::npos)
      << r.error().message;
  auto with_crs = options_for(dir / "s.db", "x", {dir / "nocrs.tif"});
  with_crs.crs = "EPSG:32611";
  r = ingest_imagery(with_crs);
  ASSERT_TRUE(r.ok()) << r.error().message;
  with_crs.crs = "EPSG:999999";
  r = ingest_imagery(with_crs);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("EPSG:999999"), std::string::npos);

  auto bad = options_for(dir / "s.db", "x", {dir / "nocrs.tif"});
  bad.crs = "EPSG:32611";
  bad.resampling = "sharpest";
  EXPECT_NE(ingest_imagery(bad).error().message.find("--resampling 'sharpest'"), std::string::npos);
  bad.resampling = "bilinear";
  bad.min_level = 30;
  EXPECT_NE(ingest_imagery(bad).error().message.find("--min-level 30"), std::string::npos);
}

// Every published imagery tile with its ETag, in z/x/y order: what a failed ingest must not change.
std::string published_imagery(const fs::path& db) {
  return sql_value(db,
                   "SELECT group_concat(z || '/' || x || '/' || y || '=' || etag, ' ') FROM "
                   "(SELECT * FROM published_imagery ORDER BY z, x, y)");
}

// What a failed or cancelled ingest leaves: the previous imagery exactly as it was, no version
// being built, an intact file.
TEST(IngestImagery, FailedOrCancelledIngestLeavesTheStoreAsItWas) {
  TempDir dir;
  const Orthophoto good =
      testing::write_marker_orthophoto(dir / "good.tif", 32611, 390000, 3800000, 4.0, 400, 300);
  const fs::path db = dir / "s.db";
  ingest_ok(options_for(db, "ortho", {good.path}));
  const auto state = [&] {
    return published_imagery(db) + " | versions " +
           sql_value(db, "SELECT group_concat(id || status) FROM imagery_versions");
  };
  const std::string before = state();
  ASSERT_NE(before.find("0/0/0="), std::string::npos) << before;

  // A second source that GDAL cannot open: refused before anything is written.
  auto r = ingest_imagery(options_for(db, "ortho", {good.path, dir / "absent.tif"}));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(state(), before);

  // A source whose pixels cannot be read (the file is cut after its header): fails while
  // tiles are being written.
  const Orthophoto big =
      testing::write_marker_orthophoto(dir / "big.tif", 32611, 391000, 3801000, 4.0, 1200, 900);
  fs::copy_file(big.path, dir / "cut.tif");
  const auto size = fs::file_size(dir / "cut.tif");
  fs::resize_file(dir / "cut.tif", size / 3);
  r = ingest_imagery(options_for(db, "ortho", {good.path, dir / "cut.tif"}));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("cut.tif"), std::string::npos) << r.error().message;
  EXPECT_EQ(state(), before);

  // Cancelled by its progress sink after a few tiles.
  int calls = 0;
  auto cancelled = ingest_imagery(options_for(db, "ortho", {big.path}), [&](const Progress& p) {
    return p.phase != "imagery" || ++calls < 2;
  });
  ASSERT_FALSE(cancelled.ok());
  EXPECT_EQ(cancelled.error().code, ErrorCode::cancelled);
  EXPECT_EQ(state(), before);
  EXPECT_EQ(sql_value(db, "PRAGMA integrity_check"), "ok");
  EXPECT_EQ(sql_value(db, "SELECT count(*) FROM imagery_versions WHERE status = 'building'"), "0");
}

// A worker that dies (an exception outside a tile's own error handling) or cannot be started
// fails the ingest with an error naming the workers — it neither hangs waiting for the tiles that
// worker took nor terminates the process — and the store keeps its published imagery.
TEST(IngestImagery, AWorkerThatDiesOrCannotStartFailsTheIngestAndKeepsTheStore) {
  if (!fault::enabled()) GTEST_SKIP() << "built without fault injection";
  TempDir dir;
  const Orthophoto good =
      testing::write_marker_orthophoto(dir / "good.tif", 32611, 390000, 3800000, 4.0, 400, 300);
  const fs::path db = dir / "s.db";
  ingest_ok(options_for(db, "ortho", {good.path}));
  const std::string before = published_imagery(db);
  struct Case {
    const char* point;
    fault::Kind kind;
    const char* message;
  };
  for (const Case& c :
       {Case{"imagery.render", fault::Kind::throw_error, "imagery worker: injected fault"},
        Case{"imagery.render", fault::Kind::out_of_memory, "imagery worker: out of memory"},
        Case{"imagery.worker.spawn", fault::Kind::no_thread,
             "imagery worker: cannot start a thread"}}) {
    SCOPED_TRACE(c.point);
    auto options = options_for(db, "ortho", {good.path});
    options.threads = 2;
    const fault::Arm arm(c.point, /*skip=*/1, c.kind);
    auto r = ingest_imagery(options);
    EXPECT_TRUE(arm.fired());
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find(c.message), std::string::npos) << r.error().message;
    EXPECT_EQ(published_imagery(db), before);
  }
  EXPECT_EQ(sql_value(db, "PRAGMA integrity_check"), "ok");
  EXPECT_EQ(sql_value(db, "SELECT count(*) FROM imagery_versions WHERE status = 'building'"), "0");
}

}  // namespace
}  // namespace tinstream::imagery
