// tinstream/triangulate/finest_tiles.hpp — the finest tiles: pass 3 of the ingest
// (docs/DESIGN.md §3.3).
//
// Each finest tile is the Delaunay triangulation of the GLOBAL point set restricted to the tile
// rectangle R: Delaunay edges that cross R's border give edge points (intersection, elevation
// interpolated linearly), each corner gets the elevation of the global triangle containing it
// (or, outside the data, is flagged NODATA and takes the height of the input point nearest to it —
// never 0, see docs/tile-format.md §2.1), the border is constrained, and the tile is
// re-triangulated from corners + edge points + interior points (tile::TinTile). An edge through a
// tile corner (exact orientation test) gives no edge point: the corner is the vertex there.
//
// Halo method (beyond the paper): a tile is computed from its own points plus the points of the
// neighbouring *sub-cells* (quadtree cells 2^sub_shift times finer than the tile) that hold a point
// inside the circumcircle of a triangle meeting R's border ∂R (or beyond a local hull edge touching
// R). The local triangulation is grown until no such point is missing — then the triangles meeting
// ∂R are globally Delaunay (no point outside the gathered cells lies in their circles), and they,
// with the tile's own points, are all the tile's output depends on, so the tile is the global
// triangulation restricted to R. To bound the work near data gaps and the data's outer boundary,
// only triangles with circumradius ≤ rmax count as surface (see canonical_circumradius2), so only
// points within R ⊕ 2·rmax are ever examined. Tiles are independent: any thread or machine can
// compute any tile, in any order.
//
// Watertightness: two neighbours see the same global edges crossing their shared border and
// compute each intersection from the edge's endpoints in canonical (lexicographic) order with
// the same formula, so their shared edge points are bit-identical. Points lying exactly on a
// border line are edge points of both tiles. Corners are interpolated the same way by all four
// tiles around them, and a NODATA corner's nearest input point is searched by all four in the
// same sub-cells, in the same order.
//
// Threads: PointCells is read-only after construction and may be shared; each thread needs its
// own subdivide::SortedRunReader (it owns a file handle).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <unordered_map>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/kernel/predicates.hpp"
#include "tinstream/subdivide/sorted_run.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::triangulate {

// Where the points of every sub-cell of every finest tile are in the sorted run.
class PointCells {
 public:
  // Scans the run once (sequentially) to count the points of each sub-cell.
  // Reads the run once, split between `threads` readers.
  static Result<std::shared_ptr<const PointCells>> build(const subdivide::SortedRun& run,
                                                         unsigned threads = 1);

  std::uint32_t level() const { return level_; }          // finest tile level L
  std::uint32_t sub_shift() const { return sub_shift_; }  // cells per tile side = 2^sub_shift
  std::uint32_t cell_level() const { return level_ + sub_shift_; }
  const std::vector<subdivide::TileRange>& tiles() const { return tiles_; }
  // Index into tiles() of a finest tile, or -1 when it holds no points.
  std::ptrdiff_t tile_index(const geo::TileId& id) const;
  // Record range [first, first + count) of cell (cx, cy) at cell_level().
  std::pair<std::uint64_t, std::uint64_t> cell_range(std::uint32_t cx, std::uint32_t cy) const;
  const std::filesystem::path& run_path() const { return run_path_; }
  // The convex hull of all points (counter-clockwise, no collinear vertices).
  const std::vector<kernel::XY>& hull() const { return hull_; }

 private:
  std::uint32_t level_ = 0, sub_shift_ = 0;
  std::vector<subdivide::TileRange> tiles_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;  // key (x << 32 | y) → tiles_ index
  std::vector<std::uint32_t> cell_offsets_;  // per tile: 4^sub_shift + 1 prefix sums (Morton order)
  std::filesystem::path run_path_;
  std::vector<kernel::XY> hull_;
};

// The surface: global Delaunay triangles whose circumradius is at most
// max_circumradius_tiles × (finest tile width). Larger triangles only bridge data gaps or hug the
// data's convex hull; they are left out when deciding edge and corner points (a tile's own
// re-triangulation still covers its whole rectangle). This bounds the halo to R ⊕ 2·rmax.
// Squared circumradius of a triangle computed from its vertices in lexicographic order, so every
// tile gets the same bits for the same triangle.
double canonical_circumradius2(kernel::XY a, kernel::XY b, kernel::XY c);

struct FinestTileOptions {
  double max_circumradius_tiles = 0.5;
  std::size_t max_gathered_points = 4u << 20;  // refuse a tile whose halo needs more
  int max_rounds = 64;                         // halo growth rounds before giving up
};

struct FinestTileStats {
  // Points in the tile's halo triangulation: the halo plus the own points (in band mode only the
  // own cells along the border and those a circle reached; see src/halo.hpp).
  std::uint64_t gathered_points = 0;
  int rounds = 0;                  // halo growth rounds
  std::uint64_t circle_tests = 0;  // point-in-circumcircle tests deciding the halo
};

// Computes one finest tile. `reader` must read the run that `cells` indexes.
Result<tile::TinTile> build_finest_tile(const geo::TileId& id, const PointCells& cells,
                                        subdivide::SortedRunReader& reader,
                                        const FinestTileOptions& options = {},
                                        FinestTileStats* stats = nullptr);

// Computes every finest tile of the run on `threads` workers. Each worker hands the tiles it
// finishes to `sink` itself, so `sink` is called from several threads at once and must be
// thread-safe: CPU work on a tile (encoding it for the store) then runs in parallel, and only the
// sink's own critical section (the store write) is serial. The calling thread reports `progress`.
// Stops at the first error (returned) or when `sink` or `progress` returns false/an error.
struct TriangulateSummary {
  std::uint64_t tiles = 0;
  std::uint64_t gathered_points = 0;  // Σ FinestTileStats::gathered_points: overhead measure
  int max_rounds = 0;
  std::uint64_t circle_tests = 0;  // Σ point-in-circumcircle tests (work measure of the halo)
};
using TileSink = std::function<Status(tile::TinTile&&)>;
Result<TriangulateSummary> build_finest_tiles(const subdivide::SortedRun& run, unsigned threads,
                                              const TileSink& sink,
                                              const FinestTileOptions& options = {},
                                              const ProgressSink& progress = {});

}  // namespace tinstream::triangulate
