// mosaic.hpp — the imagery sources as one mosaic in the layer's Mercator (GDAL).
//
// plan_mosaic() opens every source once (on the calling thread), checks that it is an 8-bit
// colour raster with a CRS, and measures its footprint and native resolution in the target
// Mercator: EPSG:3857 for spherical layers (normalised x, y times π·a are EPSG:3857 metres, so
// tiles are exactly the EPSG:3857 tiles), EPSG:3395 (World Mercator on WGS84) for ellipsoidal.
//
// A TileRenderer warps the sources into one tile at a time (GDALWarp into a 4-band in-memory
// dataset whose last band is alpha: pixels no source covers stay transparent, later sources are
// composited over earlier ones). It reads only the source windows under the tile, through GDAL's
// block cache, so memory does not grow with the sources. One TileRenderer per thread: it owns
// its GDAL handles (GDAL datasets are not thread-safe), opened on first use.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/imagery/image.hpp"

namespace tinstream::imagery {

struct SourcePlan {
  std::string path;
  std::string driver;   // GDAL's short name, e.g. "GTiff"
  std::string crs;      // the CRS read from the file (or given), as its name
  std::string crs_wkt;  // the same as WKT (empty: the file's own is used)
  std::int32_t width = 0, height = 0;
  std::string bands;           // "RGB", "RGBA", "gray", "gray+alpha", "palette"
  geo::MercatorRect bounds{};  // footprint in normalised Mercator, clamped to the map
  double resolution = 0;       // target Mercator metres per pixel (GDAL's suggestion)
};

struct MosaicPlan {
  geo::Projection projection = geo::Projection::spherical;
  std::vector<SourcePlan> sources;
  geo::MercatorRect bounds{};      // union of the footprints
  std::uint32_t native_level = 0;  // level whose 256-pixel tiles match the finest source
};

// `crs` (EPSG:n, WKT or PROJ string) overrides the files' own CRS; empty: each file's own, and a
// file without one is an error.
Result<MosaicPlan> plan_mosaic(const std::vector<std::filesystem::path>& paths,
                               const std::string& crs, geo::Projection projection,
                               std::uint32_t tile_size);

// GDAL resampling names accepted for the native level: near, bilinear, cubic, cubicspline,
// lanczos, average, mode.
Status check_resampling(const std::string& name);

class TileRenderer {
 public:
  TileRenderer(const MosaicPlan& plan, std::string resampling, std::uint32_t tile_size);
  ~TileRenderer();
  TileRenderer(const TileRenderer&) = delete;
  TileRenderer& operator=(const TileRenderer&) = delete;

  // The tile's pixels (transparent where no source covers it). Errors name the source.
  Result<RgbaImage> render(const geo::TileId& id);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Normalised Mercator ↔ target Mercator metres (EPSG:3857 / EPSG:3395): × or ÷ π·a.
inline constexpr double kMercatorMetresPerUnit = 20037508.342789244;

}  // namespace tinstream::imagery
