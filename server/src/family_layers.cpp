// Route family "layers": metadata of the published layers.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "families.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;

// An input's path as anyone may see it: its file name. Uploads are stored as
// upload-<16 hex>-<name>: the name the uploader gave. (Paths as the ingest recorded them are
// server paths: absolute, under the data root or the upload directory, or /proc/self/fd/N/….)
std::string public_source_name(const std::string& path) {
  std::string name = std::filesystem::path(path).filename().string();
  constexpr std::size_t kPrefix = 7, kHex = 16;  // "upload-", then 16 hex digits and '-'
  if (name.rfind("upload-", 0) == 0 && name.size() > kPrefix + kHex + 1 &&
      name[kPrefix + kHex] == '-' &&
      name.find_first_not_of("0123456789abcdef", kPrefix) == kPrefix + kHex) {
    name.erase(0, kPrefix + kHex + 1);
  }
  return name;
}

// The ingest options as stored, each input named by public_source_name().
json public_options(const std::string& stored) {
  json opts = json::parse(stored, nullptr, false);
  if (opts.is_discarded() || !opts.is_object()) return json::object();
  if (auto inputs = opts.find("inputs"); inputs != opts.end() && inputs->is_array()) {
    for (auto& input : *inputs) {
      if (!input.is_object()) continue;
      if (auto path = input.find("path"); path != input.end() && path->is_string())
        *path = public_source_name(path->get<std::string>());
    }
  }
  return opts;
}

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
  j["options"] = public_options(l.options_json);
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
