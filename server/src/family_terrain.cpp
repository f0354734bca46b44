// Route family "tiles", Cesium part: /tiles/{layer}/layer.json and
// /tiles/{layer}/{z}/{x}/{y}.terrain (quantized-mesh-1.0, gzip, cached in the TerrainCache).
#include <algorithm>
#include <variant>

#include "families.hpp"
#include "negotiation.hpp"
#include "stored_tiles.hpp"
#include "tinstream/store/etag.hpp"
#include "tinstream/terrain/gzip.hpp"
#include "tinstream/terrain/layer_json.hpp"
#include "tinstream/terrain/quantized_mesh.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::server {
namespace {

// Terrain only for spherical layers; a JSON 409 explains why otherwise.
std::optional<Response> refuse_ellipsoidal(const store::LayerInfo& info) {
  if (info.projection == geo::Projection::spherical) return std::nullopt;
  return json_error(409, "layer \"" + info.name +
                             "\" uses ellipsoidal Mercator; Cesium quantized-mesh tiles exist only "
                             "for spherical-Mercator (EPSG:3857) layers — use /tiles/" +
                             info.name + "/{quadkey}");
}

// Sends cached gzip bytes as they are (no copy) when the client takes gzip, else inflated.
void send_maybe_gzip(const Request& req, Response& res,
                     const std::shared_ptr<const CachedBody>& body) {
  if (accept_quality(req.accept_encoding, "gzip") > 0) {
    res.set("Content-Encoding", "gzip");
    res.shared_body = std::shared_ptr<const std::string>(body, &body->bytes);
    return;
  }
  const std::string& gz = body->bytes;
  auto raw = terrain::gzip_decompress(
      std::span(reinterpret_cast<const std::uint8_t*>(gz.data()), gz.size()));
  if (!raw) {
    res = json_error(500, raw.error().message);
    return;
  }
  res.body.assign(raw->begin(), raw->end());
}

// The headers of a terrain answer that do not depend on the request; `with_body` adds those of
// a 200 with gzip bytes.
void set_terrain_headers(Response& res, const ServerConfig& config, const std::string& etag,
                         bool normals, bool with_body) {
  res.set("Cache-Control", cache_control(config));
  res.set("Vary", "Accept, Accept-Encoding");
  res.set("ETag", etag);
  if (!with_body) return;
  res.set("Content-Type", normals ? "application/vnd.quantized-mesh;extensions=octvertexnormals"
                                  : "application/vnd.quantized-mesh");
}

// The 304 of a terrain request whose If-None-Match names `etag`, if it does.
std::optional<Response> terrain_not_modified(const Request& req, const ServerConfig& config,
                                             const std::string& etag, bool normals) {
  if (!etag_matches(req.if_none_match, etag)) return std::nullopt;
  Response res;
  set_terrain_headers(res, config, etag, normals, false);
  res.status = 304;
  return res;
}

// Cache key of an encoded terrain tile: layer version, tile and extensions; written into `key`
// (a buffer the caller reuses: no allocation per request).
void terrain_key(std::string& key, const TerrainRoute& r, std::int64_t version, bool normals) {
  key.clear();
  key.append("qm|").append(r.layer).append("|").append(std::to_string(version)).append("|");
  key.append(r.id.quadkey()).append(normals ? "|n" : "|");
}

// A stored tile's blob, inflated and decoded.
Result<tile::TinTile> decode_stored(const store::StoredTile& blob, const geo::TileId& id) {
  auto raw = inflate_blob(blob, id);
  if (!raw) return raw.error();
  auto decoded = tile::decode(*raw);
  if (!decoded)
    return Error(ErrorCode::internal, "tile " + id.to_string() + ": " + decoded.error().message);
  return std::move(*decoded);
}

// Encodes one terrain tile (stored, or a filler tile: terrain::synthetic_tiles) as gzip
// quantized-mesh; or the answer that replaces it (404, 304 on a matching If-None-Match, errors).
std::variant<std::shared_ptr<const CachedBody>, Response> encode_terrain(
    const Request& req, Context& ctx, const TerrainRoute& r, const store::LayerInfo& info,
    bool normals) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto stored = (*st)->tile(r.layer, r.id);
  if (!stored) return error_response(stored.error());
  // Filler tiles (what layer.json lists, terrain::synthetic_tiles, by the same rule): every tile
  // of levels 0 and 1, and the tiles above the coarsest stored level over the layer's data, so
  // their number is bounded by the layer's extent.
  const bool synthetic = !stored->has_value();
  if (synthetic && !terrain::may_be_filler(r.id, info.min_level, info.mercator_bounds)) {
    return json_error(404, "no terrain tile " + r.id.to_string() + " (TMS row " +
                               std::to_string(r.id.tms_row()) + ") in layer \"" + r.layer + "\"");
  }
  std::string base_tag = synthetic ? "flat-" + r.id.quadkey() + "-" + std::to_string(info.version)
                                   : safe_etag(**stored);
  base_tag.erase(std::remove(base_tag.begin(), base_tag.end(), '"'), base_tag.end());
  const std::string etag = "\"qm2-" + base_tag + (normals ? "-n" : "") + "\"";
  const std::string sent_etag =
      representation_etag(etag, accept_quality(req.accept_encoding, "gzip") > 0 ? "" : "id");
  if (auto not_modified = terrain_not_modified(req, ctx.config, sent_etag, normals)) {
    return std::move(*not_modified);
  }
  // A filler tile is joined to the stored neighbours of its level (levels 0 and 1 can hold
  // stored tiles too).
  const Result<tile::TinTile> tin =
      synthetic ? terrain::filler_tile(
                      r.id, info.min_level,
                      [&](const geo::TileId& id) -> Result<std::optional<tile::TinTile>> {
                        auto blob = (*st)->tile(r.layer, id);
                        if (!blob) return blob.error();
                        if (!blob->has_value()) return std::optional<tile::TinTile>();
                        auto t = decode_stored(**blob, id);
                        if (!t) return t.error();
                        return std::optional<tile::TinTile>(std::move(*t));
                      })
                : decode_stored(**stored, r.id);
  if (!tin) return error_response(tin.error());
  auto qm = terrain::encode_quantized_mesh(*tin, info.projection, {normals});
  if (!qm) return error_response(qm.error());
  auto bytes = terrain::gzip_compress(*qm);
  Response head;
  set_terrain_headers(head, ctx.config, etag, normals, true);
  head.set("Content-Encoding", "gzip");
  add_cors(head, ctx.config);
  return std::make_shared<const CachedBody>(
      CachedBody{etag, std::string(bytes.begin(), bytes.end()),
                 std::make_shared<const HeaderBlock>(std::move(head.headers), bytes.size())});
}

}  // namespace

// layer.json's ETag is derived from its bytes (like a stored tile's), not from the layer's
// version alone: a store rebuilt from scratch starts its versions again at 1, and a client (or a
// CDN in front of several servers) revalidating an old copy must not get a 304 for a different
// tile set. Answered from the cached body, so a 304 costs no store read once cached.
Response serve(const Request& req, Context& ctx, const LayerJsonRoute& r) {
  auto found = layer_info(ctx, r.layer);
  if (!found) return error_response(found.error());
  const store::LayerInfo* info = found->get();
  if (auto refusal = refuse_ellipsoidal(*info)) return *refusal;
  if (Status row = check_layer_row(*info); !row) return error_response(row.error());
  const std::string key = "layer.json|" + r.layer + "|" + std::to_string(info->version);
  std::shared_ptr<const CachedBody> body =
      ctx.terrain_cache ? ctx.terrain_cache->get(key) : nullptr;
  if (!body) {
    auto st = get_store(ctx);
    if (!st) return error_response(st.error());
    auto ids = (*st)->tile_ids(r.layer);
    if (!ids) return error_response(ids.error());
    terrain::LayerJsonInput in;
    in.name = info->name;
    in.attribution = info->attribution;
    in.description = "tinstream layer " + info->name;
    in.version = std::to_string(info->version);
    in.bounds = info->bounds;
    in.min_level = info->min_level;
    in.max_level = info->max_level;
    in.tile_ids = std::move(*ids);
    const std::string text = terrain::layer_json(in);
    const std::span<const std::uint8_t> raw(reinterpret_cast<const std::uint8_t*>(text.data()),
                                            text.size());
    std::string etag = store::make_etag(raw);  // "\"<hash>-<length>\""
    etag.insert(1, "lj-");
    auto bytes = terrain::gzip_compress(raw);
    body = std::make_shared<const CachedBody>(
        CachedBody{std::move(etag), std::string(bytes.begin(), bytes.end()), nullptr});
    if (ctx.terrain_cache) ctx.terrain_cache->put(key, body);
  }
  const std::string sent_etag =
      representation_etag(body->etag, accept_quality(req.accept_encoding, "gzip") > 0 ? "" : "id");
  Response res;
  res.set("ETag", sent_etag);
  res.set("Cache-Control", "no-cache");
  res.set("Vary", "Accept-Encoding");
  if (etag_matches(req.if_none_match, sent_etag)) {
    res.status = 304;
    return res;
  }
  res.set("Content-Type", "application/json");
  send_maybe_gzip(req, res, body);
  return res;
}

Response serve(const Request& req, Context& ctx, const TerrainRoute& r) {
  auto found = layer_info(ctx, r.layer);
  if (!found) return error_response(found.error());
  const store::LayerInfo& info = **found;
  if (auto refusal = refuse_ellipsoidal(info)) return *refusal;
  if (Status row = check_layer_row(info); !row) return error_response(row.error());
  const bool normals = accept_wants_extension(req.accept, "octvertexnormals");
  thread_local std::string key;  // handle_terrain never runs nested on one thread
  terrain_key(key, r, info.version, normals);

  // Hot path: a cached encoding of this layer version needs no store access at all, and its 200
  // carries headers formatted once.
  std::shared_ptr<const CachedBody> body =
      ctx.terrain_cache ? ctx.terrain_cache->get(key) : nullptr;
  if (!body) {
    auto encoded = encode_terrain(req, ctx, r, info, normals);
    if (auto* answer = std::get_if<Response>(&encoded)) return std::move(*answer);
    body = std::move(std::get<std::shared_ptr<const CachedBody>>(encoded));
    if (ctx.terrain_cache) ctx.terrain_cache->put(key, body);
  }
  Response res;
  if (accept_quality(req.accept_encoding, "gzip") > 0) {
    if (auto not_modified = terrain_not_modified(req, ctx.config, body->etag, normals)) {
      return std::move(*not_modified);
    }
    res.prebuilt = body->head;
    res.shared_body = std::shared_ptr<const std::string>(body, &body->bytes);
    return res;
  }
  // The client takes no gzip: the inflated body is another representation with its own tag,
  // cached beside the gzip one (inflated once, not on every request).
  const std::string etag = representation_etag(body->etag, "id");
  if (auto not_modified = terrain_not_modified(req, ctx.config, etag, normals)) {
    return std::move(*not_modified);
  }
  key.append("|id");
  std::shared_ptr<const CachedBody> inflated =
      ctx.terrain_cache ? ctx.terrain_cache->get(key) : nullptr;
  if (!inflated) {
    const std::string& gz = body->bytes;
    auto raw = terrain::gzip_decompress(
        std::span(reinterpret_cast<const std::uint8_t*>(gz.data()), gz.size()), kMaxTileBytes);
    if (!raw) return json_error(500, "tile " + r.id.to_string() + ": " + raw.error().message);
    Response head;
    set_terrain_headers(head, ctx.config, etag, normals, true);
    add_cors(head, ctx.config);
    inflated = std::make_shared<const CachedBody>(
        CachedBody{etag, std::string(raw->begin(), raw->end()),
                   std::make_shared<const HeaderBlock>(std::move(head.headers), raw->size())});
    if (ctx.terrain_cache) ctx.terrain_cache->put(key, inflated);
  }
  res.prebuilt = inflated->head;
  res.shared_body = std::shared_ptr<const std::string>(inflated, &inflated->bytes);
  return res;
}

}  // namespace tinstream::server
