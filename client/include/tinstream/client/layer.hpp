// tinstream/client/layer.hpp — what the client knows about a layer before loading any tile.
//
// Filled from the server's `GET /layers/{layer}` (parse_layer_json) or from a store's layer row
// (from_store_info); immutable once the viewer has started, shared read-only by every thread.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/tile_key.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/geo/tile_id.hpp"

namespace tinstream::store {
struct LayerInfo;
}

namespace tinstream::client {

struct LayerDescription {
  std::string name;
  // An imagery layer (imagery.hpp) has no heights and no errors; it shares the loader's layer
  // table so that its tiles travel through the same pool and tiers.
  TileKind kind = TileKind::terrain;
  std::string image_format;  // imagery: "png", "jpeg" or "webp"
  geo::Projection projection = geo::Projection::spherical;
  geo::MercatorRect mercator_bounds{};  // of the data
  geo::LonLatRect bounds{};             // of the data, degrees
  std::uint32_t min_level = 0;
  std::uint32_t max_level = 0;
  double min_z = 0, max_z = 0;
  std::vector<double> level_max_error;  // index: level
  std::uint64_t tile_count = 0;
  std::int64_t version = 0;
  std::int64_t created_unix = 0;
  std::string attribution;

  // The largest stored geometric error of level z (0 beyond the table).
  double level_error(std::uint32_t z) const;
  // Identifies this publication of the layer for the disk cache ("v<version>-<created>"): a
  // store rebuilt from scratch restarts its versions at 1, the creation time tells them apart.
  std::string cache_version() const;
  // Whether tile `id` can hold data of this layer: its rectangle meets the data bounds and its
  // level lies in [min_level, max_level].
  bool may_contain(const geo::TileId& id) const;
};

// Parses one layer object of the server's /layers or /layers/{layer} answer. Errors name the
// missing or malformed field.
Result<LayerDescription> parse_layer_json(std::string_view text);
// Parses the {"layers":[…]} answer of GET /layers.
Result<std::vector<LayerDescription>> parse_layers_json(std::string_view text);
LayerDescription from_store_info(const store::LayerInfo& info);

}  // namespace tinstream::client
