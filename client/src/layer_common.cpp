#include "layer_common.hpp"

namespace tinstream::client {

using nlohmann::json;

Error LayerFields::error(const std::string& what) const {
  return invalid_argument(
      (name_.empty() ? std::string("a layer without a name") : "layer \"" + name_ + "\"") + ": " +
      what);
}

Error LayerFields::error(const json::exception& e) const {
  std::string reason;
  if (object_.is_object() && !object_.contains(field_)) {
    reason = "missing";
  } else {
    // nlohmann's "[json.exception.type_error.302] type must be number, but is string": the
    // reason without the tag.
    reason = e.what();
    if (const auto tag_end = reason.find("] ");
        reason.starts_with("[json.") && tag_end != reason.npos)
      reason.erase(0, tag_end + 2);
  }
  return error("field \"" + std::string(field_) + "\": " + reason);
}

Result<std::string> layer_name_from_json(const json& object) {
  LayerFields f(object);
  try {
    return f.get<std::string>("name");
  } catch (const json::exception& e) {
    return f.error(e);
  }
}

Result<LayerDescription> layer_from_json(const json& object, const KindFieldsReader& kind_fields) {
  LayerFields f(object);
  LayerDescription l;
  try {
    l.name = f.get<std::string>("name");
    f.set_layer_name(l.name);
    auto projection = geo::parse_projection(f.get<std::string>("projection"));
    if (!projection) return f.error("field \"projection\": " + projection.error().message);
    l.projection = *projection;
    const json& b = f.at("bounds");
    l.bounds = {b.at("west").get<double>(), b.at("south").get<double>(), b.at("east").get<double>(),
                b.at("north").get<double>()};
    l.min_level = f.get<std::uint32_t>("min_level");
    l.max_level = f.get<std::uint32_t>("max_level");
    l.tile_count = f.get_or("tile_count", std::uint64_t{0});
    l.version = f.get_or("version", std::int64_t{0});
    l.created_unix = f.get_or("created_unix", std::int64_t{0});
    l.attribution = f.get_or("attribution", std::string());
    kind_fields(f, l);
  } catch (const json::exception& e) {
    return f.error(e);
  }
  if (l.min_level > l.max_level || l.max_level > static_cast<std::uint32_t>(geo::kMaxLevel))
    return f.error("levels " + std::to_string(l.min_level) + "…" + std::to_string(l.max_level) +
                   " out of order or above " + std::to_string(geo::kMaxLevel));
  return l;
}

}  // namespace tinstream::client
