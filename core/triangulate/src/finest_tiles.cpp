#include "tinstream/triangulate/finest_tiles.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <thread>

#include "border_cut.hpp"
#include "delaunay.hpp"
#include "halo.hpp"
#include "tile_buffers.hpp"
#include "tile_geometry.hpp"
#include "tinstream/base/worker_threads.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::triangulate {
namespace {

using detail::pack;
using kernel::XY;
using subdivide::SortedPoint;

constexpr std::uint32_t kKeyLevel = 30;
constexpr std::uint32_t kDefaultSubShift = 4;

// Andrew's monotone chain with exact orientation; collinear points dropped; counter-clockwise.
std::vector<XY> convex_hull(std::vector<XY> points) {
  std::sort(points.begin(), points.end(),
            [](const XY& a, const XY& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  points.erase(std::unique(points.begin(), points.end(),
                           [](const XY& a, const XY& b) { return a.x == b.x && a.y == b.y; }),
               points.end());
  if (points.size() < 3) return points;
  std::vector<XY> hull(2 * points.size());
  std::size_t k = 0;
  for (const XY& p : points) {
    while (k >= 2 && kernel::orient2d(hull[k - 2], hull[k - 1], p) <= 0.0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && kernel::orient2d(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  hull.shrink_to_fit();  // kept per tile while PointCells::build runs: not 2 × the tile's points
  return hull;
}

}  // namespace

double canonical_circumradius2(XY a, XY b, XY c) {
  auto less = [](const XY& l, const XY& r) { return l.x < r.x || (l.x == r.x && l.y < r.y); };
  if (less(b, a)) std::swap(a, b);
  if (less(c, b)) std::swap(b, c);
  if (less(b, a)) std::swap(a, b);
  const detail::Circle circle = detail::circumcircle(a, b, c);
  return circle.unbounded ? std::numeric_limits<double>::infinity() : circle.r2;
}

// ── PointCells ─────────────────────────────────────────────────────────────────────────────────

Result<std::shared_ptr<const PointCells>> PointCells::build(const subdivide::SortedRun& run,
                                                            unsigned threads) {
  auto cells = std::make_shared<PointCells>();
  cells->level_ = run.finest_level;
  cells->sub_shift_ = std::min(kDefaultSubShift, kKeyLevel - run.finest_level);
  cells->tiles_ = run.tiles;
  cells->run_path_ = run.path;
  const std::uint32_t per_tile = 1u << (2 * cells->sub_shift_);
  const std::size_t tiles = cells->tiles_.size();
  cells->cell_offsets_.assign(tiles * (per_tile + 1), 0);
  for (std::uint32_t i = 0; i < tiles; ++i) {
    cells->index_.emplace(pack(cells->tiles_[i].id.x, cells->tiles_[i].id.y), i);
  }
  const std::uint32_t cell_shift = 2 * (kKeyLevel - cells->cell_level());
  // Calls visit(t, points) for each tile index in `which`, on `threads` readers, each taking the
  // next tile.
  auto for_each_tile = [&](const std::vector<std::uint32_t>& which, const auto& visit) -> Status {
    std::atomic<std::size_t> next{0};
    std::mutex mutex;
    Status failure;
    auto read_tiles = [&] {
      // The exception barrier (this runs on the workers and on the calling thread). Fault point
      // "pass3.cells": one tile.
      Status s = guarded("pass 3 cell index", [&]() -> Status {
        auto reader = subdivide::SortedRunReader::open(run.path);
        if (!reader) return reader.error();
        std::vector<SortedPoint> chunk;
        for (std::size_t i; (i = next.fetch_add(1)) < which.size();) {
          fault::point("pass3.cells");
          const auto& range = cells->tiles_[which[i]];
          if (Status r = reader->read(range.first, range.count, chunk); !r) return r;
          visit(which[i], chunk);
        }
        return {};
      });
      if (s.ok()) return;
      next.store(which.size());  // the other readers stop too
      std::lock_guard lock(mutex);
      if (failure.ok()) failure = s;
    };
    WorkerThreads pool("pass 3 cell index", "pass3.cells");
    Status started;
    for (unsigned t = 1; t < std::max(1u, threads) && started.ok(); ++t) {
      started = pool.start(read_tiles);
    }
    if (started.ok()) {
      read_tiles();
    } else {
      next.store(which.size());  // those started stop at once
    }
    (void)pool.join();  // read_tiles keeps its own failures
    return started.ok() ? failure : started;
  };
  // Every tile: its cell offsets and the bounding box of its points.
  std::vector<std::uint32_t> all(tiles);
  for (std::uint32_t t = 0; t < tiles; ++t) all[t] = t;
  std::vector<geo::MercatorRect> boxes(tiles);
  Status read = for_each_tile(all, [&](std::uint32_t t, const std::vector<SortedPoint>& chunk) {
    std::uint32_t* counts = &cells->cell_offsets_[std::size_t{t} * (per_tile + 1)];
    geo::MercatorRect box{chunk[0].x, chunk[0].y, chunk[0].x, chunk[0].y};
    for (const SortedPoint& p : chunk) {
      const auto local = static_cast<std::uint32_t>((p.key >> cell_shift) & (per_tile - 1));
      ++counts[local + 1];
      box.min_x = std::min(box.min_x, p.x), box.max_x = std::max(box.max_x, p.x);
      box.min_y = std::min(box.min_y, p.y), box.max_y = std::max(box.max_y, p.y);
    }
    for (std::uint32_t i = 1; i <= per_tile; ++i) counts[i] += counts[i - 1];
    boxes[t] = box;
  });
  if (!read.ok()) return read.error();
  // The data's hull is the hull of the tiles' hulls. A tile whose four diagonal neighbours' points
  // all lie strictly beyond its own in both coordinates has no point on it: for every direction,
  // one neighbour's points lie strictly further that way. Only the other tiles are read again.
  auto enclosed = [&](std::uint32_t t) {
    const geo::TileId& id = cells->tiles_[t].id;
    const geo::MercatorRect& b = boxes[t];
    for (const int dx : {-1, 1}) {
      for (const int dy : {-1, 1}) {  // rows count from the north: dy = -1 is north, +y
        const std::ptrdiff_t n = cells->tile_index(
            {id.z, static_cast<std::uint32_t>(static_cast<std::int64_t>(id.x) + dx),
             static_cast<std::uint32_t>(static_cast<std::int64_t>(id.y) + dy)});
        if (n < 0) return false;
        const geo::MercatorRect& o = boxes[static_cast<std::size_t>(n)];
        const bool beyond_x = dx > 0 ? o.min_x > b.max_x : o.max_x < b.min_x;
        const bool beyond_y = dy < 0 ? o.min_y > b.max_y : o.max_y < b.min_y;
        if (!beyond_x || !beyond_y) return false;
      }
    }
    return true;
  };
  std::vector<std::uint32_t> open;
  for (std::uint32_t t = 0; t < tiles; ++t) {
    if (!enclosed(t)) open.push_back(t);
  }
  std::vector<std::vector<XY>> tile_hulls(tiles);
  read = for_each_tile(open, [&](std::uint32_t t, const std::vector<SortedPoint>& chunk) {
    std::vector<XY> points(chunk.size());
    for (std::size_t i = 0; i < chunk.size(); ++i) points[i] = {chunk[i].x, chunk[i].y};
    tile_hulls[t] = convex_hull(std::move(points));
  });
  if (!read.ok()) return read.error();
  std::vector<XY> hull_candidates;
  for (const auto& h : tile_hulls) {
    hull_candidates.insert(hull_candidates.end(), h.begin(), h.end());
  }
  cells->hull_ = convex_hull(std::move(hull_candidates));
  return std::shared_ptr<const PointCells>(std::move(cells));
}

std::ptrdiff_t PointCells::tile_index(const geo::TileId& id) const {
  if (id.z != level_) return -1;
  const auto it = index_.find(pack(id.x, id.y));
  return it == index_.end() ? -1 : static_cast<std::ptrdiff_t>(it->second);
}

std::pair<std::uint64_t, std::uint64_t> PointCells::cell_range(std::uint32_t cx,
                                                               std::uint32_t cy) const {
  const std::ptrdiff_t t = tile_index({level_, cx >> sub_shift_, cy >> sub_shift_});
  if (t < 0) return {0, 0};
  const std::uint32_t mask = (1u << sub_shift_) - 1;
  const auto local = static_cast<std::uint32_t>(subdivide::morton_interleave(cx & mask, cy & mask));
  const std::uint32_t per_tile = 1u << (2 * sub_shift_);
  const std::uint32_t* offsets = &cell_offsets_[static_cast<std::size_t>(t) * (per_tile + 1)];
  const auto& range = tiles_[static_cast<std::size_t>(t)];
  return {range.first + offsets[local], offsets[local + 1] - offsets[local]};
}

// ── One tile ───────────────────────────────────────────────────────────────────────────────────

namespace {

// One finest tile: gather its halo (halo.hpp), cut the global triangulation at its border
// (border_cut.hpp), re-triangulate corners + edge points + interior (the border is the hull).
Result<tile::TinTile> build_tile(const geo::TileId& id, const PointCells& cells,
                                 subdivide::SortedRunReader& reader,
                                 const FinestTileOptions& options, FinestTileStats* stats,
                                 detail::TileBuffers& buffers) {
  if (id.z != cells.level()) {
    return invalid_argument("tile " + id.to_string() + " is not at the finest level " +
                            std::to_string(cells.level()));
  }
  detail::HaloGatherer halo(id, cells, reader, options, buffers);
  if (Status s = halo.gather(); !s) return s.error();
  if (stats) {
    stats->gathered_points = buffers.pts.size();
    stats->rounds = halo.rounds();
    stats->circle_tests = halo.circle_tests();
  }
  auto out = detail::cut_at_border(id, cells, reader, halo, buffers);
  if (!out) return out.error();
  const std::vector<tile::Vertex> vertices = out->vertices();
  auto& xy = buffers.xy;
  xy.resize(vertices.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) xy[i] = {vertices[i].x, vertices[i].y};
  buffers.delaunay.clear();  // a cleared builder triangulates exactly as a new one (same order)
  buffers.delaunay.extend(xy);
  const auto& triangles = buffers.delaunay.mesh().triangles;
  out->triangles.assign(triangles.begin(), triangles.end());
  out->update_z_range();
  return out;
}

}  // namespace

Result<tile::TinTile> build_finest_tile(const geo::TileId& id, const PointCells& cells,
                                        subdivide::SortedRunReader& reader,
                                        const FinestTileOptions& options, FinestTileStats* stats) {
  detail::TileBuffers buffers;
  return build_tile(id, cells, reader, options, stats, buffers);
}

// ── All tiles, in parallel ─────────────────────────────────────────────────────────────────────

Result<TriangulateSummary> build_finest_tiles(const subdivide::SortedRun& run, unsigned threads,
                                              const TileSink& sink,
                                              const FinestTileOptions& options,
                                              const ProgressSink& progress) {
  auto cells_or = PointCells::build(run, threads);
  if (!cells_or) return cells_or.error();
  const std::shared_ptr<const PointCells> cells = *cells_or;
  const std::size_t total = cells->tiles().size();
  threads = std::max(
      1u, std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::size_t>(total, 1))));

  std::mutex mutex;
  std::condition_variable changed;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  TriangulateSummary summary;  // guarded by mutex, as are the two below
  Status failure;              // the first error
  unsigned finished = 0;       // workers that have returned
  auto fail = [&](Status s) {
    std::lock_guard lock(mutex);
    if (failure.ok()) failure = std::move(s);
    stop.store(true);
    changed.notify_all();
  };

  auto work = [&] {
    auto reader = subdivide::SortedRunReader::open(cells->run_path());
    detail::TileBuffers buffers;  // this worker's, reused from tile to tile
    if (!reader) fail(reader.error());
    while (reader) {
      const std::size_t i = next.fetch_add(1);
      if (i >= total || stop.load()) break;
      fault::point("pass3.tile");
      FinestTileStats stats;
      auto tile = build_tile(cells->tiles()[i].id, *cells, *reader, options, &stats, buffers);
      buffers.release_oversized();
      if (!tile) {
        fail(tile.error());
        break;
      }
      if (stop.load()) break;
      if (Status s = sink(std::move(*tile)); !s) {
        fail(s);
        break;
      }
      std::lock_guard lock(mutex);
      ++summary.tiles;
      summary.gathered_points += stats.gathered_points;
      summary.max_rounds = std::max(summary.max_rounds, stats.rounds);
      summary.circle_tests += stats.circle_tests;
      changed.notify_all();
    }
  };
  // The exception barrier: whatever a tile or the sink throws is the run's error, and the worker
  // still counts as finished.
  auto worker = [&] {
    if (Status s = guarded("pass 3 worker", work); !s) fail(std::move(s));
    std::lock_guard lock(mutex);
    ++finished;
    changed.notify_all();
  };
  WorkerThreads pool("pass 3 worker", "pass3.tile");
  unsigned started = 0;
  for (; started < threads; ++started) {
    if (Status s = pool.start(worker); !s) {
      fail(std::move(s));  // the started workers stop at their next tile
      break;
    }
  }

  std::uint64_t reported = ~std::uint64_t{0};
  for (;;) {
    std::uint64_t done = 0;
    bool all_returned = false;
    {
      std::unique_lock lock(mutex);
      changed.wait(lock, [&] { return finished == started || summary.tiles != reported; });
      done = summary.tiles;
      all_returned = finished == started;
    }
    if (progress && done != reported && !progress({"triangulate", done, total, "tiles"})) {
      fail(Error(ErrorCode::cancelled, "ingest cancelled while triangulating"));
    }
    reported = done;
    if (all_returned) break;
  }
  (void)pool.join();  // the workers' failures went to fail()
  if (!failure.ok()) return failure.error();
  return summary;
}

}  // namespace tinstream::triangulate
