// The metadata a terrain layer and an imagery layer have in common, read in one place from each
// of the two forms they come in:
// - a store row (store::LayerInfo, store::ImageryInfo): common_description, which
//   from_store_info (layer.cpp) and from_imagery_info (imagery.cpp) complete;
// - the server's JSON (a terrain layer's document, an imagery entry of GET /layers):
//   layer_from_json, which parse_layer_json (layer.cpp) and parse_imagery_json (imagery.cpp)
//   complete. Its errors have one wording, naming the layer and the field:
//     layer "NAME": field "FIELD": REASON
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "tinstream/base/result.hpp"
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

// The fields of one layer object of the server's JSON, read by name. A read throws
// nlohmann::json::exception on a missing or mistyped field; error() then words it.
class LayerFields {
 public:
  explicit LayerFields(const nlohmann::json& object) : object_(object) {}

  // The field's value; throws when it is missing or not a T.
  template <typename T>
  T get(const char* field) {
    field_ = field;
    return object_.at(field).template get<T>();
  }
  // The field's value, `fallback` when it is missing; throws when it is not a T.
  template <typename T>
  T get_or(const char* field, T fallback) {
    field_ = field;
    return object_.value(field, std::move(fallback));
  }
  // The field itself (an object whose members the caller reads: errors name this field).
  const nlohmann::json& at(const char* field) {
    field_ = field;
    return object_.at(field);
  }
  // Names the layer in error() once its name is read.
  void set_layer_name(std::string name) { name_ = std::move(name); }

  // `e`, thrown by the last read, in the one wording (invalid_argument).
  Error error(const nlohmann::json::exception& e) const;
  // A failure of the layer as a whole or of one field's value: layer "NAME": WHAT.
  Error error(const std::string& what) const;

 private:
  const nlohmann::json& object_;
  const char* field_ = "";
  std::string name_;
};

// A layer object's name (the first thing read, to pick the layer from a list).
Result<std::string> layer_name_from_json(const nlohmann::json& object);

// The shared metadata of a layer object: name, projection, bounds (degrees), min_level,
// max_level, tile_count, version, created_unix, attribution (the last four optional); then
// `kind_fields` reads what only its kind has (mercator_bounds: terrain layers send theirs,
// imagery entries do not); then the levels are checked (min ≤ max ≤ geo::kMaxLevel).
using KindFieldsReader = std::function<void(LayerFields&, LayerDescription&)>;
Result<LayerDescription> layer_from_json(const nlohmann::json& object,
                                         const KindFieldsReader& kind_fields);

}  // namespace tinstream::client
