#include "tinstream/server/routes.hpp"

#include <charconv>
#include <optional>
#include <type_traits>
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

RouteError wrong_method(const std::string& allow, std::string route) {
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
  return std::visit([](const auto& r) { return std::decay_t<decltype(r)>::kName; }, route);
}

bool is_admin_route(const Route& route) {
  return std::visit(
      [](const auto& r) {
        using R = std::decay_t<decltype(r)>;
        if constexpr (std::is_same_v<R, PreflightRoute>) {
          return r.admin;
        } else if constexpr (requires { R::kAdmin; }) {
          return R::kAdmin;
        } else {
          return false;
        }
      },
      route);
}

namespace {

// The decoded path segments of a request target (`/a/b` → {"a", "b"}; `/` → {""}).
using Segments = std::vector<std::string>;

RouteError layer_error(const std::string& name, std::string_view route) {
  return error(400,
               "invalid layer name \"" + name.substr(0, 80) +
                   "\": use 1-64 characters from [A-Za-z0-9_.-], not starting with '.'",
               std::string(route));
}

// Family "service": /healthz, /metrics.
RouteResult parse_service(std::string_view method, const Segments& seg, std::string_view) {
  if (seg.size() != 1) return error(404, "no such resource");
  if (seg[0] == "healthz") {
    if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", "healthz");
    return Route{HealthRoute{}};
  }
  if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", "metrics");
  return Route{MetricsRoute{}};
}

// Family "layers": /layers, /layers/{layer}.
RouteResult parse_layers(std::string_view method, const Segments& seg, std::string_view) {
  const std::size_t n = seg.size();
  if (n > 2) return error(404, "no such resource");
  const std::string_view name = n == 1 ? LayersRoute::kName : LayerRoute::kName;
  if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", std::string(name));
  if (n == 1) return Route{LayersRoute{}};
  if (!is_valid_layer_name(seg[1])) return layer_error(seg[1], name);
  return Route{LayerRoute{seg[1]}};
}

RouteResult parse_dem_tile(const Segments& seg, std::string_view query);

// Family "tiles": /tiles/{layer}/layer.json, /tiles/{layer}/{z}/{x}/{y}.terrain,
// /tiles/{layer}/{quadkey}.
RouteResult parse_tiles(std::string_view method, const Segments& seg, std::string_view query) {
  const std::size_t n = seg.size();
  if (n != 3 && n != 5) return error(404, "no such resource");
  const bool dem = n == 5 && seg[4].size() > 4 && seg[4].substr(seg[4].size() - 4) == ".png";
  const std::string_view name = dem                      ? DemTileRoute::kName
                                : n == 5                 ? TerrainRoute::kName
                                : seg[2] == "layer.json" ? LayerJsonRoute::kName
                                                         : NativeTileRoute::kName;
  if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", std::string(name));
  if (!is_valid_layer_name(seg[1])) return layer_error(seg[1], name);
  if (n == 3) {
    if (seg[2] == "layer.json") return Route{LayerJsonRoute{seg[1]}};
    auto id = geo::TileId::from_quadkey(seg[2]);
    if (!id) return error(400, id.error().message, "tile");
    return Route{NativeTileRoute{seg[1], *id}};
  }
  if (seg[4].size() > 4 && std::string_view(seg[4]).substr(seg[4].size() - 4) == ".png") {
    return parse_dem_tile(seg, query);
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

// The query of POST /admin/ingest: key=value pairs, percent-decoded ('+' is a space); the last
// value of a repeated key counts.
RouteResult parse_ingest_query(std::string_view query) {
  IngestRoute r;
  while (!query.empty()) {
    const auto amp = query.find('&');
    std::string_view kv = query.substr(0, amp);
    const auto eq = kv.find('=');
    auto k = percent_decode(kv.substr(0, eq), true);
    auto v =
        percent_decode(eq == std::string_view::npos ? std::string_view{} : kv.substr(eq + 1), true);
    if (!k || !v) return error(400, "malformed percent-encoding in query", "ingest");
    if (!k->empty()) r.query[*k] = *v;
    if (amp == std::string_view::npos) break;
    query = query.substr(amp + 1);
  }
  return Route{std::move(r)};
}

// Family "admin": /admin/ingest, /admin/jobs[/{id}], /admin/layers/{layer}.
RouteResult parse_admin(std::string_view method, const Segments& seg, std::string_view query) {
  const std::size_t n = seg.size();
  if (n == 2 && seg[1] == "ingest") {
    if (method != "POST") return wrong_method("POST, OPTIONS", "ingest");
    return parse_ingest_query(query);
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
  return error(404, "no such resource");
}

// "{z}", "{x}", "{y}.{ext}" (XYZ rows) → a tile id and the extension, or the error to answer.
std::variant<std::pair<geo::TileId, std::string>, RouteError> parse_xyz(const std::string& zs,
                                                                        const std::string& xs,
                                                                        const std::string& ys_ext,
                                                                        std::string_view route) {
  const auto dot = ys_ext.rfind('.');
  if (dot == std::string::npos) return error(404, "no such resource", std::string(route));
  const auto z = parse_number(zs), x = parse_number(xs),
             y = parse_number(std::string_view(ys_ext).substr(0, dot));
  if (!z || !x || !y) {
    return error(400, std::string(route) + " tile: z, x and y must be decimal numbers",
                 std::string(route));
  }
  auto id = geo::TileId::from_zxy(*z, *x, *y);
  if (!id) return error(400, id.error().message, std::string(route));
  return std::pair{*id, ys_ext.substr(dot + 1)};
}

// The value of `key` in a query string (percent-decoded), or "" when absent.
std::optional<std::string> query_value(std::string_view query, std::string_view key) {
  while (!query.empty()) {
    const auto amp = query.find('&');
    const std::string_view kv = query.substr(0, amp);
    const auto eq = kv.find('=');
    if (kv.substr(0, eq) == key) {
      return percent_decode(eq == std::string_view::npos ? std::string_view{} : kv.substr(eq + 1),
                            true);
    }
    if (amp == std::string_view::npos) break;
    query = query.substr(amp + 1);
  }
  return std::string();
}

// /tiles/{layer}/{z}/{x}/{y}.png?encoding=terrarium|mapbox&nodata=opaque|transparent (method and
// layer already checked).
RouteResult parse_dem_tile(const Segments& seg, std::string_view query) {
  auto parsed = parse_xyz(seg[2], seg[3], seg[4], DemTileRoute::kName);
  if (auto* e = std::get_if<RouteError>(&parsed)) return *e;
  auto encoding = query_value(query, "encoding");
  if (!encoding) return error(400, "malformed percent-encoding in query", "dem");
  if (encoding->empty()) *encoding = "terrarium";
  if (*encoding != "terrarium" && *encoding != "mapbox") {
    return error(400, "encoding must be terrarium or mapbox", "dem");
  }
  auto nodata = query_value(query, "nodata");
  if (!nodata) return error(400, "malformed percent-encoding in query parameter nodata", "dem");
  if (nodata->empty()) *nodata = "opaque";
  if (*nodata != "opaque" && *nodata != "transparent") {
    return error(400, "nodata must be opaque (alpha 255, the default) or transparent (alpha 0)",
                 "dem");
  }
  return Route{DemTileRoute{seg[1], std::get<0>(parsed).first, *encoding, *nodata}};
}

// Family "imagery": /imagery/{layer}/{quadkey}, /imagery/{layer}/{z}/{x}/{y}.{png|jpg|webp}.
RouteResult parse_imagery(std::string_view method, const Segments& seg, std::string_view) {
  const std::size_t n = seg.size();
  if (n != 3 && n != 5) return error(404, "no such resource");
  if (!is_read(method)) return wrong_method("GET, HEAD, OPTIONS", "imagery");
  if (!is_valid_layer_name(seg[1])) return layer_error(seg[1], "imagery");
  if (n == 3) {
    auto id = geo::TileId::from_quadkey(seg[2]);
    if (!id) return error(400, id.error().message, "imagery");
    return Route{ImageryTileRoute{seg[1], *id, {}}};
  }
  auto parsed = parse_xyz(seg[2], seg[3], seg[4], ImageryTileRoute::kName);
  if (auto* e = std::get_if<RouteError>(&parsed)) return *e;
  auto& [id, ext] = std::get<0>(parsed);
  if (ext != "png" && ext != "jpg" && ext != "webp") {
    return error(404, "imagery tiles are /imagery/{layer}/{z}/{x}/{y}.png, .jpg or .webp",
                 "imagery");
  }
  return Route{ImageryTileRoute{seg[1], id, ext}};
}

// Family "web": / and /maplibre (the pages), /web/{path…} (their files).
RouteResult parse_web(std::string_view method, const Segments& seg, std::string_view) {
  const bool page = seg[0] != "web";
  if (page ? seg.size() != 1 : seg.size() < 2) return error(404, "no such resource");
  if (!is_read(method)) {
    return wrong_method("GET, HEAD, OPTIONS", page ? "web_page" : "web_asset");
  }
  if (page) return Route{WebPageRoute{seg[0].empty() ? "index.html" : seg[0] + ".html"}};
  std::string path;
  for (std::size_t i = 1; i < seg.size(); ++i) {
    const std::string& s = seg[i];
    bool ok = !s.empty() && s.front() != '.';
    for (const char c : s) {
      ok = ok && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                  c == '_' || c == '.' || c == '-');
    }
    if (!ok) return error(404, "no such file", "web_asset");
    path += (i == 1 ? "" : "/") + s;
  }
  return Route{WebAssetRoute{std::move(path)}};
}

// The registration table of route families (routes.hpp, "Route families"): the first path
// segment each one owns, and its parser (given the method, every decoded segment — the first
// included — and the raw query).
struct Family {
  std::string_view first_segment;
  RouteResult (*parse)(std::string_view method, const Segments& segments, std::string_view query);
};
constexpr Family kFamilies[] = {
    {"healthz", parse_service},
    {"metrics", parse_service},
    {"layers", parse_layers},
    {"tiles", parse_tiles},
    {"admin", parse_admin},
    {"imagery", parse_imagery},
    {"", parse_web},
    {"maplibre", parse_web},
    {"web", parse_web},
};

}  // namespace

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
  Segments seg;
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

  if (method == "OPTIONS") {
    return Route{PreflightRoute{seg[0] == "admin" || seg[0] == "metrics"}};
  }
  for (const Family& family : kFamilies) {
    if (seg[0] == family.first_segment) return family.parse(method, seg, query);
  }
  return error(404, "no such resource");
}

}  // namespace tinstream::server
