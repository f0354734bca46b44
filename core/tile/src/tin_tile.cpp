#include "tinstream/tile/tin_tile.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "exact_orientation.hpp"

namespace tinstream::tile {

namespace {

// Where the lists of each role start in the vertex numbering (tin_tile.hpp).
struct Offsets {
  std::size_t north, east, south, west, interior, end;
};

Offsets offsets_of(const TinTile& t) {
  Offsets o{};
  o.north = 4;
  o.east = o.north + t.north.size();
  o.south = o.east + t.east.size();
  o.west = o.south + t.south.size();
  o.interior = o.west + t.west.size();
  o.end = o.interior + t.interior.size();
  return o;
}

std::string fmt(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string point_text(const Vertex& v) { return "(" + fmt(v.x) + ", " + fmt(v.y) + ")"; }

}  // namespace

std::size_t TinTile::vertex_count() const { return offsets_of(*this).end; }

const Vertex& TinTile::vertex(std::size_t i) const {
  const Offsets o = offsets_of(*this);
  assert(i < o.end);
  if (i < o.north) return corners[i];
  if (i < o.east) return north[i - o.north];
  if (i < o.south) return east[i - o.east];
  if (i < o.west) return south[i - o.south];
  if (i < o.interior) return west[i - o.west];
  return interior[i - o.interior];
}

VertexRole TinTile::role(std::size_t i) const {
  const Offsets o = offsets_of(*this);
  assert(i < o.end);
  if (i < o.north) return VertexRole::corner;
  if (i < o.east) return VertexRole::north;
  if (i < o.south) return VertexRole::east;
  if (i < o.west) return VertexRole::south;
  if (i < o.interior) return VertexRole::west;
  return VertexRole::interior;
}

std::vector<Vertex> TinTile::vertices() const {
  std::vector<Vertex> all;
  all.reserve(vertex_count());
  all.insert(all.end(), corners.begin(), corners.end());
  for (const auto* list : {&north, &east, &south, &west, &interior}) {
    all.insert(all.end(), list->begin(), list->end());
  }
  return all;
}

std::vector<Vertex> TinTile::border(geo::Direction side) const {
  // Corner pairs and lists per side, in edge order (see the drawing in tin_tile.hpp).
  std::size_t first = 0, last = 0;
  const std::vector<Vertex>* list = nullptr;
  switch (side) {
    case geo::Direction::north:
      first = 0, last = 1, list = &north;
      break;
    case geo::Direction::east:
      first = 1, last = 3, list = &east;
      break;
    case geo::Direction::south:
      first = 2, last = 3, list = &south;
      break;
    case geo::Direction::west:
      first = 0, last = 2, list = &west;
      break;
  }
  std::vector<Vertex> out;
  if (list == nullptr) return out;
  out.reserve(list->size() + 2);
  out.push_back(corners[first]);
  out.insert(out.end(), list->begin(), list->end());
  out.push_back(corners[last]);
  return out;
}

void TinTile::update_z_range() {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  const std::size_t n = vertex_count();
  for (std::size_t i = 0; i < n; ++i) {
    if (i < 4 && corner_nodata[i]) continue;
    const double z = vertex(i).z;
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  if (lo > hi) lo = hi = 0;  // no vertex with data
  min_z = lo;
  max_z = hi;
}

bool TinTile::is_nodata_triangle(std::size_t t) const {
  const Triangle& tri = triangles[t];
  return is_nodata_vertex(tri[0]) || is_nodata_vertex(tri[1]) || is_nodata_vertex(tri[2]);
}

std::vector<std::uint8_t> TinTile::footprint_mask() const {
  std::vector<std::uint8_t> mask(triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) mask[t] = is_nodata_triangle(t) ? 0 : 1;
  return mask;
}

bool TinTile::has_nodata_triangles() const {
  if (!corner_nodata[0] && !corner_nodata[1] && !corner_nodata[2] && !corner_nodata[3]) {
    return false;
  }
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (is_nodata_triangle(t)) return true;
  }
  return false;
}

Status check_structure(const TinTile& tile) {
  const std::string name = "tile " + tile.id.to_string();
  if (!tile.id.valid()) return invalid_argument(name + ": invalid tile id");
  const geo::MercatorRect r = tile.id.bounds();
  const Offsets o = offsets_of(tile);
  if (o.end > std::numeric_limits<std::uint32_t>::max()) {
    return invalid_argument(name + ": more vertices than 32-bit indices can address");
  }

  // Values.
  for (std::size_t i = 0; i < o.end; ++i) {
    const Vertex& v = tile.vertex(i);
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) ||
        !std::isfinite(v.weight)) {
      return invalid_argument(name + ": vertex " + std::to_string(i) + " has a non-finite value");
    }
    if (v.weight < 0) {
      return invalid_argument(name + ": vertex " + std::to_string(i) + " has a negative weight");
    }
  }
  for (double s : {tile.min_z, tile.max_z, tile.geometric_error, tile.rms_error}) {
    if (!std::isfinite(s)) return invalid_argument(name + ": non-finite statistics");
  }
  if (tile.min_z > tile.max_z) return invalid_argument(name + ": min_z > max_z");
  if (tile.geometric_error < 0 || tile.rms_error < 0) {
    return invalid_argument(name + ": negative error statistics");
  }

  // Corners: exactly at the tile corners. (A NODATA corner's height is continued from the data:
  // any finite value. Tiles written before that rule hold 0 there.)
  const std::array<std::array<double, 2>, 4> corner_xy{
      {{r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}}};
  static constexpr const char* kCornerNames[4] = {"NW", "NE", "SW", "SE"};
  for (std::size_t c = 0; c < 4; ++c) {
    const Vertex& v = tile.corners[c];
    if (v.x != corner_xy[c][0] || v.y != corner_xy[c][1]) {
      return invalid_argument(name + ": " + kCornerNames[c] + " corner at " + point_text(v) +
                              " is not the exact tile corner " +
                              point_text({corner_xy[c][0], corner_xy[c][1], 0, 0}));
    }
  }

  // Edge lists: exactly on their border, strictly inside the side, strictly ordered.
  struct Side {
    const char* label;
    const std::vector<Vertex>* list;
    bool along_x;     // the coordinate that varies along the edge is x
    double fixed;     // the exact value of the other coordinate
    bool increasing;  // edge order
  };
  const std::array<Side, 4> sides{{{"north", &tile.north, true, r.max_y, true},
                                   {"east", &tile.east, false, r.max_x, false},
                                   {"south", &tile.south, true, r.min_y, true},
                                   {"west", &tile.west, false, r.min_x, false}}};
  for (const Side& s : sides) {
    double previous = s.along_x ? r.min_x : (s.increasing ? r.min_y : r.max_y);
    const double end = s.along_x ? r.max_x : r.min_y;
    for (std::size_t i = 0; i < s.list->size(); ++i) {
      const Vertex& v = (*s.list)[i];
      const double along = s.along_x ? v.x : v.y;
      const double across = s.along_x ? v.y : v.x;
      const std::string where =
          name + ": " + s.label + " edge point " + std::to_string(i) + " " + point_text(v);
      if (across != s.fixed) return invalid_argument(where + " is not exactly on the border");
      const bool ordered = s.increasing ? along > previous : along < previous;
      if (!ordered) {
        return invalid_argument(where + (i == 0 ? " is not strictly inside the side"
                                                : " is out of order or a duplicate"));
      }
      previous = along;
    }
    if (!s.list->empty()) {
      const bool inside = s.increasing ? previous < end : previous > end;
      if (!inside) {
        return invalid_argument(name + ": last " + s.label +
                                " edge point is not strictly inside the side");
      }
    }
  }
  for (std::size_t i = 0; i < tile.interior.size(); ++i) {
    const Vertex& v = tile.interior[i];
    if (!(v.x > r.min_x && v.x < r.max_x && v.y > r.min_y && v.y < r.max_y)) {
      return invalid_argument(name + ": interior point " + std::to_string(i) + " " + point_text(v) +
                              " is not strictly inside the tile");
    }
  }

  // Triangles: indices in range, exactly counter-clockwise, areas summing to the tile's.
  if (tile.triangles.empty()) return invalid_argument(name + ": no triangles");
  // Areas from coordinate differences within the tile: such a difference is exact (Sterbenz) or,
  // for a tile touching 0, off by at most an ulp of the tile size, so the rounding of the sum is
  // relative to the tile area whatever the level.
  double area2 = 0;
  for (std::size_t t = 0; t < tile.triangles.size(); ++t) {
    const Triangle& tri = tile.triangles[t];
    for (const std::uint32_t index : tri) {
      if (index >= o.end) {
        return invalid_argument(name + ": triangle " + std::to_string(t) + " refers to vertex " +
                                std::to_string(index) + " of " + std::to_string(o.end));
      }
    }
    const Vertex& a = tile.vertex(tri[0]);
    const Vertex& b = tile.vertex(tri[1]);
    const Vertex& c = tile.vertex(tri[2]);
    if (detail::orient2d_sign(a.x, a.y, b.x, b.y, c.x, c.y) <= 0) {
      return invalid_argument(name + ": triangle " + std::to_string(t) + " (" +
                              std::to_string(tri[0]) + ", " + std::to_string(tri[1]) + ", " +
                              std::to_string(tri[2]) + ") is not counter-clockwise");
    }
    const double bx = b.x - a.x, by = b.y - a.y, cx = c.x - a.x, cy = c.y - a.y;
    area2 += bx * cy - by * cx;
  }
  const double expected = 2 * r.width() * r.height();
  const double tolerance = expected * (1e-12 + 64.0 * std::numeric_limits<double>::epsilon() *
                                                   static_cast<double>(tile.triangles.size()));
  if (std::abs(area2 - expected) > tolerance) {
    return invalid_argument(name + ": triangles cover " + fmt(area2 / expected) +
                            " of the tile area (overlaps or holes)");
  }
  return {};
}

}  // namespace tinstream::tile
