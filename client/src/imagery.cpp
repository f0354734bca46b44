#include "tinstream/client/imagery.hpp"

#include <nlohmann/json.hpp>
#include <string>

#include "layer_common.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {

using nlohmann::json;

LayerDescription from_imagery_info(const store::ImageryInfo& info) {
  LayerDescription l = common_description(info);
  l.kind = TileKind::imagery;
  l.image_format = info.format;
  return l;
}

Result<LayerDescription> parse_imagery_json(std::string_view layers_json, std::string_view name) {
  const json j = json::parse(layers_json, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    return invalid_argument("the layer list is not a JSON object");
  const auto it = j.find("imagery");
  if (it == j.end() || !it->is_array())
    return not_found("the server lists no imagery layers (no \"imagery\" in /layers)");
  std::string known;
  for (const json& i : *it) {
    try {
      const auto n = i.at("name").get<std::string>();
      if (n != name) {
        known += (known.empty() ? "" : ", ") + n;
        continue;
      }
      LayerDescription l;
      l.kind = TileKind::imagery;
      l.name = n;
      l.image_format = i.at("format").get<std::string>();
      auto projection = geo::parse_projection(i.at("projection").get<std::string>());
      if (!projection) return projection.error();
      l.projection = *projection;
      const json& b = i.at("bounds");
      l.bounds = {b.at("west").get<double>(), b.at("south").get<double>(),
                  b.at("east").get<double>(), b.at("north").get<double>()};
      // /layers gives imagery bounds in degrees only.
      const geo::NormalisedMercator m(l.projection);
      l.mercator_bounds = {
          geo::NormalisedMercator::x_from_lon(l.bounds.west), m.y_from_lat(l.bounds.south),
          geo::NormalisedMercator::x_from_lon(l.bounds.east), m.y_from_lat(l.bounds.north)};
      l.min_level = i.at("min_level").get<std::uint32_t>();
      l.max_level = i.at("max_level").get<std::uint32_t>();
      l.tile_count = i.value("tile_count", std::uint64_t{0});
      l.version = i.value("version", std::int64_t{0});
      l.created_unix = i.value("created_unix", std::int64_t{0});
      l.attribution = i.value("attribution", std::string());
      if (l.min_level > l.max_level || l.max_level > static_cast<std::uint32_t>(geo::kMaxLevel))
        return invalid_argument("imagery layer \"" + n + "\": levels " +
                                std::to_string(l.min_level) + "…" + std::to_string(l.max_level) +
                                " out of order or above 30");
      return l;
    } catch (const json::exception& e) {
      return invalid_argument(std::string("imagery layer metadata: ") + e.what());
    }
  }
  return not_found("no imagery layer \"" + std::string(name) +
                   "\" (the server has: " + (known.empty() ? "none" : known) + ")");
}

Result<imagery::RgbaImage> decode_imagery_tile(std::span<const std::uint8_t> payload,
                                               ContentEncoding encoding,
                                               const LayerDescription& layer, const TileKey& key) {
  const std::string what = "imagery tile " + key.tile.to_string() + " (" + key.tile.quadkey() +
                           ") of layer \"" + layer.name + "\": ";
  auto bytes = inflate_payload(payload, encoding);
  if (!bytes) return Error(bytes.error().code, what + bytes.error().message);
  constexpr std::uint64_t max_pixels = std::uint64_t{kMaxImageryTileSize} * kMaxImageryTileSize;
  auto image = imagery::decode(*bytes, max_pixels);
  if (!image) return Error(image.error().code, what + image.error().message);
  if (image->width != image->height || image->width == 0)
    return invalid_argument(what + "the image is " + std::to_string(image->width) + "×" +
                            std::to_string(image->height) + ", not square");
  return image;
}

std::array<float, 4> ancestor_uv(const geo::TileId& tile, const geo::TileId& ancestor) {
  const std::uint32_t d = tile.z - ancestor.z;
  const double s = 1.0 / static_cast<double>(std::uint64_t{1} << d);
  const double du = static_cast<double>(tile.x - (ancestor.x << d)) * s;
  const double dv = static_cast<double>(tile.y - (ancestor.y << d)) * s;
  return {static_cast<float>(s), static_cast<float>(s), static_cast<float>(du),
          static_cast<float>(dv)};
}

}  // namespace tinstream::client
