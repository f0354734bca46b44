#include "tinstream/ingest/verify.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <unordered_map>

#include "tinstream/kernel/predicates.hpp"
#include "tinstream/lod/error.hpp"
#include "tinstream/terrain/quantized_mesh.hpp"

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

// Pairs of a tile's vertices closer than kNearDuplicate (normalised Mercator units, about 4e-5 m
// at the equator): quantised encodings (quantized-mesh, float32 on a GPU) merge them into one
// position, and their triangles into needles of zero area (#20: an edge point 1e-14 beside a
// corner). Sorted by x, each vertex compared with those within the distance in x.
constexpr double kNearDuplicate = 1e-12;

std::uint64_t count_near_duplicates(const tile::TinTile& t) {
  std::vector<tile::Vertex> v = t.vertices();
  std::sort(v.begin(), v.end(), [](const tile::Vertex& a, const tile::Vertex& b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
  });
  std::uint64_t pairs = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    for (std::size_t j = i + 1; j < v.size() && v[j].x - v[i].x < kNearDuplicate; ++j) {
      if (std::hypot(v[j].x - v[i].x, v[j].y - v[i].y) < kNearDuplicate) ++pairs;
    }
  }
  return pairs;
}

// The zero-area triangles of a quantized-mesh encoding, read back from its bytes (the layout of
// quantized_mesh.hpp: the 88-byte header, the vertex count, u, v and height as zig-zag deltas,
// the triangle count and its high-water-mark indices, u32 and 4-aligned above 65,536 vertices).
// An Error when the bytes are cut short.
Result<std::uint64_t> count_zero_area_triangles(const std::vector<std::uint8_t>& qm) {
  std::size_t at = 88;
  auto read = [&](std::size_t bytes) -> Result<std::uint32_t> {
    if (at + bytes > qm.size()) return Error(ErrorCode::corrupt_data, "quantized-mesh cut short");
    std::uint32_t value = 0;
    for (std::size_t k = 0; k < bytes; ++k) value |= std::uint32_t{qm[at + k]} << (8 * k);
    at += bytes;
    return value;
  };
  auto n = read(4);
  if (!n) return n.error();
  std::array<std::vector<std::int32_t>, 2> uv;
  for (auto& column : uv) {
    column.resize(*n);
    std::int32_t value = 0;
    for (auto& c : column) {
      auto zigzag = read(2);
      if (!zigzag) return zigzag.error();
      value += static_cast<std::int32_t>(*zigzag >> 1) ^ -static_cast<std::int32_t>(*zigzag & 1);
      c = value;
    }
  }
  at += 2 * std::size_t{*n};  // heights
  const bool wide = *n > 65536;
  if (wide && at % 4 != 0) at += 4 - at % 4;
  auto triangles = read(4);
  if (!triangles) return triangles.error();
  std::uint32_t highest = 0;
  std::uint64_t zero_area = 0;
  for (std::uint32_t t = 0; t < *triangles; ++t) {
    std::array<std::int64_t, 3> index{};
    for (auto& i : index) {
      auto code = read(wide ? 4 : 2);
      if (!code) return code.error();
      i = static_cast<std::int64_t>(highest) - *code;
      if (*code == 0) ++highest;
      if (i < 0 || i >= static_cast<std::int64_t>(*n)) {
        return Error(ErrorCode::corrupt_data, "quantized-mesh index out of range");
      }
    }
    const auto u = [&](std::size_t k) {
      return std::int64_t{uv[0][static_cast<std::size_t>(index[k])]};
    };
    const auto v = [&](std::size_t k) {
      return std::int64_t{uv[1][static_cast<std::size_t>(index[k])]};
    };
    if ((u(1) - u(0)) * (v(2) - v(0)) - (v(1) - v(0)) * (u(2) - u(0)) == 0) ++zero_area;
  }
  return zero_area;
}

// Checks that quantised encodings of the tile stay sound: no two of its vertices closer than 1e-12
// (they would share a quantised position), and for a layer in spherical Mercator (the one Cesium
// reads) no zero-area triangle in its quantized-mesh encoding.
void check_quantisable(const tile::TinTile& t, geo::Projection projection, const std::string& name,
                       Problems& problems, VerifyReport& report) {
  if (const std::uint64_t pairs = count_near_duplicates(t); pairs > 0) {
    report.near_duplicate_pairs += pairs;
    problems.add(name + ": " + std::to_string(pairs) +
                 " pairs of vertices closer than 1e-12 (near-duplicate vertices)");
  }
  if (projection != geo::Projection::spherical) return;
  auto qm = terrain::encode_quantized_mesh(t, projection);
  if (!qm) {
    problems.add(name + ": quantized-mesh encoding: " + qm.error().message);
    return;
  }
  auto zero_area = count_zero_area_triangles(*qm);
  if (!zero_area) {
    problems.add(name + ": quantized-mesh encoding: " + zero_area.error().message);
  } else if (*zero_area > 0) {
    problems.add(name + ": " + std::to_string(*zero_area) +
                 " zero-area triangles in its quantized-mesh encoding");
  }
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
  ErrorCheck(const std::vector<geo::TileId>& ids, std::uint32_t finest, std::size_t samples,
             bool surface)
      : finest_(finest), samples_(samples), surface_(surface) {
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
    if (surface_) check_surface(t, sample, name, problems, report);
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

  // The exact maximum over the sample's data triangles (the overlay: vertices and edge crossings),
  // which the vertex sample above only bounds from below. The allowance covers this evaluation's
  // own rounding.
  static void check_surface(const tile::TinTile& t, const std::vector<tile::TinTile>& sample,
                            const std::string& name, Problems& problems, VerifyReport& report) {
    std::vector<const tile::TinTile*> fines;
    fines.reserve(sample.size());
    for (const auto& f : sample) fines.push_back(&f);
    const double overlay = lod::surface_difference(t, fines).max_abs;
    if (t.geometric_error > 0) {
      report.worst_surface_ratio =
          std::max(report.worst_surface_ratio, overlay / t.geometric_error);
    }
    if (overlay > t.geometric_error + lod::error_rounding_allowance(t)) {
      problems.add(name + ": stored geometric error " + std::to_string(t.geometric_error) +
                   " m is below the maximum difference to the finest surface (overlay, edge "
                   "crossings included), " +
                   std::to_string(overlay) + " m");
    }
  }

  std::uint32_t finest_;
  std::size_t samples_;
  bool surface_;
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
  const ErrorCheck error_check(*ids, finest, options.error_samples, options.surface_error);

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
    if (options.quantisation) check_quantisable(*t, info->projection, name, problems, report);
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
