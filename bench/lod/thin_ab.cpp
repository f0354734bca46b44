// bench/lod: an A/B tool for the thinning (core/lod), on the two paths thin_tile takes. Not a test.
//
//   thin_ab grid    <dem.tif> <N> [reps]
//       thin_tile on the whole grid as one tile in its own metres (as lod_vs_greedy does),
//       max_points N: lattice path. Prints wall and CPU seconds per run, vertices, and a hash of
//       the result (vertices and triangles). LOD_LATTICE_SCAN=0 turns LodOptions::lattice_scan
//       off: the same grid on the general path (every point filed under its triangle), which
//       exercises the greedy stage's re-filing with a lattice's ties (points on edges).
//   thin_ab parents <store> <layer> <child level> [max parents] [reps]
//       build_parent (default LodOptions) for the parents of the stored tiles at <child level>,
//       from the stored children: the general path a LiDAR ingest takes. Prints time, a hash of
//       every parent's blob, and how many parents are bit-identical to the stored ones.
//
// For instruction counts: valgrind --tool=callgrind --toggle-collect='tinstream::lod::thin_tile*'
// thin_ab … (only thin_tile's share, not the overlay error of build_parent).
// Build: see the comment of run.sh (same include paths and libraries), or bench/lod/CMakeLists.txt.
#include <gdal_priv.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "grid_input.hpp"
#include "tinstream/lod/parent.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/tile/codec.hpp"

namespace {

using tinstream::tile::TinTile;
using tinstream::tile::Vertex;

// FNV-1a, 64 bits.
struct Hash {
  std::uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  }
};

struct Clock {
  std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
  std::clock_t cpu = std::clock();
  double wall_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
  }
  double cpu_s() const { return static_cast<double>(std::clock() - cpu) / CLOCKS_PER_SEC; }
};

int grid(const char* path, std::size_t n, int reps) {
  GDALAllRegister();
  auto* ds = static_cast<GDALDataset*>(GDALOpen(path, GA_ReadOnly));
  if (!ds) return std::fprintf(stderr, "cannot open %s\n", path), 1;
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  double gt[6];
  ds->GetGeoTransform(gt);
  std::vector<float> z(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, z.data(), w, h, GDT_Float32, 0, 0) !=
      CE_None)
    return 1;
  GDALClose(ds);
  auto v = [&](int c, int r) {
    return Vertex{
        gt[0] + (c + 0.5) * gt[1], gt[3] + (r + 0.5) * gt[5],
        z[static_cast<std::size_t>(r) * static_cast<std::size_t>(w) + static_cast<std::size_t>(c)],
        0.0};
  };
  // The same input as lod_vs_greedy's grid_input.
  const tinstream::lod::ThinInput in = tinstream::bench::grid_thin_input(w, h, v);
  tinstream::lod::LodOptions o;
  o.max_points = n;
  if (const char* l = std::getenv("LOD_LATTICE_SCAN")) o.lattice_scan = std::string(l) != "0";
  for (int rep = 0; rep < reps; ++rep) {
    const Clock clock;
    tinstream::lod::ThinStats st;
    auto t = tinstream::lod::thin_tile(in, o, &st);
    const double ws = clock.wall_s(), cs = clock.cpu_s();
    if (!t.ok()) return std::fprintf(stderr, "thin_tile: %s\n", t.error().message.c_str()), 1;
    Hash hash;
    for (const Vertex& p : t->vertices()) hash.bytes(&p, sizeof p);
    for (const auto& tr : t->triangles) hash.bytes(tr.data(), sizeof tr);
    std::printf("grid N=%zu wall %.4f s cpu %.4f s vertices %zu greedy %zu hash %016llx\n", n, ws,
                cs, t->vertex_count(), st.greedy_inserted, static_cast<unsigned long long>(hash.h));
  }
  return 0;
}

int parents(const char* store_path, const std::string& layer, std::uint32_t level,
            std::size_t limit, int reps) {
  using tinstream::store::TileStore;
  auto store = TileStore::open(store_path, TileStore::Mode::read_only);
  if (!store.ok()) return std::fprintf(stderr, "%s\n", store.error().message.c_str()), 1;
  auto ids = store->tile_ids(layer, level);
  if (!ids.ok()) return std::fprintf(stderr, "%s\n", ids.error().message.c_str()), 1;
  std::map<tinstream::geo::TileId, std::array<std::optional<TinTile>, 4>> families;
  for (const auto& id : *ids) {
    const auto p = id.parent();
    if (!families.count(p) && families.size() == limit) continue;
    auto t = store->read_tile(layer, id);
    if (!t.ok() || !*t) return std::fprintf(stderr, "cannot read %s\n", id.to_string().c_str()), 1;
    families[p][id.child_index()] = std::move(**t);
  }
  std::size_t points = 0;
  for (const auto& [p, ch] : families) {
    for (const auto& c : ch) points += c ? c->vertex_count() : 0;
  }
  for (int rep = 0; rep < reps; ++rep) {
    Hash hash;
    std::size_t same = 0, built = 0;
    double wall = 0, cpu = 0;
    for (const auto& [p, ch] : families) {
      const Clock clock;
      auto t = tinstream::lod::build_parent(p, ch, {});
      wall += clock.wall_s(), cpu += clock.cpu_s();
      if (!t.ok()) return std::fprintf(stderr, "build_parent: %s\n", t.error().message.c_str()), 1;
      const std::vector<std::uint8_t> blob = tinstream::tile::encode(*t);
      hash.bytes(blob.data(), blob.size());
      ++built;
      auto stored = store->read_tile(layer, p);
      if (stored.ok() && *stored && tinstream::tile::encode(**stored) == blob) ++same;
    }
    std::printf(
        "parents of level %u: %zu built from %zu points, wall %.3f s cpu %.3f s, "
        "identical to stored %zu, hash %016llx\n",
        level, built, points, wall, cpu, same, static_cast<unsigned long long>(hash.h));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "grid" && argc >= 4) {
    return grid(argv[2], std::stoul(argv[3]), argc > 4 ? std::stoi(argv[4]) : 1);
  }
  if (mode == "parents" && argc >= 5) {
    return parents(argv[2], argv[3], static_cast<std::uint32_t>(std::stoul(argv[4])),
                   argc > 5 ? std::stoul(argv[5]) : SIZE_MAX, argc > 6 ? std::stoi(argv[6]) : 1);
  }
  std::fprintf(stderr,
               "usage: %s grid <dem.tif> <N> [reps] | parents <store> <layer> <child level> "
               "[max parents] [reps]\n",
               argv[0]);
  return 2;
}
