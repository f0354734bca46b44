// The metadata a store's terrain layer (store::LayerInfo) and imagery layer (store::ImageryInfo)
// have in common, copied into a LayerDescription: from_store_info (layer.cpp) and
// from_imagery_info (imagery.cpp) add what only their kind has.
#pragma once

#include "tinstream/client/layer.hpp"

namespace tinstream::client {

// StoreInfo: store::LayerInfo or store::ImageryInfo (the fields named below, same meaning).
template <typename StoreInfo>
LayerDescription common_description(const StoreInfo& info) {
  LayerDescription l;
  l.name = info.name;
  l.projection = info.projection;
  l.mercator_bounds = info.mercator_bounds;
  l.bounds = info.bounds;
  l.min_level = info.min_level;
  l.max_level = info.max_level;
  l.tile_count = info.tile_count;
  l.version = info.version;
  l.created_unix = info.created_unix;
  l.attribution = info.attribution;
  return l;
}

}  // namespace tinstream::client
