// families.hpp — the route families' handlers and what they share. Private to the server.
//
// handle() (handler.cpp) parses the target into a typed Route (routes.hpp) and calls the `serve`
// overload of its alternative; each family keeps its handlers in its own file:
//
//   family_service.cpp   /healthz, /metrics, OPTIONS (CORS preflight)
//   family_layers.cpp    /layers, /layers/{layer}
//   family_tiles.cpp     /tiles/{layer}/{quadkey}                     native tiles
//   family_terrain.cpp   /tiles/{layer}/layer.json, …/{z}/{x}/{y}.terrain   Cesium terrain
//   family_admin.cpp     /admin/…                                     ingest jobs, layer removal
//   family_imagery.cpp   /imagery/…, /tiles/{layer}/{z}/{x}/{y}.png   imagery, raster-DEM tiles
//   family_web.cpp       /, /maplibre, /web/…                         the browser viewers
//
// Adding a family: routes.hpp, "Route families". Every serve() runs on an io thread, concurrently
// with the others (see handler.hpp for what Context guarantees).
#pragma once

#include <filesystem>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "tinstream/server/handler.hpp"
#include "tinstream/server/routes.hpp"

namespace tinstream::server {

// --- What the families share (handler.cpp) ---------------------------------------------------

// HTTP status of an error code: invalid_argument 400, not_found 404, unsupported 409,
// cancelled/io_error 503, corrupt_data/internal 500.
int http_status(ErrorCode code);
Response error_response(const Error& e);
// The calling io thread's store.
Result<store::TileStore*> get_store(Context& ctx);
// The layer row, through the layer cache when there is one (the store is opened only on a miss).
Result<std::shared_ptr<const store::LayerInfo>> layer_info(Context& ctx, const std::string& name);
// `public, max-age=…` of tiles.
std::string cache_control(const ServerConfig& config);
// Removes a file, ignoring errors; nothing for an empty path.
void remove_quietly(const std::filesystem::path& path);

// --- The handlers, one overload per route ------------------------------------------------------

// family_service.cpp
Response serve(const Request& request, Context& ctx, const HealthRoute& route);
Response serve(const Request& request, Context& ctx, const MetricsRoute& route);
Response serve(const Request& request, Context& ctx, const PreflightRoute& route);
// family_layers.cpp
Response serve(const Request& request, Context& ctx, const LayersRoute& route);
Response serve(const Request& request, Context& ctx, const LayerRoute& route);
// family_tiles.cpp
Response serve(const Request& request, Context& ctx, const NativeTileRoute& route);
// family_terrain.cpp
Response serve(const Request& request, Context& ctx, const LayerJsonRoute& route);
Response serve(const Request& request, Context& ctx, const TerrainRoute& route);
// family_admin.cpp
Response serve(const Request& request, Context& ctx, const IngestRoute& route);
Response serve(const Request& request, Context& ctx, const JobsRoute& route);
Response serve(const Request& request, Context& ctx, const JobRoute& route);
Response serve(const Request& request, Context& ctx, const DeleteLayerRoute& route);
// family_imagery.cpp
Response serve(const Request& request, Context& ctx, const DemTileRoute& route);
Response serve(const Request& request, Context& ctx, const ImageryTileRoute& route);
// The imagery layers and the raster-DEM URLs added to a /layers or /layers/{layer} document
// (family_layers.cpp calls it): `document` is {"layers": [...]} or one layer object.
Status add_imagery_metadata(Context& ctx, nlohmann::json& document);
// family_web.cpp
Response serve(const Request& request, Context& ctx, const WebPageRoute& route);
Response serve(const Request& request, Context& ctx, const WebAssetRoute& route);

}  // namespace tinstream::server
