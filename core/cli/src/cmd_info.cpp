// `tinstream info --store FILE [--layer NAME] [--tile QUADKEY]`: what a tile store holds, as JSON.
//   no --layer   the published layers, one summary each
//   --layer      one layer's metadata
//   --tile       one tile's statistics: counts, vertex roles, NODATA corners, bounds (Mercator and
//                lon/lat), stored size and ETag, and whether it passes check_structure
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::cli {
namespace {

struct InfoOptions {
  std::string store;
  std::string layer;
  std::string tile;
  bool has_tile = false;  // --tile given (an empty quadkey is the level-0 tile)
};

nlohmann::json layer_summary(const store::LayerInfo& l) {
  return {{"name", l.name},
          {"version", l.version},
          {"projection", std::string(geo::to_string(l.projection))},
          {"min_level", l.min_level},
          {"max_level", l.max_level},
          {"tile_count", l.tile_count},
          {"point_count", l.point_count},
          {"created_unix", l.created_unix}};
}

nlohmann::json layer_details(const store::LayerInfo& l) {
  nlohmann::json j = layer_summary(l);
  j["vertical_datum"] = l.vertical_datum;
  j["bounds"] = {{"mercator",
                  {{"min_x", l.mercator_bounds.min_x},
                   {"min_y", l.mercator_bounds.min_y},
                   {"max_x", l.mercator_bounds.max_x},
                   {"max_y", l.mercator_bounds.max_y}}},
                 {"lonlat",
                  {{"west", l.bounds.west},
                   {"south", l.bounds.south},
                   {"east", l.bounds.east},
                   {"north", l.bounds.north}}}};
  j["max_points"] = l.max_points;
  j["source_points"] = l.source_points;
  j["min_z"] = l.min_z;
  j["max_z"] = l.max_z;
  j["level_max_error"] = l.level_max_error;
  const auto options = nlohmann::json::parse(l.options_json, nullptr, false);
  j["options"] = options.is_discarded() ? nlohmann::json(l.options_json) : options;
  j["attribution"] = l.attribution;
  return j;
}

int fail(const std::string& message) {
  std::cerr << "tinstream info: " << message << "\n";
  return 1;
}

int run_info(const InfoOptions& o) {
  if (o.has_tile && o.layer.empty()) return fail("--tile needs --layer");
  auto store = store::TileStore::open(o.store, store::TileStore::Mode::read_only);
  if (!store) return fail(store.error().message);

  if (o.layer.empty()) {
    auto layers = store->layers();
    if (!layers) return fail(layers.error().message);
    nlohmann::json j = {{"store", o.store}, {"layers", nlohmann::json::array()}};
    for (const auto& l : *layers) j["layers"].push_back(layer_summary(l));
    std::cout << j.dump(2) << "\n";
    return 0;
  }

  auto layer = store->layer(o.layer);
  if (!layer) return fail(layer.error().message);
  if (!o.has_tile) {
    std::cout << layer_details(*layer).dump(2) << "\n";
    return 0;
  }

  const auto id = geo::TileId::from_quadkey(o.tile);
  if (!id) return fail("--tile " + o.tile + ": " + id.error().message);
  auto stored = store->tile(o.layer, *id);
  if (!stored) return fail(stored.error().message);
  if (!stored->has_value()) {
    return fail("layer '" + o.layer + "' has no tile " + id->to_string() + " (quadkey " + o.tile +
                ")");
  }
  auto raw = tile::decompress((*stored)->compressed);
  if (!raw)
    return fail("layer '" + o.layer + "' tile " + id->to_string() + ": " + raw.error().message);
  auto t = tile::decode(*raw);
  if (!t) return fail("layer '" + o.layer + "' tile " + id->to_string() + ": " + t.error().message);

  const geo::MercatorRect m = id->bounds();
  const geo::LonLatRect ll = id->lonlat_bounds(geo::NormalisedMercator(layer->projection));
  nlohmann::json nodata = nlohmann::json::array();
  static constexpr const char* kCorners[4] = {"NW", "NE", "SW", "SE"};
  for (std::size_t c = 0; c < 4; ++c) {
    if (t->corner_nodata[c]) nodata.push_back(kCorners[c]);
  }
  const Status structure = tile::check_structure(*t);
  nlohmann::json j = {
      {"layer", o.layer},
      {"tile",
       {{"quadkey", id->quadkey()},
        {"z", id->z},
        {"x", id->x},
        {"y", id->y},
        {"tms_y", id->tms_row()}}},
      {"vertex_count", t->vertex_count()},
      {"triangle_count", t->triangles.size()},
      {"roles",
       {{"corner", 4},
        {"north", t->north.size()},
        {"east", t->east.size()},
        {"south", t->south.size()},
        {"west", t->west.size()},
        {"interior", t->interior.size()}}},
      {"nodata_corners", nodata},
      {"min_z", t->min_z},
      {"max_z", t->max_z},
      {"geometric_error", t->geometric_error},
      {"rms_error", t->rms_error},
      {"source_points", t->source_points},
      {"bounds",
       {{"mercator",
         {{"min_x", m.min_x}, {"min_y", m.min_y}, {"max_x", m.max_x}, {"max_y", m.max_y}}},
        {"lonlat",
         {{"west", ll.west}, {"south", ll.south}, {"east", ll.east}, {"north", ll.north}}}}},
      {"stored",
       {{"compressed_bytes", (*stored)->compressed.size()},
        {"encoded_bytes", raw->size()},
        {"etag", (*stored)->etag}}},
      {"structure", structure.ok() ? std::string("ok") : structure.error().message}};
  std::cout << j.dump(2) << "\n";
  return 0;
}

const CommandRegistration kRegistration{
    "info", "Describe a tile store, one layer or one tile, as JSON",
    [](CLI::App& sub) -> CommandRun {
      auto o = std::make_shared<InfoOptions>();
      sub.add_option("--store", o->store, "Tile store file (SQLite)")->required();
      sub.add_option("--layer", o->layer,
                     "Layer name: print its metadata instead of the layer list");
      CLI::Option* tile =
          sub.add_option("--tile", o->tile,
                         "Quadkey of a tile of --layer (\"\" for level 0): print its statistics");
      sub.footer(
          "Without --layer: {store, layers: [summary…]}. With --layer: the layer's metadata.\n"
          "With --tile: counts, vertex roles, NODATA corners, bounds in normalised Mercator and\n"
          "degrees, stored size and ETag, and the result of the structural check.");
      return [o, tile] {
        o->has_tile = tile->count() > 0;
        return run_info(*o);
      };
    }};

}  // namespace
}  // namespace tinstream::cli
