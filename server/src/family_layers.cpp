// Route family "layers": metadata of the published layers.
#include <nlohmann/json.hpp>

#include "families.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;

json layer_to_json(const store::LayerInfo& l) {
  json j = {
      {"name", l.name},
      {"projection", geo::to_string(l.projection)},
      {"vertical_datum", l.vertical_datum},
      {"bounds",
       {{"west", l.bounds.west},
        {"south", l.bounds.south},
        {"east", l.bounds.east},
        {"north", l.bounds.north}}},
      {"mercator_bounds",
       {{"min_x", l.mercator_bounds.min_x},
        {"min_y", l.mercator_bounds.min_y},
        {"max_x", l.mercator_bounds.max_x},
        {"max_y", l.mercator_bounds.max_y}}},
      {"min_level", l.min_level},
      {"max_level", l.max_level},
      {"max_points", l.max_points},
      {"tile_count", l.tile_count},
      {"point_count", l.point_count},
      {"source_points", l.source_points},
      {"min_z", l.min_z},
      {"max_z", l.max_z},
      {"level_max_error", l.level_max_error},
      {"attribution", l.attribution},
      {"created_unix", l.created_unix},
      {"version", l.version},
  };
  json opts = json::parse(l.options_json, nullptr, false);
  j["options"] = opts.is_discarded() ? json::object() : opts;
  j["tiles"] = "/tiles/" + l.name + "/{quadkey}";
  if (l.projection == geo::Projection::spherical) {
    j["terrain"] = "/tiles/" + l.name + "/layer.json";
  } else {
    j["terrain"] = nullptr;
  }
  return j;
}

}  // namespace

Response serve(const Request&, Context& ctx, const LayersRoute&) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto layers = (*st)->layers();
  if (!layers) return error_response(layers.error());
  json arr = json::array();
  for (const auto& l : *layers) arr.push_back(layer_to_json(l));
  json document = {{"layers", arr}};
  if (Status s = add_imagery_metadata(ctx, document); !s) return error_response(s.error());
  return json_response(200, document.dump());
}

Response serve(const Request&, Context& ctx, const LayerRoute& r) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto info = (*st)->layer(r.layer);
  if (!info) return error_response(info.error());
  json document = layer_to_json(*info);
  if (Status s = add_imagery_metadata(ctx, document); !s) return error_response(s.error());
  return json_response(200, document.dump());
}

}  // namespace tinstream::server
