// tinstream/imagery/ingest_imagery.hpp — colour rasters → an imagery pyramid in the tile store.
//
// ingest_imagery() reads any 8-bit RGB(A), grey or palette raster GDAL opens (GeoTIFF
// orthophotos in any CRS; several files form one mosaic, later files drawn over earlier ones),
// reprojects it into the layer's Mercator quadtree (spherical: exactly the EPSG:3857 tiles) and
// writes 256 × 256 tiles at every level from the sources' native resolution (max_level) up to
// min_level: the finest level warped from the sources (GDAL, `resampling`), each coarser level
// downsampled 2:1 from its four children (imagery::downsample_children: linear-light box
// filter, alpha weighted). Tiles without a single visible pixel are not stored.
//
// The finest tiles are visited depth-first in quadkey (Morton) order, rendered and encoded on
// `threads` workers (each with its own GDAL handles) and handed back in that order, so a parent
// is complete as soon as its last child is: memory holds the tiles in flight (a few per worker)
// plus at most four child images per level, whatever the size of the sources. GDAL's block
// cache is set to half of `memory_bytes` (a process-wide GDAL setting).
//
// The layer is written as a new imagery version and published atomically at the end
// (store::ImageryWriter): a failed, cancelled or killed ingest leaves the previous imagery and
// every terrain layer as they were. Runs on the calling thread (plus its workers); progress goes
// to `progress` (phase "imagery", unit "tiles", then "publish"); a sink returning false cancels.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/imagery/image.hpp"

namespace tinstream::imagery {

struct ImageryIngestOptions {
  std::filesystem::path store_path;
  std::string layer;
  std::vector<std::filesystem::path> sources;
  std::string crs;  // overrides every source's CRS (EPSG:n, WKT, PROJ string); empty: the files'
  // Empty: the projection of the terrain layer of the same name, else spherical.
  std::optional<geo::Projection> projection;
  std::optional<std::uint32_t> max_level;  // empty: the sources' native level
  std::uint32_t min_level = 0;
  ImageFormat format = ImageFormat::png;
  EncodeOptions encode;
  std::string resampling = "bilinear";  // GDAL's name, for the finest level
  unsigned threads = 0;                 // 0: one per core
  std::size_t memory_bytes = 256u << 20;
  std::string attribution;
};

struct ImagerySourceSummary {
  std::string path, driver, crs, bands;
  std::int32_t width = 0, height = 0;
  double resolution = 0;  // Mercator metres per source pixel
};

struct ImageryLevelSummary {
  std::uint32_t level = 0;
  std::uint64_t tiles = 0;
  std::uint64_t bytes = 0;
};

struct ImagerySummary {
  std::string layer;
  std::string format;
  geo::Projection projection = geo::Projection::spherical;
  std::string projection_rule;  // why this projection ("--projection", "terrain layer", "default")
  std::uint32_t native_level = 0, min_level = 0, max_level = 0;
  std::vector<ImagerySourceSummary> sources;
  std::vector<ImageryLevelSummary> levels;  // min_level … max_level
  std::uint64_t tiles = 0, bytes = 0;
  std::uint64_t finest_visited = 0;  // finest tiles rendered, stored or not
  geo::LonLatRect bounds{};
  double seconds = 0;
};

Result<ImagerySummary> ingest_imagery(const ImageryIngestOptions& options,
                                      const ProgressSink& progress = {});

}  // namespace tinstream::imagery
