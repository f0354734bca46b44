// tinstream/terrain/layer_json.hpp — Cesium's layer.json (tilejson 2.1.0 + quantized-mesh keys).
//
// `available` lists, per level 0 … maxzoom, the tiles that exist as merged TMS rectangles
// {startX, startY, endX, endY} (inclusive). Cesium's WebMercatorTilingScheme starts from the
// single level-0 tile and refines downwards, so the ancestors of the coarsest stored tiles are
// listed too, and every tile of levels 0 and 1 (kWholeLevels below): the server synthesises
// them as flat tiles (flat_tile()) and the static export writes them. Other tiles are absent;
// Cesium upsamples their parents there.
// Pure functions, thread-safe.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tinstream/geo/tile_id.hpp"

namespace tinstream::terrain {

// An inclusive rectangle of TMS tile indices at one level.
struct TileRange {
  std::uint32_t start_x = 0, start_y = 0, end_x = 0, end_y = 0;
  friend bool operator==(const TileRange&, const TileRange&) = default;
};

// Merges the tiles of one level (XYZ rows, any order, duplicates allowed) into few rectangles in
// TMS rows: runs along each row, then vertical merging of identical runs on consecutive rows.
// The union of the result is exactly the input set; rectangles do not overlap.
std::vector<TileRange> merge_ranges(std::vector<geo::TileId> tiles_of_one_level);

struct LayerJsonInput {
  std::string name;
  std::string description;
  std::string attribution;
  std::string version = "1.0.0";  // tiles URLs get ?v=<version> so caches see new layer versions
  geo::LonLatRect bounds{};
  std::uint32_t min_level = 0;        // coarsest stored level
  std::uint32_t max_level = 0;        // finest stored level
  std::vector<geo::TileId> tile_ids;  // every stored tile
  bool oct_vertex_normals = true;     // advertise the extension
};

// Levels whose every tile layer.json lists and the server (or the static export) provides,
// flat where nothing is stored: 0 and 1. CesiumJS cannot stand in for a missing level-1 tile by
// upsampling its parent: a tile 180° wide has no horizon-occlusion point, CesiumJS's upsampler
// then builds no terrain data, and the tile stays failed and queued — `globe.tilesLoaded` never
// holds again (found by bench/client's CesiumJS run). From level 2 (90° tiles) on it can.
inline constexpr std::uint32_t kWholeLevels = 2;

// The filler rule, stated once for layer.json, the static export and the server: a tile that is
// not stored is a filler (filler_tile()) when it lies on a whole level (z < kWholeLevels), or
// above the coarsest stored level (z < min_level) over the layer's data. `over_data` says
// whether data lies under the tile: synthetic_tiles() knows it exactly (a stored tile of
// min_level lies under it); the server, which has only the layer's row, asks may_be_filler().
bool is_filler(std::uint32_t z, std::uint32_t min_level, bool over_data);

// is_filler() for a layer known by its row only: over the data = the tile shares at least a
// point with `data_bounds` (store::LayerInfo::mercator_bounds, which holds every stored tile's
// data). Every tile synthetic_tiles() lists passes; so does a tile over a gap of the data at
// min_level or one that only touches the bounds, which layer.json does not list (the server
// serves it when asked; Cesium does not ask). Bounded by the layer's extent either way.
bool may_be_filler(const geo::TileId& id, std::uint32_t min_level,
                   const geo::MercatorRect& data_bounds);

// The tiles to synthesise as fillers, by is_filler(): the ancestors of the stored tiles above
// `min_level` (levels 0 … min_level − 1, so that Cesium's refinement from the single level-0
// tile reaches them), and every tile of the levels below kWholeLevels; stored tiles excluded.
// Sorted, without duplicates.
std::vector<geo::TileId> synthetic_tiles(const std::vector<geo::TileId>& stored,
                                         std::uint32_t min_level);

// The layer.json document (UTF-8 JSON text).
std::string layer_json(const LayerJsonInput& input);

}  // namespace tinstream::terrain
