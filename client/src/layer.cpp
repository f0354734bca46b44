#include "tinstream/client/layer.hpp"

#include <nlohmann/json.hpp>

#include "layer_common.hpp"
#include "tinstream/client/tile_key.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {

using nlohmann::json;

double LayerDescription::level_error(std::uint32_t z) const {
  return z < level_max_error.size() ? level_max_error[z] : 0.0;
}

std::string LayerDescription::cache_version() const {
  return "v" + std::to_string(version) + "-" + std::to_string(created_unix);
}

bool LayerDescription::may_contain(const geo::TileId& id) const {
  if (id.z < min_level || id.z > max_level) return false;
  const geo::MercatorRect r = id.bounds();
  return r.min_x <= mercator_bounds.max_x && r.max_x >= mercator_bounds.min_x &&
         r.min_y <= mercator_bounds.max_y && r.max_y >= mercator_bounds.min_y;
}

namespace {

// A terrain layer's document: the shared metadata (layer_common.hpp) and its heights and errors.
Result<LayerDescription> from_json(const json& j) {
  return layer_from_json(j, [](LayerFields& f, LayerDescription& l) {
    const json& m = f.at("mercator_bounds");
    l.mercator_bounds = {m.at("min_x").get<double>(), m.at("min_y").get<double>(),
                         m.at("max_x").get<double>(), m.at("max_y").get<double>()};
    l.min_z = f.get<double>("min_z");
    l.max_z = f.get<double>("max_z");
    l.level_max_error = f.get<std::vector<double>>("level_max_error");
  });
}

}  // namespace

Result<LayerDescription> parse_layer_json(std::string_view text) {
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    return invalid_argument("layer metadata is not a JSON object");
  return from_json(j);
}

Result<std::vector<LayerDescription>> parse_layers_json(std::string_view text) {
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.contains("layers") || !j["layers"].is_array())
    return invalid_argument("the layer list is not {\"layers\": [...]}");
  std::vector<LayerDescription> out;
  for (const json& l : j["layers"]) {
    auto d = from_json(l);
    if (!d) return d.error();
    out.push_back(std::move(*d));
  }
  return out;
}

LayerDescription from_store_info(const store::LayerInfo& info) {
  LayerDescription l = common_description(info);
  l.min_z = info.min_z;
  l.max_z = info.max_z;
  l.level_max_error = info.level_max_error;
  return l;
}

std::string_view to_string(TileKind kind) {
  switch (kind) {
    case TileKind::terrain:
      return "terrain";
    case TileKind::imagery:
      return "imagery";
  }
  return "terrain";
}

}  // namespace tinstream::client
