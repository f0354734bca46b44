// bench/lod: the stored pyramid's one-tile levels against greedy insertion from the finest data,
// for scattered data (LiDAR), where Delatin (a grid method) cannot be the peer (#20). Not a test.
//
//   pyramid_vs_greedy STORE LAYER [--tile Z/X/Y]
//
// --tile: that stored tile only, against greedy insertion from the finest data points under it;
// also where the stored tile is worst, and lod::thin_tile run on every finest data point inside
// the tile with the stored tile's corners and border (the thinning alone, without the pyramid's
// choice of candidates). REBUILD_DEPTH=d (with MAXP=the store's --max-points) also rebuilds the
// tile with build_from_sources from the stored children and the stored tiles d levels below (no
// witnesses or bounds) and says whether it is identical to the stored one.
// In that thin_tile run, GREEDY_FACTOR=k sets LodOptions::greedy_factor (the greedy stage's size,
// 0 = drop from all points) and NO_NODATA (any value) treats the tile's NODATA corners as data,
// to see what the corners cost the tile.
//
// For every level whose single tile holds all the data: that stored tile's vertex count V and its
// maximum vertical error over the finest level's data points (the input points, and the edge
// points and corners on the data: the same points pyramid_quality measures at), beside the
// maximum error over the same points of a greedy-insertion TIN with V vertices built from those
// points: the four corners of the data's bounding box (a little outside it, each at the height of
// the data point nearest to it), then, one at a time, the point farthest (vertically) from the
// current Delaunay TIN (Garland & Heckbert's greedy insertion, the method Delatin implements for
// grids), until V vertices. The peer's triangulation is CGAL's (Delaunay_triangulation_2, exact
// predicates), its bookkeeping is this file's. Both errors are evaluated by this file.

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <queue>
#include <string>
#include <vector>

#include "../../core/lod/tests/point_greedy.hpp"
#include "store_data.hpp"
#include "tinstream/lod/parent.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/codec.hpp"

namespace {

using tinstream::bench::Point3;

// A tile's largest vertical difference from the points (each located in it).
double max_error(const tinstream::tile::TinTile& tile, const std::vector<Point3>& pts) {
  const tinstream::bench::Locator here = tinstream::bench::tile_locator(tile);
  double e = 0;
  for (const auto& p : pts) {
    double w;
    e = std::max(e, std::abs(here.height(p.x, p.y, &w) - p.z));
  }
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || (argc > 3 && (argc != 5 || std::string(argv[3]) != "--tile"))) {
    std::fprintf(stderr, "usage: %s STORE LAYER [--tile Z/X/Y]\n", argv[0]);
    return 2;
  }
  std::optional<tinstream::geo::TileId> only;
  if (argc == 5) {
    unsigned z = 0, x = 0, y = 0;
    if (std::sscanf(argv[4], "%u/%u/%u", &z, &x, &y) != 3)
      return std::fprintf(stderr, "--tile wants Z/X/Y, not %s\n", argv[4]), 2;
    only = tinstream::geo::TileId{z, x, y};
  }
  auto store =
      tinstream::store::TileStore::open(argv[1], tinstream::store::TileStore::Mode::read_only);
  if (!store) return std::fprintf(stderr, "%s\n", store.error().message.c_str()), 1;
  auto info = store->layer(argv[2]);
  if (!info) return std::fprintf(stderr, "%s\n", info.error().message.c_str()), 1;
  const std::uint32_t finest = info->max_level;
  const auto fd = tinstream::bench::finest_data(*store, argv[2], finest);
  std::vector<Point3> pts;
  for (const auto& [id, p] : fd.points) {
    const std::uint32_t shift = only ? finest - only->z : 0;
    if (only && ((id.x >> shift) != only->x || (id.y >> shift) != only->y)) continue;
    pts.insert(pts.end(), p.begin(), p.end());
  }
  // One copy of each (x, y): the finest tiles share their border points.
  std::sort(pts.begin(), pts.end(),
            [](const Point3& a, const Point3& b) { return a.x != b.x ? a.x < b.x : a.y < b.y; });
  pts.erase(std::unique(pts.begin(), pts.end(),
                        [](const Point3& a, const Point3& b) { return a.x == b.x && a.y == b.y; }),
            pts.end());
  std::printf("%s layer %s: finest level %u, %zu distinct finest data points\n\n", argv[1], argv[2],
              finest, pts.size());
  std::printf(
      "| level | levels above the finest | vertices | ours: max error (m) | greedy insertion: max "
      "error (m) | ours / greedy | greedy build (s, cumulative) "
      "|\n|---:|---:|---:|---:|---:|---:|---:|\n");
  // Levels from the finest up whose one tile holds the data, largest vertex count first: one
  // greedy run serves them all (its TIN at V vertices is measured on the way up).
  struct Level {
    std::uint32_t z;
    std::size_t vertices;
    double ours;
  };
  std::vector<Level> levels;
  for (std::uint32_t z = finest + 1; z-- > info->min_level;) {
    auto ids = store->tile_ids(argv[2], z);
    if (only) {
      if (z != only->z) continue;
      ids = std::vector<tinstream::geo::TileId>{*only};
    }
    if (!ids || ids->size() != 1) continue;
    auto t = store->read_tile(argv[2], ids->front());
    if (!t || !*t) return std::fprintf(stderr, "cannot read level %u\n", z), 1;
    const tinstream::bench::Locator here = tinstream::bench::tile_locator(**t);
    double ours = 0;
    const Point3* worst = nullptr;
    for (const auto& p : pts) {
      double w;
      const double e = std::abs(here.height(p.x, p.y, &w) - p.z);
      if (e > ours) ours = e, worst = &p;
    }
    if (only) {
      // The same tile thinned by lod::thin_tile from every finest data point inside it, its
      // corners and border as stored: is it the thinning or the candidates it was given?
      tinstream::lod::ThinInput in = tinstream::lod::thin_input(**t);
      in.interior.clear();
      const auto r = only->bounds();
      for (const auto& p : pts) {
        if (p.x > r.min_x && p.x < r.max_x && p.y > r.min_y && p.y < r.max_y)
          in.interior.push_back({p.x, p.y, p.z});
      }
      tinstream::lod::LodOptions o;
      o.max_points = (**t).vertex_count();
      if (const char* g = std::getenv("GREEDY_FACTOR")) o.greedy_factor = std::atof(g);
      if (std::getenv("NO_NODATA")) in.corner_nodata = {false, false, false, false};
      tinstream::lod::ThinStats st;
      auto thinned = tinstream::lod::thin_tile(in, o, &st);
      if (thinned) {
        const double e = max_error(*thinned, pts);
        std::printf(
            "thin_tile from all %zu interior points, the stored border: %zu vertices, max "
            "error %.4f m (greedy stage %zu, its error %.4f; duplicates %zu, border removed %zu, "
            "last error %.4f)\n",
            in.interior.size(), thinned->vertex_count(), e, st.greedy_inserted, st.greedy_error,
            st.duplicates, st.border_removed, st.last_error);
      }
    }
    if (only && std::getenv("REBUILD_DEPTH")) {
      // The tile rebuilt by build_from_sources from the stored children and the stored tiles
      // REBUILD_DEPTH levels below (no witnesses or bounds: the candidates as the pyramid gives
      // them when the sources are finest tiles).
      const std::uint32_t depth =
          static_cast<std::uint32_t>(std::atoi(std::getenv("REBUILD_DEPTH")));
      tinstream::lod::Children ch;
      const auto kids = only->children();
      for (std::size_t k = 0; k < 4; ++k) {
        auto c = store->read_tile(argv[2], kids[k]);
        if (c && *c) ch.tiles[k] = tinstream::lod::LodTile{std::move(**c), {}, {}, {}};
      }
      tinstream::lod::Sources src;
      src.depth = depth;
      if (depth > 1) {
        auto deeper = store->tile_ids(argv[2], only->z + depth);
        for (const auto& id : *deeper) {
          if ((id.x >> depth) != only->x || (id.y >> depth) != only->y) continue;
          auto c = store->read_tile(argv[2], id);
          src.tiles.push_back(tinstream::lod::LodTile{std::move(**c), {}, {}, {}});
        }
      }
      tinstream::lod::LodOptions o;
      o.max_points = std::strtoul(std::getenv("MAXP") ? std::getenv("MAXP") : "16384", nullptr, 10);
      tinstream::lod::ThinStats st;
      auto rebuilt = tinstream::lod::build_from_sources(*only, ch, src, o, &st);
      if (!rebuilt) {
        std::printf("rebuild: %s\n", rebuilt.error().message.c_str());
      } else {
        const double e = max_error(rebuilt->tile, pts);
        std::printf(
            "rebuilt from depth %u (%zu sources): %zu input points, %zu vertices, max error "
            "%.4f m, identical to stored: %s; duplicates %zu, greedy %zu (error %.4f), border "
            "removed %zu, last error %.4f\n",
            depth, src.tiles.size(), st.input_points, rebuilt->tile.vertex_count(), e,
            tinstream::tile::encode(rebuilt->tile) == tinstream::tile::encode(**t) ? "yes" : "no",
            st.duplicates, st.greedy_inserted, st.greedy_error, st.border_removed, st.last_error);
      }
    }
    if (only && worst) {
      const auto r = only->bounds();
      std::printf(
          "ours: worst point at (%.4f, %.4f) of the tile (0…1 west→east, south→north), %.3f m\n\n",
          (worst->x - r.min_x) / r.width(), (worst->y - r.min_y) / r.height(), worst->z);
    }
    levels.push_back({z, (**t).vertex_count(), ours});
  }
  std::sort(levels.begin(), levels.end(),
            [](const Level& a, const Level& b) { return a.vertices < b.vertices; });
  const auto start = std::chrono::steady_clock::now();
  std::vector<tinstream::testing::GreedyPoint> gp;
  gp.reserve(pts.size());
  for (const auto& p : pts) gp.push_back({p.x, p.y, p.z});
  tinstream::testing::PointGreedy greedy(gp);
  for (const Level& l : levels) {
    while (greedy.vertices() < l.vertices && greedy.step()) {
    }
    const double peer = greedy.max_error();
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("| %u | %u | %zu | %.4f | %.4f | %.3f | %.2f |\n", l.z, finest - l.z, l.vertices,
                l.ours, peer, peer > 0 ? l.ours / peer : 0.0, secs);
    std::fflush(stdout);
  }
  return 0;
}
