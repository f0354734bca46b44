// tinstream-bench-store STORE LAYER: writes a synthetic but realistic layer for the server
// benchmark when the ingest pipeline is not at hand — a 16×16 block of level-14 tiles near
// Luxembourg (65×65 vertex grids, ~8k triangles each) with their level-13 and -12 parents.
#include <cstdio>
#include <exception>

#include "grid_tile.hpp"
#include "tinstream/store/tile_store.hpp"

int main(int argc, char** argv) {
  using namespace tinstream;
  if (argc != 3) {
    std::fprintf(stderr, "usage: tinstream-bench-store STORE LAYER\n");
    return 2;
  }
  auto st = store::TileStore::open(argv[1], store::TileStore::Mode::read_write);
  if (!st) {
    std::fprintf(stderr, "%s\n", st.error().message.c_str());
    return 1;
  }
  std::vector<geo::TileId> ids;
  for (std::uint32_t z = 12; z <= 14; ++z) {
    const std::uint32_t n = 4u << (z - 12), x0 = 2120u << (z - 12), y0 = 1400u << (z - 12);
    for (std::uint32_t x = x0; x < x0 + n; ++x)
      for (std::uint32_t y = y0; y < y0 + n; ++y) ids.push_back(*geo::TileId::from_zxy(z, x, y));
  }
  store::LayerInfo info;
  info.name = argv[2];
  info.min_level = 12;
  info.max_level = 14;
  info.attribution = "synthetic benchmark surface";
  const geo::NormalisedMercator merc;
  info.bounds = ids.front().lonlat_bounds(merc);
  for (const auto& id : ids) {
    if (id.z != 12) continue;
    const auto b = id.lonlat_bounds(merc);
    info.bounds.west = std::min(info.bounds.west, b.west);
    info.bounds.south = std::min(info.bounds.south, b.south);
    info.bounds.east = std::max(info.bounds.east, b.east);
    info.bounds.north = std::max(info.bounds.north, b.north);
  }
  auto writer = st->begin_layer(info);
  if (!writer) {
    std::fprintf(stderr, "%s\n", writer.error().message.c_str());
    return 1;
  }
  for (const auto& id : ids) {
    if (Status s = (*writer)->put(testing::make_grid_tile(id, 65, testing::synthetic_height)); !s) {
      std::fprintf(stderr, "%s\n", s.error().message.c_str());
      return 1;
    }
  }
  info.tile_count = ids.size();
  if (Status s = (*writer)->publish(info); !s) {
    std::fprintf(stderr, "%s\n", s.error().message.c_str());
    return 1;
  }
  std::printf("wrote %zu tiles\n", ids.size());
  return 0;
}
