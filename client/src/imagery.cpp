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
    auto n = layer_name_from_json(i);
    if (!n) return n.error();
    if (*n != name) {
      known += (known.empty() ? "" : ", ") + *n;
      continue;
    }
    // The shared metadata (layer_common.hpp), the image format, and Mercator bounds from the
    // degrees (/layers gives imagery bounds in degrees only).
    return layer_from_json(i, [](LayerFields& f, LayerDescription& l) {
      l.kind = TileKind::imagery;
      l.image_format = f.get<std::string>("format");
      const geo::NormalisedMercator m(l.projection);
      l.mercator_bounds = {
          geo::NormalisedMercator::x_from_lon(l.bounds.west), m.y_from_lat(l.bounds.south),
          geo::NormalisedMercator::x_from_lon(l.bounds.east), m.y_from_lat(l.bounds.north)};
    });
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
