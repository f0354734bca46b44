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
//
// Path segments are percent-decoded one by one after splitting on '/', so `%2F` can never create
// a segment and `%2e%2e` decodes to "..", which no layer name, quadkey or number accepts. Layer
// names follow store::validate_layer_name ([A-Za-z0-9_.-]{1,64}, no leading '.').
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <variant>

#include "tinstream/geo/tile_id.hpp"

namespace tinstream::server {

struct HealthRoute {};
struct MetricsRoute {};
struct LayersRoute {};
struct LayerRoute {
  std::string layer;
};
struct LayerJsonRoute {
  std::string layer;
};
struct TerrainRoute {
  std::string layer;
  geo::TileId id;
};
struct NativeTileRoute {
  std::string layer;
  geo::TileId id;
};
struct IngestRoute {
  std::map<std::string, std::string> query;
};
struct JobsRoute {};
struct JobRoute {
  std::string id;
};
struct DeleteLayerRoute {
  std::string layer;
};
struct PreflightRoute {};

using Route = std::variant<HealthRoute, MetricsRoute, LayersRoute, LayerRoute, LayerJsonRoute,
                           TerrainRoute, NativeTileRoute, IngestRoute, JobsRoute, JobRoute,
                           DeleteLayerRoute, PreflightRoute>;

struct RouteError {
  int status = 400;  // 400 malformed, 404 no such path, 405 wrong method
  std::string message;
  std::string allow;  // for 405: the methods the path accepts
  std::string route = "other";
};

using RouteResult = std::variant<Route, RouteError>;

RouteResult parse_route(std::string_view method, std::string_view target);

// Metrics label of a route ("tile", "terrain", …).
std::string_view route_name(const Route& route);

// Percent-decoding of one path segment or query component; nullopt on a malformed escape or a
// decoded NUL. `plus_is_space` for query strings.
std::optional<std::string> percent_decode(std::string_view in, bool plus_is_space = false);

bool is_valid_layer_name(std::string_view name);

}  // namespace tinstream::server
