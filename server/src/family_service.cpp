// Route family "service": health, metrics and the CORS preflight.
#include <nlohmann/json.hpp>

#include "families.hpp"

namespace tinstream::server {

using nlohmann::json;

Response serve(const Request&, Context& ctx, const HealthRoute&) {
  auto st = get_store(ctx);
  if (!st) return json_error(503, "store unavailable: " + st.error().message);
  auto layers = (*st)->layers();
  if (!layers) return json_error(503, "store unavailable: " + layers.error().message);
  return json_response(200, json{{"status", "ok"}, {"layers", layers->size()}}.dump());
}

Response serve(const Request&, Context& ctx, const MetricsRoute&) {
  Response res;
  res.set("Content-Type", "text/plain; version=0.0.4");
  res.body = ctx.metrics ? ctx.metrics->render(ctx.jobs ? ctx.jobs->counts() : JobCounts{}) : "";
  return res;
}

// CORS preflight: public routes are readable from any origin (cors_allow_origin), the admin API
// and the metrics from none (their preflight carries no CORS header, so a browser refuses the
// cross-origin call).
Response serve(const Request&, Context&, const PreflightRoute& r) {
  Response res;
  res.status = 204;
  if (r.admin) return res;
  res.set("Access-Control-Allow-Methods", "GET, HEAD, OPTIONS");
  res.set("Access-Control-Allow-Headers", "If-None-Match, Accept, Accept-Encoding");
  res.set("Access-Control-Max-Age", "86400");
  return res;
}

}  // namespace tinstream::server
