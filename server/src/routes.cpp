#include "tinstream/server/routes.hpp"

#include <charconv>
#include <optional>
#include <vector>

namespace tinstream::server {
namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Decimal number of at most 10 digits, nothing else.
std::optional<std::int64_t> parse_number(std::string_view s) {
  if (s.empty() || s.size() > 10) return std::nullopt;
  std::int64_t v = 0;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

RouteError error(int status, std::string message, std::string route = "other") {
  return RouteError{status, std::move(message), {}, std::move(route)};
}

RouteError wrong_method(std::string allow, std::string route) {
  return RouteError{405, "method not allowed; allowed: " + allow, allow, std::move(route)};
}

bool is_read(std::string_view m) { return m == "GET" || m == "HEAD"; }

}  // namespace

std::optional<std::string> percent_decode(std::string_view in, bool plus_is_space) {
  // Most segments (every one of a tile request) have nothing to decode: copied whole.
  bool plain = true;
  for (const char c : in) {
    if (c == '%' || c == '\0' || (c == '+' && plus_is_space)) {
      plain = false;
      break;
    }
  }
  if (plain) return std::string(in);
  std::string out;
  out.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    char c = in[i];
    if (c == '%') {
      if (i + 2 >= in.size()) return std::nullopt;
      const int hi = hex_value(in[i + 1]), lo = hex_value(in[i + 2]);
      if (hi < 0 || lo < 0) return std::nullopt;
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
    } else if (c == '+' && plus_is_space) {
      c = ' ';
    }
    if (c == '\0') return std::nullopt;
    out.push_back(c);
  }
  return out;
}

bool is_valid_layer_name(std::string_view name) {
  if (name.empty() || name.size() > 64 || name.front() == '.') return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '.' || c == '-';
    if (!ok) return false;
  }
  return true;
}

std::string_view route_name(const Route& route) {
  struct Namer {
    std::string_view operator()(const HealthRoute&) const { return "healthz"; }
    std::string_view operator()(const MetricsRoute&) const { return "metrics"; }
    std::string_view operator()(const LayersRoute&) const { return "layers"; }
    std::string_view operator()(const LayerRoute&) const { return "layer"; }
    std::string_view operator()(const LayerJsonRoute&) const { return "layer_json"; }
    std::string_view operator()(const TerrainRoute&) const { return "terrain"; }
    std::string_view operator()(const NativeTileRoute&) const { return "tile"; }
    std::string_view operator()(const IngestRoute&) const { return "ingest"; }
    std::string_view operator()(const JobsRoute&) const { return "jobs"; }
    std::string_view operator()(const JobRoute&) const { return "job"; }
    std::string_view operator()(const DeleteLayerRoute&) const { return "delete_layer"; }
    std::string_view operator()(const PreflightRoute&) const { return "preflight"; }
  };
  return std::visit(Namer{}, route);
}

RouteResult parse_route(std::string_view method, std::string_view target) {
  if (target.empty() || target.front() != '/') {
    return error(400, "request target must be an absolute path");
  }
  std::string_view path = target;
  std::string_view query;
  if (auto q = target.find('?'); q != std::string_view::npos) {
    path = target.substr(0, q);
    query = target.substr(q + 1);
  }
  if (auto h = path.find('#'); h != std::string_view::npos) path = path.substr(0, h);

  // Split and decode segments.
  std::vector<std::string> seg;
  seg.reserve(8);  // one allocation for any route's segments
  std::string_view rest = path.substr(1);
  while (true) {
    const auto slash = rest.find('/');
    auto decoded = percent_decode(rest.substr(0, slash));
    if (!decoded) return error(400, "malformed percent-encoding in path");
    seg.push_back(std::move(*decoded));
    if (slash == std::string_view::npos) break;
    rest = rest.substr(slash + 1);
  }
  for (const auto& s : seg) {
    if (s.find('/') != std::string::npos || s.find('\\') != std::string::npos) {
      return error(400, "path segment contains a slash");
    }
  }

  if (method == "OPTIONS") return Route{PreflightRoute{}};

  auto layer_error = [](const std::string& name, std::string route) {
    return error(400,
                 "invalid layer name \"" + name.substr(0, 80) +
                     "\": use 1-64 characters from [A-Za-z0-9_.-], not starting with '.'",
                 std::move(route));
  };

  const std::size_t n = seg.size();
  if (n == 1 && seg[0] == "healthz") {
    if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", "healthz");
    return Route{HealthRoute{}};
  }
  if (n == 1 && seg[0] == "metrics") {
    if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", "metrics");
    return Route{MetricsRoute{}};
  }
  if (seg[0] == "layers" && n <= 2) {
    if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", n == 1 ? "layers" : "layer");
    if (n == 1) return Route{LayersRoute{}};
    if (!is_valid_layer_name(seg[1])) return layer_error(seg[1], "layer");
    return Route{LayerRoute{seg[1]}};
  }
  if (seg[0] == "tiles" && (n == 3 || n == 5)) {
    const char* name = n == 5 ? "terrain" : (seg[2] == "layer.json" ? "layer_json" : "tile");
    if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", name);
    if (!is_valid_layer_name(seg[1])) return layer_error(seg[1], name);
    if (n == 3) {
      if (seg[2] == "layer.json") return Route{LayerJsonRoute{seg[1]}};
      auto id = geo::TileId::from_quadkey(seg[2]);
      if (!id) return error(400, id.error().message, "tile");
      return Route{NativeTileRoute{seg[1], *id}};
    }
    constexpr std::string_view kExt = ".terrain";
    std::string_view ys = seg[4];
    if (ys.size() <= kExt.size() || ys.substr(ys.size() - kExt.size()) != kExt) {
      return error(404, "no such resource; terrain tiles are /tiles/{layer}/{z}/{x}/{y}.terrain",
                   "terrain");
    }
    ys.remove_suffix(kExt.size());
    const auto z = parse_number(seg[2]), x = parse_number(seg[3]), y = parse_number(ys);
    if (!z || !x || !y)
      return error(400, "terrain tile: z, x and y must be decimal numbers", "terrain");
    auto id = geo::TileId::from_tms(*z, *x, *y);
    if (!id) return error(400, id.error().message, "terrain");
    return Route{TerrainRoute{seg[1], *id}};
  }
  if (seg[0] == "admin") {
    if (n == 2 && seg[1] == "ingest") {
      if (method != "POST") return wrong_method("POST, OPTIONS", "ingest");
      IngestRoute r;
      while (!query.empty()) {
        const auto amp = query.find('&');
        std::string_view kv = query.substr(0, amp);
        const auto eq = kv.find('=');
        auto k = percent_decode(kv.substr(0, eq), true);
        auto v = percent_decode(
            eq == std::string_view::npos ? std::string_view{} : kv.substr(eq + 1), true);
        if (!k || !v) return error(400, "malformed percent-encoding in query", "ingest");
        if (!k->empty()) r.query[*k] = *v;
        if (amp == std::string_view::npos) break;
        query = query.substr(amp + 1);
      }
      return Route{std::move(r)};
    }
    if (n >= 2 && n <= 3 && seg[1] == "jobs") {
      if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", n == 2 ? "jobs" : "job");
      if (n == 2) return Route{JobsRoute{}};
      if (!parse_number(seg[2])) return error(400, "job ids are decimal numbers", "job");
      return Route{JobRoute{seg[2]}};
    }
    if (n == 3 && seg[1] == "layers") {
      if (method != "DELETE") return wrong_method("DELETE, OPTIONS", "delete_layer");
      if (!is_valid_layer_name(seg[2])) return layer_error(seg[2], "delete_layer");
      return Route{DeleteLayerRoute{seg[2]}};
    }
  }
  return error(404, "no such resource");
}

}  // namespace tinstream::server
