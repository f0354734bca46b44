// tinstream/terrain/layer_json.hpp — Cesium's layer.json (tilejson 2.1.0 + quantized-mesh keys).
//
// `available` lists, per level 0 … maxzoom, the tiles that exist as merged TMS rectangles
// {startX, startY, endX, endY} (inclusive). Cesium's WebMercatorTilingScheme starts from the
// single level-0 tile and refines downwards, so the ancestors of the coarsest stored tiles are
// listed too: the server synthesises them as flat tiles (flat_tile()) and the static export
// writes them. Other tiles are absent; Cesium upsamples their parents there.
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

// The tiles above `min_level` that lead to the stored tiles: every ancestor (levels 0 …
// min_level − 1) of a stored tile at level ≥ min_level, sorted, without duplicates.
std::vector<geo::TileId> synthetic_ancestors(const std::vector<geo::TileId>& stored,
                                             std::uint32_t min_level);

// The layer.json document (UTF-8 JSON text).
std::string layer_json(const LayerJsonInput& input);

}  // namespace tinstream::terrain
