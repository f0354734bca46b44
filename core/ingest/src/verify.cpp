#include "tinstream/ingest/verify.hpp"

#include <algorithm>
#include <map>
#include <unordered_map>

#include "tinstream/kernel/predicates.hpp"
#include "tinstream/lod/error.hpp"

namespace tinstream::ingest {
namespace {

class Problems {
 public:
  Problems(VerifyReport& report, std::size_t max) : report_(report), max_(max) {}
  void add(std::string message) {
    ++report_.problems;
    if (report_.messages.size() < max_) report_.messages.push_back(std::move(message));
  }

 private:
  VerifyReport& report_;
  std::size_t max_;
};

bool same_vertices(const std::vector<tile::Vertex>& a, const std::vector<tile::Vertex>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].x != b[i].x || a[i].y != b[i].y || a[i].z != b[i].z) return false;
  }
  return true;
}

// Empty circle across every interior edge (exact).
std::uint64_t count_non_delaunay(const tile::TinTile& t) {
  const auto v = t.vertices();
  std::unordered_map<std::uint64_t, std::uint32_t> opposite;  // directed edge → third vertex
  opposite.reserve(t.triangles.size() * 3);
  auto key = [](std::uint32_t a, std::uint32_t b) { return (std::uint64_t{a} << 32) | b; };
  for (const auto& tri : t.triangles) {
    for (std::size_t k = 0; k < 3; ++k) opposite[key(tri[k], tri[(k + 1) % 3])] = tri[(k + 2) % 3];
  }
  std::uint64_t bad = 0;
  for (const auto& tri : t.triangles) {
    for (std::size_t k = 0; k < 3; ++k) {
      const auto it = opposite.find(key(tri[(k + 1) % 3], tri[k]));
      if (it == opposite.end()) continue;  // border edge
      const auto& a = v[tri[0]];
      const auto& b = v[tri[1]];
      const auto& c = v[tri[2]];
      const auto& d = v[it->second];
      if (kernel::incircle({a.x, a.y}, {b.x, b.y}, {c.x, c.y}, {d.x, d.y}) > 0.0) ++bad;
    }
  }
  return bad;
}

// Decoded tiles of one layer, read on demand: neighbours and children are read again when their
// turn comes. A tile that cannot be read is a problem (named); a missing one is nullptr. The
// pointers handed out stay valid until trim().
class TileCache {
 public:
  TileCache(store::TileStore& store, const std::string& layer, Problems& problems)
      : store_(store), layer_(layer), problems_(problems) {}
  const tile::TinTile* load(const geo::TileId& id) {
    if (auto it = cache_.find(id); it != cache_.end()) return &it->second;
    auto t = store_.read_tile(layer_, id);
    if (!t) {
      problems_.add("tile " + id.quadkey() + " (" + id.to_string() + "): " + t.error().message);
      return nullptr;
    }
    if (!t->has_value()) return nullptr;
    return &cache_.emplace(id, std::move(**t)).first->second;
  }
  // Bounds the memory: empties the cache when it holds more than a few thousand tiles.
  void trim() {
    if (cache_.size() > 4096) cache_.clear();
  }

 private:
  store::TileStore& store_;
  const std::string& layer_;
  Problems& problems_;
  std::map<geo::TileId, tile::TinTile> cache_;
};

// The geometric-error check: a coarse tile's stored error must be at least the error measured
// against the finest surface on a sample of the finest tiles under it (verify.hpp).
class ErrorCheck {
 public:
  ErrorCheck(const std::vector<geo::TileId>& ids, std::uint32_t finest, std::size_t samples)
      : finest_(finest), samples_(samples) {
    // The finest tiles in Morton order: a tile's descendants are one contiguous range of them.
    for (const auto& id : ids) {
      if (id.z == finest) finest_morton_.emplace_back(id.morton(), id);
    }
    std::sort(finest_morton_.begin(), finest_morton_.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
  }

  // Requires: id.z < the finest level.
  void check(const geo::TileId& id, const tile::TinTile& t, const std::string& name,
             TileCache& cache, Problems& problems, VerifyReport& report) const {
    if (samples_ == 0) return;
    const std::vector<tile::TinTile> sample = finest_sample(id, cache);
    if (sample.empty()) return;
    auto measured = lod::measured_max_error(t, sample);
    if (!measured) {
      problems.add(name + ": error check: " + measured.error().message);
      return;
    }
    ++report.error_checks;
    if (t.geometric_error > 0) {
      report.worst_error_ratio = std::max(report.worst_error_ratio, *measured / t.geometric_error);
    }
    if (*measured > t.geometric_error) {
      problems.add(name + ": stored geometric error " + std::to_string(t.geometric_error) +
                   " m is below the error measured against the finest surface, " +
                   std::to_string(*measured) + " m");
    }
  }

 private:
  // Up to `samples_` finest tiles under `id`, spread evenly over its descendants.
  std::vector<tile::TinTile> finest_sample(const geo::TileId& id, TileCache& cache) const {
    const std::uint32_t shift = 2 * (finest_ - id.z);
    const std::uint64_t first = id.morton() << shift, last = (id.morton() + 1) << shift;
    auto below = [](const std::pair<std::uint64_t, geo::TileId>& e, std::uint64_t m) {
      return e.first < m;
    };
    const auto lo = std::lower_bound(finest_morton_.begin(), finest_morton_.end(), first, below);
    const auto hi = std::lower_bound(lo, finest_morton_.end(), last, below);
    const auto count = static_cast<std::size_t>(hi - lo);
    std::vector<tile::TinTile> sample;
    if (count == 0) return sample;
    const std::size_t take = std::min(count, samples_);
    for (std::size_t k = 0; k < take; ++k) {
      const geo::TileId fid = (lo + static_cast<std::ptrdiff_t>(k * count / take))->second;
      if (const tile::TinTile* f = cache.load(fid)) sample.push_back(*f);
    }
    return sample;
  }

  std::uint32_t finest_;
  std::size_t samples_;
  std::vector<std::pair<std::uint64_t, geo::TileId>> finest_morton_;
};

// Watertight against the east and south neighbours (so each pair is compared once).
void check_shared_borders(const geo::TileId& id, const tile::TinTile& t, const std::string& name,
                          const std::map<geo::TileId, bool>& present, TileCache& cache,
                          Problems& problems, VerifyReport& report) {
  for (auto dir : {geo::Direction::east, geo::Direction::south}) {
    const auto nid = id.neighbour(dir);
    if (!nid || !present.count(*nid)) continue;
    const tile::TinTile* n = cache.load(*nid);
    if (!n) continue;
    ++report.shared_borders;
    const auto opposite =
        dir == geo::Direction::east ? geo::Direction::west : geo::Direction::north;
    if (!same_vertices(t.border(dir), n->border(opposite))) {
      problems.add(name + ": " + (dir == geo::Direction::east ? "east" : "south") +
                   " border differs from neighbour " + nid->quadkey() + " (not watertight)");
    }
  }
}

// A coarse tile has children under it, each with an error at most the tile's (monotone).
void check_children(const geo::TileId& id, const tile::TinTile& t, const std::string& name,
                    const std::map<geo::TileId, bool>& present, TileCache& cache,
                    Problems& problems) {
  bool has_child = false;
  for (const auto& c : id.children()) {
    if (!present.count(c)) continue;
    has_child = true;
    if (const tile::TinTile* child = cache.load(c)) {
      if (child->geometric_error > t.geometric_error) {
        problems.add(name + ": geometric error " + std::to_string(t.geometric_error) +
                     " is below child " + c.quadkey() + "'s " +
                     std::to_string(child->geometric_error));
      }
    }
  }
  if (!has_child) problems.add(name + ": has no children (pyramid broken)");
}

}  // namespace

Result<VerifyReport> verify_layer(store::TileStore& store, const std::string& layer,
                                  const VerifyOptions& options, const ProgressSink& progress) {
  auto info = store.layer(layer);
  if (!info) return info.error();
  auto ids = store.tile_ids(layer);
  if (!ids) return ids.error();
  VerifyReport report;
  Problems problems(report, options.max_problems);
  const std::uint32_t finest = info->max_level;
  TileCache cache(store, layer, problems);
  std::map<geo::TileId, bool> present;
  for (const auto& id : *ids) present[id] = true;
  const ErrorCheck error_check(*ids, finest, options.error_samples);

  std::uint64_t finest_source_points = 0;
  std::map<std::uint32_t, std::uint64_t> per_level;
  std::uint64_t done = 0;
  for (const auto& id : *ids) {
    cache.trim();
    const tile::TinTile* t = cache.load(id);
    if (!t) continue;
    const std::string name = "tile " + id.quadkey() + " (" + id.to_string() + ")";
    ++report.tiles;
    ++per_level[id.z];
    report.triangles += t->triangles.size();
    if (t->id != id)
      problems.add(name + ": stored under the wrong key (holds " + t->id.to_string() + ")");
    if (Status s = tile::check_structure(*t); !s) problems.add(name + ": " + s.error().message);
    if (options.delaunay) {
      if (const auto bad = count_non_delaunay(*t); bad > 0) {
        problems.add(name + ": " + std::to_string(bad) +
                     " interior edges violate the empty-circle property");
      }
    }
    check_shared_borders(id, *t, name, present, cache, problems, report);
    if (id.z == finest) {
      finest_source_points += t->source_points;
      if (t->interior.size() > t->source_points) {
        problems.add(name + ": " + std::to_string(t->interior.size()) +
                     " interior vertices but only " + std::to_string(t->source_points) +
                     " source points");
      }
    } else {
      if (t->vertex_count() > std::max<std::size_t>(info->max_points, 4)) {
        problems.add(name + ": " + std::to_string(t->vertex_count()) +
                     " vertices, over the budget of " + std::to_string(info->max_points));
      }
      error_check.check(id, *t, name, cache, problems, report);
      check_children(id, *t, name, present, cache, problems);
    }
    if (id.z > info->min_level && !present.count(id.parent())) {
      problems.add(name + ": its parent " + id.parent().quadkey() + " is missing");
    }
    if (progress && (++done % 64 == 0) && !progress({"verify", done, ids->size(), "tiles"})) {
      return Error(ErrorCode::cancelled, "verify cancelled");
    }
  }
  if (finest_source_points != info->point_count) {
    problems.add("finest level " + std::to_string(finest) + " accounts for " +
                 std::to_string(finest_source_points) + " points, the layer records " +
                 std::to_string(info->point_count) + " (points lost)");
  }
  if (report.tiles != info->tile_count) {
    problems.add("layer records " + std::to_string(info->tile_count) + " tiles, the store holds " +
                 std::to_string(report.tiles));
  }
  for (std::uint32_t z = info->min_level; z <= finest; ++z) {
    if (!per_level.count(z)) problems.add("level " + std::to_string(z) + " has no tiles");
  }
  return report;
}

}  // namespace tinstream::ingest
