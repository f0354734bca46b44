#include "tinstream/ingest/verify.hpp"

#include <algorithm>
#include <map>
#include <unordered_map>

#include "tinstream/kernel/predicates.hpp"
#ifdef TINSTREAM_HAVE_LOD
#include "tinstream/lod/error.hpp"
#endif

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

  // Small cache of decoded tiles: neighbours are read again when their turn comes. Emptied only
  // between tiles, so the pointers load() hands out stay valid while one tile is checked.
  std::map<geo::TileId, tile::TinTile> cache;
  auto load = [&](const geo::TileId& id) -> const tile::TinTile* {
    if (auto it = cache.find(id); it != cache.end()) return &it->second;
    auto t = store.read_tile(layer, id);
    if (!t) {
      problems.add("tile " + id.quadkey() + " (" + id.to_string() + "): " + t.error().message);
      return nullptr;
    }
    if (!t->has_value()) return nullptr;
    return &cache.emplace(id, std::move(**t)).first->second;
  };
  std::map<geo::TileId, bool> present;
  for (const auto& id : *ids) present[id] = true;

  // The finest tiles in Morton order: a tile's descendants are one contiguous range of them.
  std::vector<std::pair<std::uint64_t, geo::TileId>> finest_morton;
  for (const auto& id : *ids) {
    if (id.z == finest) finest_morton.emplace_back(id.morton(), id);
  }
  std::sort(finest_morton.begin(), finest_morton.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  // Stored geometric error ≥ the error measured on a sample of the finest tiles under the tile.
  auto check_error = [&](const geo::TileId& id, const tile::TinTile& t, const std::string& name) {
#ifdef TINSTREAM_HAVE_LOD
    if (options.error_samples == 0) return;
    const std::uint32_t shift = 2 * (finest - id.z);
    const std::uint64_t first = id.morton() << shift, last = (id.morton() + 1) << shift;
    auto below = [](const std::pair<std::uint64_t, geo::TileId>& e, std::uint64_t m) {
      return e.first < m;
    };
    const auto lo = std::lower_bound(finest_morton.begin(), finest_morton.end(), first, below);
    const auto hi = std::lower_bound(lo, finest_morton.end(), last, below);
    const auto count = static_cast<std::size_t>(hi - lo);
    if (count == 0) return;
    const std::size_t take = std::min(count, options.error_samples);
    std::vector<tile::TinTile> sample;
    for (std::size_t k = 0; k < take; ++k) {
      const geo::TileId fid = (lo + static_cast<std::ptrdiff_t>(k * count / take))->second;
      if (const tile::TinTile* f = load(fid)) sample.push_back(*f);
    }
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
#else
    (void)id, (void)t, (void)name;
#endif
  };

  std::uint64_t finest_source_points = 0;
  std::map<std::uint32_t, std::uint64_t> per_level;
  std::uint64_t done = 0;
  for (const auto& id : *ids) {
    if (cache.size() > 4096) cache.clear();
    const tile::TinTile* t = load(id);
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
    // Watertight against the east and south neighbours (each pair once).
    for (auto dir : {geo::Direction::east, geo::Direction::south}) {
      const auto nid = id.neighbour(dir);
      if (!nid || !present.count(*nid)) continue;
      const tile::TinTile* n = load(*nid);
      if (!n) continue;
      ++report.shared_borders;
      const auto opposite =
          dir == geo::Direction::east ? geo::Direction::west : geo::Direction::north;
      if (!same_vertices(t->border(dir), n->border(opposite))) {
        problems.add(name + ": " + (dir == geo::Direction::east ? "east" : "south") +
                     " border differs from neighbour " + nid->quadkey() + " (not watertight)");
      }
    }
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
      check_error(id, *t, name);
      bool has_child = false;
      for (const auto& c : id.children()) {
        if (!present.count(c)) continue;
        has_child = true;
        if (const tile::TinTile* child = load(c)) {
          if (child->geometric_error > t->geometric_error) {
            problems.add(name + ": geometric error " + std::to_string(t->geometric_error) +
                         " is below child " + c.quadkey() + "'s " +
                         std::to_string(child->geometric_error));
          }
        }
      }
      if (!has_child) problems.add(name + ": has no children (pyramid broken)");
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
