// handle(): a request target parsed into a typed route, the route family's handler called for it
// (families.hpp), CORS added. And what the families share.
#include "tinstream/server/handler.hpp"

#include <algorithm>
#include <optional>
#include <system_error>
#include <variant>

#include "address_ranges.hpp"
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

std::vector<std::pair<std::string, std::string>> server_path_redactions(const ServerConfig& c) {
  namespace fs = std::filesystem;
  std::vector<std::pair<std::string, std::string>> out;
  const auto add = [&](const fs::path& p, const std::string& folder_word, bool folder) {
    if (p.empty()) return;
    std::error_code ec;
    for (const fs::path& v : {p, fs::absolute(p, ec), fs::weakly_canonical(p, ec)}) {
      std::string text = v.string();
      while (text.size() > 1 && text.back() == '/') text.pop_back();
      if (text.size() <= 1) continue;  // never "/" or "."
      if (folder) out.emplace_back(text + "/", "");
      out.emplace_back(text, folder_word);
    }
  };
  add(c.store, "the store", false);
  add(c.store.has_parent_path() ? c.store.parent_path() : fs::path("."), "the store's folder",
      true);
  add(c.data_root, "the data root", true);
  add(c.upload_dir, "the upload directory", true);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return a.first.size() != b.first.size() ? a.first.size() > b.first.size() : a < b;
  });
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void redact_server_paths(std::string& text,
                         const std::vector<std::pair<std::string, std::string>>& redactions) {
  for (const auto& [path, word] : redactions) {
    for (std::size_t at = text.find(path); at != std::string::npos;
         at = text.find(path, at + word.size())) {
      text.replace(at, path.size(), word);
    }
  }
  // Sources opened by descriptor (ingest_paths.hpp) reach the ingest as /proc/self/fd/N/name.
  static constexpr std::string_view kFd = "/proc/self/fd/";
  for (std::size_t at = text.find(kFd); at != std::string::npos; at = text.find(kFd, at)) {
    std::size_t end = at + kFd.size();
    while (end < text.size() && text[end] >= '0' && text[end] <= '9') ++end;
    if (end < text.size() && text[end] == '/') ++end;
    text.erase(at, end - at);
  }
}

namespace {

// Admin routes and metrics: only from admin_allow addresses, only on the admin listener when
// there is one; that listener serves nothing else but /healthz.
std::optional<Response> refuse_by_listener_or_address(const Request& request, const Context& ctx,
                                                      const Route& route, bool admin) {
  if (!ctx.config.admin_address.empty()) {
    const bool health = std::holds_alternative<HealthRoute>(route);
    if (admin != request.admin_listener && !(health && request.admin_listener)) {
      return json_error(404, "no such resource");
    }
  }
  if (!admin || ctx.config.admin_allow.empty()) return std::nullopt;
  for (const auto& text : ctx.config.admin_allow) {
    auto range = AddressRange::parse(text);
    if (range && range->contains(request.remote)) return std::nullopt;
  }
  return json_error(403, "admin API: not allowed from this address (admin_allow)");
}

// What every answer gets last: its metrics label, CORS for public routes, and no server path in
// an error or an admin answer.
void finish(Response& res, const Context& ctx, std::string_view route, bool admin) {
  res.route = std::string(route);
  if (!admin) add_cors(res, ctx.config);
  if ((res.status >= 400 || admin) && !res.body.empty()) {
    if (ctx.path_redactions.empty()) {
      redact_server_paths(res.body, server_path_redactions(ctx.config));
    } else {
      redact_server_paths(res.body, ctx.path_redactions);
    }
  }
}

Response internal_error(const std::exception& e) {
  return json_error(500, std::string("internal error: ") + e.what());
}

}  // namespace

Response handle(const Request& request, Context& context) {
  RouteResult parsed = parse_route(request.method, request.target);
  Response res;
  if (const auto* err = std::get_if<RouteError>(&parsed)) {
    remove_quietly(request.body_file);
    res = json_error(err->status, err->message);
    if (!err->allow.empty()) res.set("Allow", err->allow);
    finish(res, context, err->route, false);
    return res;
  }
  const Route& route = std::get<Route>(parsed);
  if (!std::holds_alternative<IngestRoute>(route)) remove_quietly(request.body_file);
  const bool admin = is_admin_route(route);
  const std::string_view name = route_name(route);
  if (auto refused = refuse_by_listener_or_address(request, context, route, admin)) {
    remove_quietly(request.body_file);
    res = std::move(*refused);
  } else {
    try {
      res = std::visit([&](const auto& r) { return serve(request, context, r); }, route);
    } catch (const std::exception& e) {
      res = internal_error(e);
    }
  }
  finish(res, context, name, admin);
  if (res.deferred) {
    // Runs later on the blocking worker: its answer is finished the same way. Context outlives
    // the server's sessions; `name` is a route's static label.
    res.deferred = [work = std::move(res.deferred), &context, name, admin]() {
      Response out;
      try {
        out = work();
      } catch (const std::exception& e) {
        out = internal_error(e);
      }
      finish(out, context, name, admin);
      return out;
    };
  }
  return res;
}

}  // namespace tinstream::server
