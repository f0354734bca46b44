// tinstream/server/routes.hpp — request target → typed route (pure, no I/O).
//
//   GET|HEAD  /healthz                                 HealthRoute
//   GET|HEAD  /metrics                                 MetricsRoute
//   GET|HEAD  /layers                                  LayersRoute
//   GET|HEAD  /layers/{layer}                          LayerRoute
//   GET|HEAD  /tiles/{layer}/layer.json                LayerJsonRoute
//   GET|HEAD  /tiles/{layer}/{z}/{x}/{y}.terrain       TerrainRoute   (TMS rows)
//   GET|HEAD  /tiles/{layer}/{quadkey}                 NativeTileRoute
//   POST      /admin/ingest                            IngestRoute
//   GET       /admin/jobs, /admin/jobs/{id}            JobsRoute, JobRoute
//   DELETE    /admin/layers/{layer}                    DeleteLayerRoute
//   OPTIONS   any path                                 PreflightRoute (CORS)
//   GET|HEAD  /tiles/{layer}/{z}/{x}/{y}.png?encoding=terrarium|mapbox&nodata=opaque|transparent
//                                                      DemTileRoute   (XYZ rows)
//   GET|HEAD  /imagery/{layer}/{quadkey}               ImageryTileRoute
//   GET|HEAD  /imagery/{layer}/{z}/{x}/{y}.{png|jpg|webp}   ImageryTileRoute (XYZ rows)
//   GET|HEAD  /, /maplibre                             WebPageRoute   (the browser viewers)
//   GET|HEAD  /web/{path…}                             WebAssetRoute  (their static files)
//
// (To add routes, see "Route families" below.)
//
// Path segments are percent-decoded one by one after splitting on '/', so `%2F` can never create
// a segment and `%2e%2e` decodes to "..", which no layer name, quadkey or number accepts. Layer
// names follow store::validate_layer_name ([A-Za-z0-9_.-]{1,64}, no leading '.').
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>

#include "tinstream/geo/tile_id.hpp"

namespace tinstream::server {

// ---------------------------------------------------------------------------------------------
// Route families: the registration point.
//
// A route family owns the paths under one first segment ("tiles", "admin", …). Each of its routes
// is a struct below, named `<What>Route`, with `kName` (its metrics label) and the fields the
// handler needs, already validated. To add a family (say `/imagery/{layer}/{z}/{x}/{y}.png`):
//   1. its route structs here, and each in the `Route` variant below (the metrics labels follow
//      from it: kRouteLabels; `static constexpr bool kAdmin = true` puts a route behind the
//      admin allow-list and listener);
//   2. a `parse_<family>(method, segments, query)` in src/routes.cpp and one line in its
//      kFamilies table naming the first segment it owns ("" is the root path `/`);
//   3. `Response serve(const Request&, Context&, const <What>Route&)` for each struct in a new
//      src/family_<family>.cpp, declared in src/families.hpp, and the file in
//      server/CMakeLists.txt. The dispatch (src/handler.cpp) is a std::visit over `Route`: a
//      route without its `serve` does not compile.
// Nothing else changes: the session, the metrics and the other families stay as they are.
// ---------------------------------------------------------------------------------------------

// Family "service": /healthz, /metrics, and OPTIONS on any path (src/family_service.cpp).
struct HealthRoute {
  static constexpr std::string_view kName = "healthz";
};
struct MetricsRoute {
  static constexpr bool kAdmin = true;  // admin_allow, admin listener, no CORS
  static constexpr std::string_view kName = "metrics";
};
// Family "layers": layer metadata (src/family_layers.cpp).
struct LayersRoute {
  static constexpr std::string_view kName = "layers";
};
struct LayerRoute {
  static constexpr std::string_view kName = "layer";
  std::string layer;
};
// Family "tiles": Cesium terrain (src/family_terrain.cpp) and native tiles (src/family_tiles.cpp).
struct LayerJsonRoute {
  static constexpr std::string_view kName = "layer_json";
  std::string layer;
};
struct TerrainRoute {
  static constexpr std::string_view kName = "terrain";
  std::string layer;
  geo::TileId id;
};
struct NativeTileRoute {
  static constexpr std::string_view kName = "tile";
  std::string layer;
  geo::TileId id;
};
// Family "admin": ingest jobs and layer removal, bearer token (src/family_admin.cpp).
struct IngestRoute {
  static constexpr bool kAdmin = true;  // admin_allow, admin listener, no CORS
  static constexpr std::string_view kName = "ingest";
  std::map<std::string, std::string> query;
};
struct JobsRoute {
  static constexpr bool kAdmin = true;  // admin_allow, admin listener, no CORS
  static constexpr std::string_view kName = "jobs";
};
struct JobRoute {
  static constexpr bool kAdmin = true;  // admin_allow, admin listener, no CORS
  static constexpr std::string_view kName = "job";
  std::string id;
};
struct DeleteLayerRoute {
  static constexpr bool kAdmin = true;  // admin_allow, admin listener, no CORS
  static constexpr std::string_view kName = "delete_layer";
  std::string layer;
};
struct PreflightRoute {
  static constexpr std::string_view kName = "preflight";
  bool admin = false;  // for a path of an admin route (/admin/…, /metrics): no CORS
};
// Family "tiles", raster-DEM part, and family "imagery" (src/family_imagery.cpp).
struct DemTileRoute {
  static constexpr std::string_view kName = "dem";
  std::string layer;
  geo::TileId id;
  std::string encoding;  // "terrarium" (the default) or "mapbox"
  std::string nodata;    // "opaque" (the default) or "transparent"
};
struct ImageryTileRoute {
  static constexpr std::string_view kName = "imagery";
  std::string layer;
  geo::TileId id;
  std::string extension;  // "png", "jpg" or "webp"; empty for the quadkey form
};
// Family "web": the browser viewers and their static files (src/family_web.cpp).
struct WebPageRoute {
  static constexpr std::string_view kName = "web_page";
  std::string page;  // file name under the web root: "index.html", "maplibre.html"
};
struct WebAssetRoute {
  static constexpr std::string_view kName = "web_asset";
  std::string path;  // relative to the web root; segments of [A-Za-z0-9_.-], none starting '.'
};

using Route =
    std::variant<HealthRoute, MetricsRoute, LayersRoute, LayerRoute, LayerJsonRoute, TerrainRoute,
                 NativeTileRoute, IngestRoute, JobsRoute, JobRoute, DeleteLayerRoute,
                 PreflightRoute, DemTileRoute, ImageryTileRoute, WebPageRoute, WebAssetRoute>;

namespace detail {
template <typename V>
struct RouteLabels;
template <typename... R>
struct RouteLabels<std::variant<R...>> {
  static constexpr std::array<std::string_view, sizeof...(R) + 1> value = {R::kName..., "other"};
};
}  // namespace detail

// The metrics label of every route, in the variant's order, then "other" (requests that match
// no route).
inline constexpr auto kRouteLabels = detail::RouteLabels<Route>::value;

struct RouteError {
  int status = 400;  // 400 malformed, 404 no such path, 405 wrong method
  std::string message;
  std::string allow;  // for 405: the methods the path accepts
  std::string route = "other";
};

using RouteResult = std::variant<Route, RouteError>;

RouteResult parse_route(std::string_view method, std::string_view target);

// Metrics label of a route ("tile", "terrain", …): its kName.
std::string_view route_name(const Route& route);

// True for the admin API and the metrics: routes whose struct says `kAdmin = true`, and their
// preflights. They answer only addresses in admin_allow, only on the admin listener when there
// is one, and never carry CORS headers.
bool is_admin_route(const Route& route);

// Percent-decoding of one path segment or query component; nullopt on a malformed escape or a
// decoded NUL. `plus_is_space` for query strings.
std::optional<std::string> percent_decode(std::string_view in, bool plus_is_space = false);

bool is_valid_layer_name(std::string_view name);

}  // namespace tinstream::server
