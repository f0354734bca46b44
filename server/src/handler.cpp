#include "tinstream/server/handler.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstring>
#include <list>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <system_error>
#include <unordered_map>
#include <variant>

#include "tinstream/server/ingest_paths.hpp"
#include "tinstream/server/routes.hpp"
#include "tinstream/store/etag.hpp"
#include "tinstream/terrain/gzip.hpp"
#include "tinstream/terrain/layer_json.hpp"
#include "tinstream/terrain/quantized_mesh.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;

// ASCII case folding, as std::tolower in the "C" locale does, without a library call per byte.
constexpr char ascii_lower(char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c + 32) : c; }

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return ascii_lower(x) == ascii_lower(y);
         });
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// The next `sep`-separated item of `rest`, trimmed; `rest` moves past it. Walks a header list
// without allocating.
std::string_view next_item(std::string_view& rest, char sep) {
  const auto p = rest.find(sep);
  const std::string_view item = trim(rest.substr(0, p));
  rest = p == std::string_view::npos ? std::string_view() : rest.substr(p + 1);
  return item;
}

// Calls fn(item) for every `sep`-separated item of s (trimmed, possibly empty); stops early when
// fn returns true, and returns whether it did.
template <typename Fn>
bool any_item(std::string_view s, char sep, Fn fn) {
  while (true) {
    const bool last = s.find(sep) == std::string_view::npos;
    if (fn(next_item(s, sep))) return true;
    if (last) return false;
  }
}

// Quality of `coding` in an Accept-Encoding header: 0 when not acceptable.
double accept_quality(std::string_view header, std::string_view coding) {
  double star = -1, exact = -1;
  any_item(header, ',', [&](std::string_view item) {
    if (item.empty()) return false;
    const std::string_view name = next_item(item, ';');
    double q = 1.0;
    any_item(item, ';', [&](std::string_view param) {
      if (param.size() > 2 && (param[0] == 'q' || param[0] == 'Q') && param[1] == '=') {
        try {
          q = std::stod(std::string(param.substr(2)));
        } catch (...) {
          q = 0;
        }
      }
      return false;
    });
    if (iequals(name, coding)) exact = q;
    if (name == "*") star = q;
    return false;
  });
  if (exact >= 0) return exact;
  if (star >= 0) return star;
  return 0;
}

// True when the Accept header asks for the quantized-mesh extension `ext`.
bool accept_wants_extension(std::string_view accept, std::string_view ext) {
  return any_item(accept, ',', [&](std::string_view item) {
    const bool has_params = item.find(';') != std::string_view::npos;
    if (!iequals(next_item(item, ';'), "application/vnd.quantized-mesh") || !has_params)
      return false;
    return any_item(item, ';', [&](std::string_view param) {
      if (param.substr(0, 11) != "extensions=") return false;
      std::string_view list = param.substr(11);
      if (!list.empty() && list.front() == '"')
        list = list.substr(1, list.size() >= 2 ? list.size() - 2 : 0);
      return any_item(list, '-', [&](std::string_view e) { return e == ext; });
    });
  });
}

bool etag_matches(std::string_view if_none_match, std::string_view etag) {
  if (if_none_match.empty()) return false;
  return any_item(if_none_match, ',', [&](std::string_view tag) {
    if (tag == "*") return true;
    if (tag.substr(0, 2) == "W/") tag.remove_prefix(2);
    return tag == etag;
  });
}

// The ETag of one encoding of a resource. A strong ETag names one representation (RFC 9110
// §8.8.3), and the gzip, deflate and identity bodies of a tile are different representations:
// the canonical encoding keeps the stored tag, another gets a suffix inside the quotes
// ("abc" -> "abc-gz"), so a cache revalidating its gzip copy never gets a 304 for an identity
// request.
std::string representation_etag(std::string_view etag, std::string_view suffix) {
  std::string tag(etag);
  if (suffix.empty()) return tag;
  const bool quoted = tag.size() >= 2 && tag.back() == '"';
  tag.insert(quoted ? tag.size() - 1 : tag.size(), std::string("-").append(suffix));
  return tag;
}

int http_status(ErrorCode code) {
  switch (code) {
    case ErrorCode::invalid_argument:
      return 400;
    case ErrorCode::not_found:
      return 404;
    case ErrorCode::unsupported:
      return 409;
    case ErrorCode::cancelled:
    case ErrorCode::io_error:
      return 503;
    case ErrorCode::corrupt_data:
    case ErrorCode::internal:
      return 500;
  }
  return 500;
}

Response error_response(const Error& e) { return json_error(http_status(e.code), e.message); }

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

std::string cache_control(const ServerConfig& c) {
  return "public, max-age=" + std::to_string(c.cache_max_age_s);
}

Result<store::TileStore*> get_store(Context& ctx) {
  if (!ctx.store) return Error(ErrorCode::internal, "no store configured");
  return ctx.store();
}

// The layer row, through the layer cache when there is one (the store is opened only on a miss).
Result<std::shared_ptr<const store::LayerInfo>> layer_info(Context& ctx, const std::string& name) {
  std::uint64_t generation = 0;
  if (ctx.layer_cache) {
    if (auto hit = ctx.layer_cache->get(name)) return hit;
    generation = ctx.layer_cache->generation();  // before the read: see LayerCache
  }
  auto st = get_store(ctx);
  if (!st) return st.error();
  auto info = (*st)->layer(name);
  if (!info) return info.error();
  if (ctx.layer_cache) ctx.layer_cache->put(*info, generation);
  return std::make_shared<const store::LayerInfo>(std::move(*info));
}

// Terrain only for spherical layers; a JSON 409 explains why otherwise.
std::optional<Response> refuse_ellipsoidal(const store::LayerInfo& info) {
  if (info.projection == geo::Projection::spherical) return std::nullopt;
  return json_error(409, "layer \"" + info.name +
                             "\" uses ellipsoidal Mercator; Cesium quantized-mesh tiles exist only "
                             "for spherical-Mercator (EPSG:3857) layers — use /tiles/" +
                             info.name + "/{quadkey}");
}

Response handle_native_tile(const Request& req, Context& ctx, const NativeTileRoute& r) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto t = (*st)->tile(r.layer, r.id);
  if (!t) return error_response(t.error());
  if (!t->has_value()) {
    return json_error(404, "no tile " + r.id.quadkey() + " (" + r.id.to_string() + ") in layer \"" +
                               r.layer + "\"");
  }
  const store::StoredTile& tile = **t;
  const double q_deflate = accept_quality(req.accept_encoding, "deflate");
  const double q_gzip = accept_quality(req.accept_encoding, "gzip");
  const bool deflate = q_deflate > 0 && q_deflate >= q_gzip;
  const std::string etag = representation_etag(tile.etag, deflate ? "" : q_gzip > 0 ? "gz" : "id");
  Response res;
  res.set("ETag", etag);
  res.set("Cache-Control", cache_control(ctx.config));
  res.set("Vary", "Accept-Encoding");
  if (etag_matches(req.if_none_match, etag)) {
    res.status = 304;
    return res;
  }
  res.set("Content-Type", "application/vnd.tinstream.tile");
  if (deflate) {
    res.set("Content-Encoding", "deflate");
    res.body.assign(tile.compressed.begin(), tile.compressed.end());
  } else if (q_gzip > 0) {
    auto gz = terrain::zlib_to_gzip(tile.compressed);
    if (!gz) return json_error(500, "tile " + r.id.quadkey() + ": " + gz.error().message);
    res.set("Content-Encoding", "gzip");
    res.body.assign(gz->begin(), gz->end());
  } else {
    auto raw = tile::decompress(tile.compressed);
    if (!raw) return json_error(500, "tile " + r.id.quadkey() + ": " + raw.error().message);
    res.body.assign(raw->begin(), raw->end());
  }
  return res;
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

// layer.json's ETag is derived from its bytes (like a stored tile's), not from the layer's
// version alone: a store rebuilt from scratch starts its versions again at 1, and a client (or a
// CDN in front of several servers) revalidating an old copy must not get a 304 for a different
// tile set. Answered from the cached body, so a 304 costs no store read once cached.
Response handle_layer_json(const Request& req, Context& ctx, const LayerJsonRoute& r) {
  auto found = layer_info(ctx, r.layer);
  if (!found) return error_response(found.error());
  const store::LayerInfo* info = found->get();
  if (auto refusal = refuse_ellipsoidal(*info)) return *refusal;
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

// Encodes one terrain tile (stored, or a flat ancestor of the coarsest stored level) as gzip
// quantized-mesh; or the answer that replaces it (404, 304 on a matching If-None-Match, errors).
std::variant<std::shared_ptr<const CachedBody>, Response> encode_terrain(
    const Request& req, Context& ctx, const TerrainRoute& r, const store::LayerInfo& info,
    bool normals) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto stored = (*st)->tile(r.layer, r.id);
  if (!stored) return error_response(stored.error());
  const bool synthetic = !stored->has_value();
  if (synthetic && r.id.z >= info.min_level) {
    return json_error(404, "no terrain tile " + r.id.to_string() + " (TMS row " +
                               std::to_string(r.id.tms_row()) + ") in layer \"" + r.layer + "\"");
  }
  std::string base_tag =
      synthetic ? "flat-" + r.id.quadkey() + "-" + std::to_string(info.version) : (**stored).etag;
  base_tag.erase(std::remove(base_tag.begin(), base_tag.end(), '"'), base_tag.end());
  const std::string etag = "\"qm2-" + base_tag + (normals ? "-n" : "") + "\"";
  const std::string sent_etag =
      representation_etag(etag, accept_quality(req.accept_encoding, "gzip") > 0 ? "" : "id");
  if (auto not_modified = terrain_not_modified(req, ctx.config, sent_etag, normals)) {
    return std::move(*not_modified);
  }
  tile::TinTile tin;
  if (synthetic) {
    tin = terrain::flat_tile(r.id);
  } else {
    auto raw = tile::decompress((**stored).compressed);
    if (!raw) return json_error(500, "tile " + r.id.to_string() + ": " + raw.error().message);
    auto decoded = tile::decode(*raw);
    if (!decoded)
      return json_error(500, "tile " + r.id.to_string() + ": " + decoded.error().message);
    tin = std::move(*decoded);
  }
  auto qm = terrain::encode_quantized_mesh(tin, info.projection, {normals});
  if (!qm) return error_response(qm.error());
  auto bytes = terrain::gzip_compress(*qm);
  Response head;
  set_terrain_headers(head, ctx.config, etag, normals, true);
  head.set("Content-Encoding", "gzip");
  add_cors(head, ctx.config);
  return std::make_shared<const CachedBody>(
      CachedBody{etag, std::string(bytes.begin(), bytes.end()),
                 std::make_shared<const HeaderBlock>(std::move(head.headers))});
}

Response handle_terrain(const Request& req, Context& ctx, const TerrainRoute& r) {
  auto found = layer_info(ctx, r.layer);
  if (!found) return error_response(found.error());
  const store::LayerInfo& info = **found;
  if (auto refusal = refuse_ellipsoidal(info)) return *refusal;
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
    res.prebuilt = body->gzip_head;
    res.shared_body = std::shared_ptr<const std::string>(body, &body->bytes);
    return res;
  }
  // The client takes no gzip: the inflated body is another representation with its own tag.
  const std::string etag = representation_etag(body->etag, "id");
  if (auto not_modified = terrain_not_modified(req, ctx.config, etag, normals)) {
    return std::move(*not_modified);
  }
  set_terrain_headers(res, ctx.config, etag, normals, true);
  send_maybe_gzip(req, res, body);
  return res;
}

void remove_quietly(const std::filesystem::path& p) {
  if (p.empty()) return;
  std::error_code ec;
  std::filesystem::remove(p, ec);
}

Response handle_ingest(const Request& req, Context& ctx, const IngestRoute& r) {
  if (auto denied = check_admin(req, ctx)) {
    remove_quietly(req.body_file);
    return *denied;
  }
  if (!ctx.jobs) {
    remove_quietly(req.body_file);
    return json_error(503, "ingest is not available in this server");
  }
  IngestJobSpec spec;
  spec.store_path = ctx.config.store;
  std::vector<std::filesystem::path> delete_after;
  if (is_upload(req)) {
    if (req.body_file.empty()) return json_error(400, "upload body missing");
    auto layer = r.query.find("layer");
    if (layer == r.query.end() || !is_valid_layer_name(layer->second)) {
      remove_quietly(req.body_file);
      return json_error(
          400, "upload: query parameter layer= must name a valid layer ([A-Za-z0-9_.-]{1,64})");
    }
    spec.layer = layer->second;
    std::string name = "upload";
    if (auto f = r.query.find("filename"); f != r.query.end()) {
      auto safe = sanitize_filename(f->second);
      if (!safe) {
        remove_quietly(req.body_file);
        return json_error(400, "upload: filename= " + safe.error().message);
      }
      name = *safe;
    }
    std::filesystem::path final_path = req.body_file;
    final_path += "-" + name;
    std::error_code ec;
    std::filesystem::rename(req.body_file, final_path, ec);
    if (ec) {
      remove_quietly(req.body_file);
      return json_error(500,
                        "upload: cannot rename " + req.body_file.string() + ": " + ec.message());
    }
    spec.sources.push_back(final_path);
    spec.root = final_path.parent_path();
    spec.allow_vrt = false;
    delete_after.push_back(final_path);
    if (auto o = r.query.find("options"); o != r.query.end()) {
      json opts = json::parse(o->second, nullptr, false);
      if (opts.is_discarded() || !opts.is_object()) {
        remove_quietly(final_path);
        return json_error(400, "upload: options= must be a JSON object");
      }
      spec.options = std::move(opts);
    }
  } else {
    json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded() || !body.is_object()) {
      return json_error(400,
                        "ingest: body must be a JSON object {\"layer\": ..., \"sources\": [...]}");
    }
    if (!body.contains("layer") || !body["layer"].is_string() ||
        !is_valid_layer_name(body["layer"].get<std::string>())) {
      return json_error(400, "ingest: \"layer\" must be a valid layer name ([A-Za-z0-9_.-]{1,64})");
    }
    spec.layer = body["layer"].get<std::string>();
    if (!body.contains("sources") || !body["sources"].is_array() || body["sources"].empty()) {
      return json_error(
          400, "ingest: \"sources\" must be a non-empty array of paths under the data root");
    }
    if (ctx.config.data_root.empty()) {
      return json_error(403,
                        "ingest: server-side paths are disabled (no data_root configured); upload "
                        "the file instead");
    }
    spec.root = ctx.config.data_root;
    for (const auto& s : body["sources"]) {
      if (!s.is_string()) return json_error(400, "ingest: every source must be a string");
      auto p = resolve_source(ctx.config.data_root, s.get<std::string>());
      if (!p)
        return json_error(p.error().code == ErrorCode::not_found
                              ? 404
                              : (p.error().code == ErrorCode::invalid_argument ? 400 : 403),
                          p.error().message);
      spec.sources.push_back(*p);
    }
    if (body.contains("options")) {
      if (!body["options"].is_object())
        return json_error(400, "ingest: \"options\" must be an object");
      spec.options = body["options"];
    }
  }
  auto id = ctx.jobs->submit(std::move(spec), std::move(delete_after));
  if (!id) {
    for (const auto& p : delete_after) remove_quietly(p);
    return json_error(503, id.error().message);
  }
  Response res =
      json_response(202, json{{"job", *id}, {"status_url", "/admin/jobs/" + *id}}.dump());
  res.set("Location", "/admin/jobs/" + *id);
  return res;
}

Response handle_delete(const Request& req, Context& ctx, const DeleteLayerRoute& r) {
  if (auto denied = check_admin(req, ctx)) return *denied;
  // A short-lived read-write connection on this io thread: deleting is one transaction.
  auto rw = store::TileStore::open(ctx.config.store, store::TileStore::Mode::read_write);
  if (!rw) return error_response(rw.error());
  Status st = rw->delete_layer(r.layer);
  if (ctx.layer_cache) ctx.layer_cache->clear();
  if (!st) return error_response(st.error());
  return json_response(200, json{{"deleted", r.layer}}.dump());
}

Response dispatch(const Request& req, Context& ctx, const Route& route) {
  if (std::holds_alternative<HealthRoute>(route)) {
    auto st = get_store(ctx);
    if (!st) return json_error(503, "store unavailable: " + st.error().message);
    auto layers = (*st)->layers();
    if (!layers) return json_error(503, "store unavailable: " + layers.error().message);
    return json_response(200, json{{"status", "ok"}, {"layers", layers->size()}}.dump());
  }
  if (std::holds_alternative<MetricsRoute>(route)) {
    Response res;
    res.set("Content-Type", "text/plain; version=0.0.4");
    res.body = ctx.metrics ? ctx.metrics->render(ctx.jobs ? ctx.jobs->counts() : JobCounts{}) : "";
    return res;
  }
  if (std::holds_alternative<LayersRoute>(route)) {
    auto st = get_store(ctx);
    if (!st) return error_response(st.error());
    auto layers = (*st)->layers();
    if (!layers) return error_response(layers.error());
    json arr = json::array();
    for (const auto& l : *layers) arr.push_back(layer_to_json(l));
    return json_response(200, json{{"layers", arr}}.dump());
  }
  if (const auto* r = std::get_if<LayerRoute>(&route)) {
    auto st = get_store(ctx);
    if (!st) return error_response(st.error());
    auto info = (*st)->layer(r->layer);
    if (!info) return error_response(info.error());
    return json_response(200, layer_to_json(*info).dump());
  }
  if (const auto* r = std::get_if<NativeTileRoute>(&route)) return handle_native_tile(req, ctx, *r);
  if (const auto* r = std::get_if<LayerJsonRoute>(&route)) return handle_layer_json(req, ctx, *r);
  if (const auto* r = std::get_if<TerrainRoute>(&route)) return handle_terrain(req, ctx, *r);
  if (const auto* r = std::get_if<IngestRoute>(&route)) return handle_ingest(req, ctx, *r);
  if (std::holds_alternative<JobsRoute>(route)) {
    if (auto denied = check_admin(req, ctx)) return *denied;
    json arr = json::array();
    if (ctx.jobs) {
      for (const auto& j : ctx.jobs->list()) arr.push_back(j.to_json());
    }
    return json_response(200, json{{"jobs", arr}}.dump());
  }
  if (const auto* r = std::get_if<JobRoute>(&route)) {
    if (auto denied = check_admin(req, ctx)) return *denied;
    auto job = ctx.jobs ? ctx.jobs->get(r->id) : std::nullopt;
    if (!job) return json_error(404, "no job " + r->id);
    return json_response(200, job->to_json().dump());
  }
  if (const auto* r = std::get_if<DeleteLayerRoute>(&route)) return handle_delete(req, ctx, *r);
  // PreflightRoute
  Response res;
  res.status = 204;
  res.set("Access-Control-Allow-Methods", "GET, HEAD, POST, DELETE, OPTIONS");
  res.set("Access-Control-Allow-Headers",
          "Authorization, Content-Type, If-None-Match, Accept, Accept-Encoding");
  res.set("Access-Control-Max-Age", "86400");
  return res;
}

}  // namespace

HeaderBlock::HeaderBlock(std::vector<std::pair<std::string, std::string>> f)
    : fields(std::move(f)) {
  for (const auto& [k, v] : fields) wire.append(k).append(": ").append(v).append("\r\n");
}

const std::string* Response::header(std::string_view name) const {
  for (const auto& [k, v] : headers) {
    if (iequals(k, name)) return &v;
  }
  if (prebuilt) {
    for (const auto& [k, v] : prebuilt->fields) {
      if (iequals(k, name)) return &v;
    }
  }
  return nullptr;
}

void Response::set(std::string name, std::string value) {
  for (auto& [k, v] : headers) {
    if (iequals(k, name)) {
      v = std::move(value);
      return;
    }
  }
  headers.emplace_back(std::move(name), std::move(value));
}

Response json_response(int status, std::string body) {
  Response r;
  r.status = status;
  r.body = std::move(body);
  r.set("Content-Type", "application/json");
  return r;
}

Response json_error(int status, std::string_view message) {
  return json_response(status, json{{"error", message}, {"status", status}}.dump());
}

std::optional<Response> check_admin(const Request& request, const Context& context) {
  if (context.admin_token.empty()) {
    return json_error(403, "admin API disabled: no admin token configured");
  }
  std::string_view auth = trim(request.authorization);
  if (auth.size() < 7 || !iequals(auth.substr(0, 7), "Bearer ")) {
    Response r =
        json_error(401, "admin API: bearer token required (Authorization: Bearer <token>)");
    r.set("WWW-Authenticate", "Bearer realm=\"tinstream-admin\"");
    return r;
  }
  const std::string_view given = trim(auth.substr(7));
  const std::string& want = context.admin_token;
  // Constant time in the token's content: always walk the longer of the two.
  const std::size_t n = std::max(given.size(), want.size());
  unsigned diff = given.size() == want.size() ? 0u : 1u;
  for (std::size_t i = 0; i < n; ++i) {
    const auto a = static_cast<unsigned char>(i < given.size() ? given[i] : 0);
    const auto b = static_cast<unsigned char>(i < want.size() ? want[i] : 0);
    diff |= static_cast<unsigned>(a ^ b);
  }
  if (diff != 0) return json_error(403, "admin API: wrong token");
  return std::nullopt;
}

bool is_upload(const Request& r) {
  if (r.method != "POST") return false;
  std::string_view path = r.target;
  path = path.substr(0, path.find('?'));
  if (path != "/admin/ingest") return false;
  std::string_view ct = trim(r.content_type);
  ct = ct.substr(0, ct.find(';'));
  return !iequals(trim(ct), "application/json");
}

void add_cors(Response& response, const ServerConfig& config) {
  // A prebuilt header block was made with add_cors already (see Response::prebuilt).
  if (config.cors_allow_origin.empty() || response.prebuilt) return;
  response.set("Access-Control-Allow-Origin", config.cors_allow_origin);
  response.set("Access-Control-Expose-Headers", "ETag, Content-Encoding, Content-Length, Location");
}

Response handle(const Request& request, Context& context) {
  RouteResult parsed = parse_route(request.method, request.target);
  Response res;
  if (const auto* err = std::get_if<RouteError>(&parsed)) {
    remove_quietly(request.body_file);
    res = json_error(err->status, err->message);
    if (!err->allow.empty()) res.set("Allow", err->allow);
    res.route = err->route;
  } else {
    const Route& route = std::get<Route>(parsed);
    if (!std::holds_alternative<IngestRoute>(route)) remove_quietly(request.body_file);
    try {
      res = dispatch(request, context, route);
    } catch (const std::exception& e) {
      res = json_error(500, std::string("internal error: ") + e.what());
    }
    res.route = std::string(route_name(route));
  }
  add_cors(res, context.config);
  return res;
}

// ---------------------------------------------------------------------------------------------

namespace {

// Heap bytes of a string beyond the object itself (short strings live inside it).
std::size_t heap_bytes(const std::string& s) {
  return s.capacity() > std::string().capacity() ? s.capacity() + 1 : 0;
}

}  // namespace

std::size_t HeaderBlock::memory_bytes() const {
  std::size_t n = sizeof(HeaderBlock) + fields.capacity() * sizeof(fields.front()) +
                  heap_bytes(wire) + wire.size() + kKeepAliveExtra + 1;  // + keep_alive_head
  for (const auto& [k, v] : fields) n += heap_bytes(k) + heap_bytes(v);
  return n;
}

struct TerrainCache::Impl {
  struct Entry {
    std::string key;
    std::shared_ptr<const CachedBody> value;
    std::uint64_t cost;
  };
  // One LRU with its share of the budget. The index's keys view the list nodes' keys (list
  // nodes never move).
  struct alignas(64) Partition {
    mutable std::mutex mutex;  // guards everything below
    std::list<Entry> lru;      // front = most recent
    std::unordered_map<std::string_view, std::list<Entry>::iterator> index;
    std::uint64_t bytes = 0;
  };
  // Bookkeeping of one entry besides its strings and header block: the list node, the index
  // node and its bucket, the CachedBody with its shared_ptr control block.
  static constexpr std::uint64_t kEntryOverhead =
      sizeof(Entry) + 2 * sizeof(void*) +
      sizeof(std::pair<const std::string_view, std::list<Entry>::iterator>) + 3 * sizeof(void*) +
      sizeof(CachedBody) + 2 * sizeof(void*);

  explicit Impl(std::uint64_t max)
      : max_bytes(max),
        n_partitions(static_cast<std::size_t>(std::clamp<std::uint64_t>(max >> 24, 1, 16))),
        partition_budget(max / n_partitions),
        parts(std::make_unique<Partition[]>(n_partitions)) {}

  // The partition of a key: a mix of its last bytes (the quadkey's least significant digits;
  // cheaper than the full hash the index computes anyway).
  Partition& partition_of(std::string_view key) const {
    if (n_partitions == 1) return parts[0];
    std::uint64_t tail = 0;
    const std::size_t n = std::min<std::size_t>(key.size(), 8);
    std::memcpy(&tail, key.data() + key.size() - n, n);
    tail *= 0x9E3779B97F4A7C15ull;
    return parts[(tail >> 32) % n_partitions];
  }

  std::uint64_t max_bytes;
  std::size_t n_partitions;
  std::uint64_t partition_budget;
  std::unique_ptr<Partition[]> parts;
};

std::uint64_t TerrainCache::cost(std::string_view key, const CachedBody& value) {
  return Impl::kEntryOverhead + (key.size() + 1) + value.bytes.capacity() + 1 +
         heap_bytes(value.etag) + (value.gzip_head ? value.gzip_head->memory_bytes() : 0);
}

TerrainCache::TerrainCache(std::uint64_t max_bytes) : impl_(std::make_unique<Impl>(max_bytes)) {}
TerrainCache::~TerrainCache() = default;

std::shared_ptr<const CachedBody> TerrainCache::get(std::string_view key) {
  Impl::Partition& p = impl_->partition_of(key);
  std::lock_guard lock(p.mutex);
  auto it = p.index.find(key);
  if (it == p.index.end()) return nullptr;
  if (it->second != p.lru.begin()) p.lru.splice(p.lru.begin(), p.lru, it->second);
  return it->second->value;
}

void TerrainCache::put(std::string_view key, std::shared_ptr<const CachedBody> value) {
  const std::uint64_t size = cost(key, *value);
  if (size > impl_->partition_budget) return;
  Impl::Partition& p = impl_->partition_of(key);
  std::lock_guard lock(p.mutex);
  if (auto it = p.index.find(key); it != p.index.end()) {
    p.bytes -= it->second->cost;
    const auto node = it->second;
    p.index.erase(it);
    p.lru.erase(node);
  }
  p.lru.push_front(Impl::Entry{std::string(key), std::move(value), size});
  p.index.emplace(p.lru.front().key, p.lru.begin());
  p.bytes += size;
  while (p.bytes > impl_->partition_budget) {
    const Impl::Entry& last = p.lru.back();
    p.bytes -= last.cost;
    p.index.erase(last.key);
    p.lru.pop_back();
  }
}

std::uint64_t TerrainCache::bytes() const {
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < impl_->n_partitions; ++i) {
    std::lock_guard lock(impl_->parts[i].mutex);
    total += impl_->parts[i].bytes;
  }
  return total;
}

std::size_t TerrainCache::partitions() const { return impl_->n_partitions; }

struct LayerCache::Impl {
  std::chrono::milliseconds ttl;
  mutable std::mutex mutex;  // guards entries and generation
  std::unordered_map<std::string, std::pair<std::shared_ptr<const store::LayerInfo>,
                                            std::chrono::steady_clock::time_point>>
      entries;
  std::uint64_t generation = 0;
};

LayerCache::LayerCache(std::uint32_t ttl_ms) : impl_(std::make_unique<Impl>()) {
  impl_->ttl = std::chrono::milliseconds(ttl_ms);
}
LayerCache::~LayerCache() = default;

std::shared_ptr<const store::LayerInfo> LayerCache::get(const std::string& name) {
  std::lock_guard lock(impl_->mutex);
  auto it = impl_->entries.find(name);
  if (it == impl_->entries.end()) return nullptr;
  if (std::chrono::steady_clock::now() - it->second.second > impl_->ttl) {
    impl_->entries.erase(it);
    return nullptr;
  }
  return it->second.first;
}

std::uint64_t LayerCache::generation() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->generation;
}

void LayerCache::put(const store::LayerInfo& info, std::uint64_t generation) {
  std::lock_guard lock(impl_->mutex);
  if (generation != impl_->generation) return;  // read before a clear(): maybe stale already
  if (impl_->entries.size() > 10000) impl_->entries.clear();
  impl_->entries[info.name] = {std::make_shared<const store::LayerInfo>(info),
                               std::chrono::steady_clock::now()};
}

void LayerCache::clear() {
  std::lock_guard lock(impl_->mutex);
  ++impl_->generation;
  impl_->entries.clear();
}

}  // namespace tinstream::server
