// `tinstream export`: takes tiles out of a store. The mode follows from the options given:
//   --tile QUADKEY --format obj|json [--out FILE]   one tile (this file)
//   --dir DIR                                       a static Cesium tree (export_cesium.hpp)
//
// OBJ is exactly: one `v <lon°> <lat°> <ellipsoidal height m>` line per vertex in the tile's
// numbering (degrees with 10 decimals, metres with 4), then one `f a b c` line per triangle,
// 1-based, counter-clockwise seen from above. With --drop-nodata, NODATA corners (height 0, no
// data) and the triangles using them are left out and the rest renumbered in the same order, so
// a mesh viewer shows no walls down to sea level where the data end. JSON carries every vertex
// plus its role, NODATA flag, normalised Mercator coordinates and weight; its triangle indices
// are 0-based.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "command.hpp"
#include "export_cesium.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::cli {
namespace {

struct ExportOptions {
  std::string store;
  std::string layer;
  std::string tile;
  std::string format;
  std::string out;
  std::string dir;
  bool has_tile = false;  // an empty quadkey is the level-0 tile
  bool drop_nodata = false;
  CesiumDirExport cesium;
};

int fail(const std::string& message) {
  std::cerr << "tinstream export: " << message << "\n";
  return 1;
}

const char* role_name(tile::VertexRole role) {
  switch (role) {
    case tile::VertexRole::corner:
      return "corner";
    case tile::VertexRole::north:
      return "north";
    case tile::VertexRole::east:
      return "east";
    case tile::VertexRole::south:
      return "south";
    case tile::VertexRole::west:
      return "west";
    case tile::VertexRole::interior:
      return "interior";
  }
  return "unknown";
}

std::string to_obj(const tile::TinTile& t, const geo::NormalisedMercator& projection,
                   bool drop_nodata) {
  std::string out;
  out.reserve(t.vertex_count() * 48 + t.triangles.size() * 24);
  char line[160];
  // number[i]: vertex i's 1-based OBJ index, 0 when left out.
  std::vector<std::uint32_t> number(t.vertex_count(), 0);
  std::uint32_t written = 0;
  for (std::size_t i = 0; i < t.vertex_count(); ++i) {
    if (drop_nodata && i < 4 && t.corner_nodata[i]) continue;
    number[i] = ++written;
    const tile::Vertex& v = t.vertex(i);
    const geo::LonLat p = projection.inverse({v.x, v.y});
    std::snprintf(line, sizeof line, "v %.10f %.10f %.4f\n", p.lon, p.lat, v.z);
    out += line;
  }
  for (const tile::Triangle& tri : t.triangles) {
    if (number[tri[0]] == 0 || number[tri[1]] == 0 || number[tri[2]] == 0) continue;
    std::snprintf(line, sizeof line, "f %u %u %u\n", number[tri[0]], number[tri[1]],
                  number[tri[2]]);
    out += line;
  }
  return out;
}

std::string to_json(const tile::TinTile& t, const store::LayerInfo& layer,
                    const geo::NormalisedMercator& projection) {
  nlohmann::json vertices = nlohmann::json::array();
  for (std::size_t i = 0; i < t.vertex_count(); ++i) {
    const tile::Vertex& v = t.vertex(i);
    const geo::LonLat p = projection.inverse({v.x, v.y});
    vertices.push_back({{"role", role_name(t.role(i))},
                        {"nodata", i < 4 && t.corner_nodata[i]},
                        {"lon", p.lon},
                        {"lat", p.lat},
                        {"height", v.z},
                        {"x", v.x},
                        {"y", v.y},
                        {"weight", v.weight}});
  }
  nlohmann::json triangles = nlohmann::json::array();
  for (const tile::Triangle& tri : t.triangles) triangles.push_back({tri[0], tri[1], tri[2]});
  const nlohmann::json j = {
      {"layer", layer.name},
      {"projection", std::string(geo::to_string(layer.projection))},
      {"tile", {{"quadkey", t.id.quadkey()}, {"z", t.id.z}, {"x", t.id.x}, {"y", t.id.y}}},
      {"min_z", t.min_z},
      {"max_z", t.max_z},
      {"geometric_error", t.geometric_error},
      {"vertices", vertices},
      {"triangles", triangles}};
  return j.dump(1) + "\n";
}

int export_tile(const ExportOptions& o) {
  if (o.format != "obj" && o.format != "json") {
    return fail("--format must be obj or json (got '" + o.format + "')");
  }
  if (o.layer.empty()) return fail("--layer is required with --tile");
  const auto id = geo::TileId::from_quadkey(o.tile);
  if (!id) return fail("--tile " + o.tile + ": " + id.error().message);
  auto store = store::TileStore::open(o.store, store::TileStore::Mode::read_only);
  if (!store) return fail(store.error().message);
  auto layer = store->layer(o.layer);
  if (!layer) return fail(layer.error().message);
  auto t = store->read_tile(o.layer, *id);
  if (!t) return fail(t.error().message);
  if (!t->has_value()) {
    return fail("layer '" + o.layer + "' has no tile " + id->to_string() + " (quadkey " + o.tile +
                ")");
  }
  const geo::NormalisedMercator projection(layer->projection);
  const std::string text =
      o.format == "obj" ? to_obj(**t, projection, o.drop_nodata) : to_json(**t, *layer, projection);
  if (o.out.empty()) {
    std::cout << text;
    std::cout.flush();
    return std::cout ? 0 : fail("writing to standard output failed");
  }
  std::ofstream file(o.out, std::ios::binary | std::ios::trunc);
  if (!file) return fail(o.out + ": cannot open for writing");
  file << text;
  file.close();
  if (!file) return fail(o.out + ": write failed");
  return 0;
}

int run_export(ExportOptions& o) {
  const bool dir_mode = !o.dir.empty();
  if (dir_mode && o.has_tile)
    return fail("give either --tile (one tile) or --dir (Cesium tree), not both");
  if (dir_mode) {
    if (o.layer.empty()) return fail("--layer is required with --dir");
    o.cesium.store = o.store;
    o.cesium.layer = o.layer;
    o.cesium.dir = o.dir;
    return run_export_cesium_dir(o.cesium);
  }
  if (!o.has_tile)
    return fail("nothing to export: give --tile QUADKEY (one tile) or --dir DIR (Cesium tree)");
  return export_tile(o);
}

const CommandRegistration kRegistration{
    "export", "Export one tile as OBJ/JSON (--tile) or a layer as a static Cesium tree (--dir)",
    [](CLI::App& sub) -> CommandRun {
      auto o = std::make_shared<ExportOptions>();
      sub.add_option("--store", o->store, "Tile store file (SQLite)")->required();
      sub.add_option("--layer", o->layer, "Layer name");
      CLI::Option* tile =
          sub.add_option("--tile", o->tile, "Quadkey of the tile to export (\"\" = level 0)");
      sub.add_option("--format", o->format, "Tile format: obj or json")
          ->check(CLI::IsMember({"obj", "json"}))
          ->default_val("obj");
      sub.add_option("--out", o->out, "Output file for --tile (default: standard output)");
      sub.add_flag("--drop-nodata", o->drop_nodata,
                   "OBJ: leave out NODATA corners (no data there, height 0) and their triangles");
      sub.add_option("--dir", o->dir, "Output directory: static Cesium quantized-mesh tree");
      add_cesium_dir_options(sub, o->cesium);
      sub.footer(
          "OBJ: `v <lon deg> <lat deg> <ellipsoidal height m>` per vertex (tile numbering: "
          "corners\n"
          "NW NE SW SE, north, east, south, west edges, interior), then `f a b c` per triangle\n"
          "(1-based, counter-clockwise seen from above). --drop-nodata leaves out NODATA\n"
          "corners and the triangles using them (no walls to sea level at the data's edge).\n"
          "JSON: every vertex with role, nodata, Mercator x/y and weight; indices 0-based.");
      return [o, tile] {
        o->has_tile = tile->count() > 0;
        return run_export(*o);
      };
    }};

}  // namespace
}  // namespace tinstream::cli
