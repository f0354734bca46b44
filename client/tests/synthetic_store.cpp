#include "synthetic_store.hpp"

#include <unistd.h>

#include <set>
#include <stdexcept>
#include <tuple>

#include "grid_tile.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client::testing {

TempDir::TempDir(const std::string& name)
    : path(std::filesystem::path(TINSTREAM_BINARY_DIR) / "client_test_tmp" /
           (name + "-" + std::to_string(::getpid()))) {
  std::filesystem::remove_all(path);
  std::filesystem::create_directories(path);
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

SyntheticLayer default_layer() {
  SyntheticLayer l;
  for (std::uint32_t y = 1400; y < 1404; ++y)
    for (std::uint32_t x = 2120; x < 2124; ++x) l.finest.push_back({12, x, y});
  return l;
}

tile::TinTile make_tile(const geo::TileId& id, const SyntheticLayer& layer) {
  tile::TinTile t =
      tinstream::testing::make_grid_tile(id, layer.grid, tinstream::testing::synthetic_height);
  const std::uint32_t finest = layer.finest.front().z;
  // Errors that make a 1280×720 view refine below a few kilometres: 20 m per level above the
  // finest (a level-11 tile at 3 km shows 20 m × 623 / 3000 ≈ 4 px).
  t.geometric_error = 20.0 * (finest - id.z);
  return t;
}

namespace {

// TileId's order (z, x, y), spelled out: clang-tidy reports modernize-use-nullptr inside the
// synthesised operator<=>.
struct IdLess {
  bool operator()(const geo::TileId& a, const geo::TileId& b) const {
    return std::tie(a.z, a.x, a.y) < std::tie(b.z, b.x, b.y);
  }
};

}  // namespace

std::vector<geo::TileId> write_layer(const std::filesystem::path& path,
                                     const SyntheticLayer& layer) {
  std::set<geo::TileId, IdLess> ids(layer.finest.begin(), layer.finest.end());
  for (geo::TileId id : layer.finest)
    while (id.z > layer.min_level) {
      id = id.parent();
      ids.insert(id);
    }
  auto st = store::TileStore::open(path, store::TileStore::Mode::read_write);
  if (!st) throw std::runtime_error("open store: " + st.error().message);
  const geo::NormalisedMercator merc(layer.projection);
  store::LayerInfo info;
  info.name = layer.name;
  info.projection = layer.projection;
  info.min_level = layer.min_level;
  info.max_level = layer.finest.front().z;
  info.max_points = 1000;
  geo::MercatorRect b = layer.finest.front().bounds();
  for (const geo::TileId& id : layer.finest) {
    const geo::MercatorRect r = id.bounds();
    b = {std::min(b.min_x, r.min_x), std::min(b.min_y, r.min_y), std::max(b.max_x, r.max_x),
         std::max(b.max_y, r.max_y)};
  }
  info.mercator_bounds = b;
  const geo::LonLat nw = merc.inverse({b.min_x, b.max_y}), se = merc.inverse({b.max_x, b.min_y});
  info.bounds = {nw.lon, se.lat, se.lon, nw.lat};
  info.level_max_error.assign(info.max_level + 1, 0.0);
  auto writer = st->begin_layer(info);
  if (!writer) throw std::runtime_error("begin_layer: " + writer.error().message);
  double min_z = 1e300, max_z = -1e300;
  for (const geo::TileId& id : ids) {
    const tile::TinTile t = make_tile(id, layer);
    min_z = std::min(min_z, t.min_z);
    max_z = std::max(max_z, t.max_z);
    info.level_max_error[id.z] = std::max(info.level_max_error[id.z], t.geometric_error);
    Status s = (*writer)->put(t);
    if (!s) throw std::runtime_error("put: " + s.error().message);
  }
  info.min_z = min_z;
  info.max_z = max_z;
  Status s = (*writer)->publish(info);
  if (!s) throw std::runtime_error("publish: " + s.error().message);
  return {ids.begin(), ids.end()};
}

void write_imagery(const std::filesystem::path& store, const std::string& terrain,
                   store::ImageryInfo info, const std::vector<geo::TileId>& tiles,
                   const ImageBytes& bytes) {
  auto st = store::TileStore::open(store, store::TileStore::Mode::read_write);
  if (!st) throw std::runtime_error(st.error().message);
  auto layer = st->layer(terrain);
  if (!layer) throw std::runtime_error(layer.error().message);
  info.mercator_bounds = layer->mercator_bounds;
  info.bounds = layer->bounds;
  auto writer = st->begin_imagery(info);
  if (!writer) throw std::runtime_error(writer.error().message);
  for (const geo::TileId& id : tiles) {
    std::optional<std::vector<std::uint8_t>> data = bytes(id);
    if (!data) continue;
    if (Status ok = (*writer)->put({id, std::move(*data), {}}); !ok)
      throw std::runtime_error(ok.error().message);
  }
  if (Status ok = (*writer)->publish(info); !ok) throw std::runtime_error(ok.error().message);
}

}  // namespace tinstream::client::testing
