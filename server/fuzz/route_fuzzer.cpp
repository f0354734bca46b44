// libFuzzer target for the HTTP route parser (the first thing a hostile request reaches).
// Input: "<METHOD>\n<target>". Invariants checked: no crash, no sanitizer report; a parsed route
// that names a layer names a valid one; tile routes carry a valid tile id; errors carry a 4xx
// status and a message.
//   scripts/fuzz.sh (build-fuzz/bin/route_fuzzer server/fuzz/corpus/route -max_total_time=60)
#include <cstdint>
#include <cstdlib>
#include <string_view>
#include <variant>

#include "tinstream/server/routes.hpp"

using namespace tinstream::server;

namespace {

void require(bool ok) {
  if (!ok) std::abort();
}

template <typename T>
void check_layer(const Route& route) {
  if (const auto* r = std::get_if<T>(&route)) require(is_valid_layer_name(r->layer));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const auto newline = input.find('\n');
  const std::string_view method =
      newline == std::string_view::npos ? "GET" : input.substr(0, newline);
  const std::string_view target =
      newline == std::string_view::npos ? input : input.substr(newline + 1);
  const RouteResult result = parse_route(method, target);
  if (const auto* route = std::get_if<Route>(&result)) {
    check_layer<LayerRoute>(*route);
    check_layer<LayerJsonRoute>(*route);
    check_layer<DeleteLayerRoute>(*route);
    if (const auto* t = std::get_if<TerrainRoute>(route))
      require(is_valid_layer_name(t->layer) && t->id.valid());
    if (const auto* t = std::get_if<NativeTileRoute>(route))
      require(is_valid_layer_name(t->layer) && t->id.valid());
    require(!route_name(*route).empty());
  } else {
    const auto& error = std::get<RouteError>(result);
    require(error.status >= 400 && error.status < 500 && !error.message.empty());
  }
  (void)percent_decode(target, true);
  return 0;
}
