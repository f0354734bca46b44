// Route family "imagery": imagery tiles from the store's imagery tables, and the raster-DEM part
// of family "tiles": Terrarium / Terrain-RGB PNGs rendered from the TIN of the same tile
// (terrain/raster_dem.hpp), cached like quantized-mesh in the TerrainCache. Also the imagery
// metadata that /layers carries.
#include <algorithm>
#include <nlohmann/json.hpp>

#include "families.hpp"
#include "negotiation.hpp"
#include "tinstream/imagery/image.hpp"
#include "tinstream/terrain/raster_dem.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;

std::string extension_of(const std::string& format) { return format == "jpeg" ? "jpg" : format; }

std::string mime_of(const std::string& format) { return "image/" + format; }

// Tile headers shared by imagery and raster-DEM answers.
void set_tile_headers(Response& res, const ServerConfig& config, const std::string& etag) {
  res.set("ETag", etag);
  res.set("Cache-Control", cache_control(config));
}

json imagery_to_json(const store::ImageryInfo& i) {
  const std::string ext = extension_of(i.format);
  json j = {
      {"name", i.name},
      {"format", i.format},
      {"projection", geo::to_string(i.projection)},
      {"tile_size", i.tile_size},
      {"bounds",
       {{"west", i.bounds.west},
        {"south", i.bounds.south},
        {"east", i.bounds.east},
        {"north", i.bounds.north}}},
      {"min_level", i.min_level},
      {"max_level", i.max_level},
      {"tile_count", i.tile_count},
      {"attribution", i.attribution},
      {"created_unix", i.created_unix},
      {"version", i.version},
      {"tiles", "/imagery/" + i.name + "/{z}/{x}/{y}." + ext},
      {"quadkey_tiles", "/imagery/" + i.name + "/{quadkey}"},
  };
  json opts = json::parse(i.options_json, nullptr, false);
  j["options"] = opts.is_discarded() ? json::object() : opts;
  return j;
}

// The raster-DEM URL templates of a terrain layer object (spherical layers only).
void add_raster_dem(json& layer) {
  const bool spherical = layer.value("projection", "") == "spherical";
  const std::string name = layer.value("name", "");
  layer["raster_dem"] =
      spherical ? json{{"terrarium", "/tiles/" + name + "/{z}/{x}/{y}.png?encoding=terrarium"},
                       {"mapbox", "/tiles/" + name + "/{z}/{x}/{y}.png?encoding=mapbox"}}
                : json(nullptr);
}

// The DEM tile's PNG, rendered and encoded; or the answer that replaces it.
std::variant<std::shared_ptr<const CachedBody>, Response> render_dem(const Request& req,
                                                                     Context& ctx,
                                                                     const DemTileRoute& r,
                                                                     terrain::DemEncoding encoding,
                                                                     terrain::DemNodata nodata) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto stored = (*st)->tile(r.layer, r.id);
  if (!stored) return error_response(stored.error());
  if (!stored->has_value()) {
    return json_error(404, "no terrain tile " + r.id.to_string() + " in layer \"" + r.layer + "\"");
  }
  std::string base = (**stored).etag;
  base.erase(std::remove(base.begin(), base.end(), '"'), base.end());
  const std::string etag = "\"dem-" + r.encoding +
                           (nodata == terrain::DemNodata::transparent ? "-t-" : "-") + base + "\"";
  if (etag_matches(req.if_none_match, etag)) {
    Response res;
    set_tile_headers(res, ctx.config, etag);
    res.status = 304;
    return res;
  }
  auto tin = store::decode_tile(**stored);
  if (!tin) return json_error(500, "tile " + r.id.to_string() + ": " + tin.error().message);
  auto raster = terrain::render_raster_dem(*tin, encoding, 256, nodata);
  if (!raster) return error_response(raster.error());
  imagery::RgbaImage image;
  image.width = image.height = raster->size;
  image.pixels = std::move(raster->rgba);
  imagery::EncodeOptions options;
  options.fast = true;  // made per request (then cached): speed over the last few percent
  auto png = imagery::encode(image, imagery::ImageFormat::png, options);
  if (!png) return error_response(png.error());
  return std::make_shared<const CachedBody>(
      CachedBody{etag, std::string(png->begin(), png->end()), nullptr});
}

}  // namespace

Response serve(const Request& req, Context& ctx, const DemTileRoute& r) {
  auto found = layer_info(ctx, r.layer);
  if (!found) return error_response(found.error());
  const store::LayerInfo& info = **found;
  if (info.projection != geo::Projection::spherical) {
    return json_error(409, "layer \"" + info.name +
                               "\" uses ellipsoidal Mercator; raster-DEM tiles exist only for "
                               "spherical-Mercator (EPSG:3857) layers");
  }
  const auto encoding = terrain::parse_dem_encoding(r.encoding);
  if (!encoding) return error_response(encoding.error());
  const auto nodata = terrain::parse_dem_nodata(r.nodata);
  if (!nodata) return error_response(nodata.error());
  const std::string key = "dem|" + r.layer + "|" + std::to_string(info.version) + "|" +
                          r.id.quadkey() + "|" + r.encoding + "|" + r.nodata;
  std::shared_ptr<const CachedBody> body =
      ctx.terrain_cache ? ctx.terrain_cache->get(key) : nullptr;
  if (!body) {
    auto rendered = render_dem(req, ctx, r, *encoding, *nodata);
    if (auto* answer = std::get_if<Response>(&rendered)) return std::move(*answer);
    body = std::move(std::get<std::shared_ptr<const CachedBody>>(rendered));
    if (ctx.terrain_cache) ctx.terrain_cache->put(key, body);
  }
  Response res;
  set_tile_headers(res, ctx.config, body->etag);
  if (etag_matches(req.if_none_match, body->etag)) {
    res.status = 304;
    return res;
  }
  res.set("Content-Type", "image/png");
  res.shared_body = std::shared_ptr<const std::string>(body, &body->bytes);
  return res;
}

Response serve(const Request& req, Context& ctx, const ImageryTileRoute& r) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto info = (*st)->imagery_layer(r.layer);
  if (!info) return error_response(info.error());
  const std::string ext = extension_of(info->format);
  if (!r.extension.empty() && r.extension != ext) {
    return json_error(404, "imagery layer \"" + r.layer + "\" is " + info->format +
                               ": use /imagery/" + r.layer + "/{z}/{x}/{y}." + ext);
  }
  auto tile = (*st)->imagery_tile(r.layer, r.id);
  if (!tile) return error_response(tile.error());
  if (!tile->has_value()) {
    return json_error(404, "no imagery tile " + r.id.to_string() + " (" + r.id.quadkey() +
                               ") in layer \"" + r.layer + "\"");
  }
  Response res;
  set_tile_headers(res, ctx.config, (**tile).etag);
  if (etag_matches(req.if_none_match, (**tile).etag)) {
    res.status = 304;
    return res;
  }
  res.set("Content-Type", mime_of(info->format));
  res.body.assign((**tile).data.begin(), (**tile).data.end());
  return res;
}

Status add_imagery_metadata(Context& ctx, json& document) {
  auto st = get_store(ctx);
  if (!st) return st.error();
  auto imagery = (*st)->imagery_layers();
  if (!imagery) return imagery.error();
  const auto same_name = [&](const json& layer) -> json {
    const std::string name = layer.value("name", "");
    for (const auto& i : *imagery) {
      if (i.name == name) return imagery_to_json(i);
    }
    return nullptr;
  };
  if (document.contains("layers")) {
    for (json& layer : document["layers"]) {
      layer["imagery"] = same_name(layer);
      add_raster_dem(layer);
    }
    json all = json::array();
    for (const auto& i : *imagery) all.push_back(imagery_to_json(i));
    document["imagery"] = std::move(all);
  } else {
    document["imagery"] = same_name(document);
    add_raster_dem(document);
  }
  return {};
}

}  // namespace tinstream::server
