// handle(): a request target parsed into a typed route, the route family's handler called for it
// (families.hpp), CORS added. And what the families share.
#include "tinstream/server/handler.hpp"

#include <system_error>
#include <variant>

#include "families.hpp"

namespace tinstream::server {

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

void remove_quietly(const std::filesystem::path& p) {
  if (p.empty()) return;
  std::error_code ec;
  std::filesystem::remove(p, ec);
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
      res = std::visit([&](const auto& r) { return serve(request, context, r); }, route);
    } catch (const std::exception& e) {
      res = json_error(500, std::string("internal error: ") + e.what());
    }
    res.route = std::string(route_name(route));
  }
  add_cors(res, context.config);
  return res;
}

}  // namespace tinstream::server
