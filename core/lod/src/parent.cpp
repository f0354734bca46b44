// A parent tile from its four children: merge (drop the internal cross), thin, measure.
//
//        parent                      children (quadkey digits)
//   NW ────── mN ────── NE            ┌────┬────┐
//   │          │         │            │ 0  │ 1  │     mN, mE, mS, mW: midpoints of the parent's
//   mW ─────── C ─────── mE           ├────┼────┤     sides (children's corners, kept as edge
//   │          │         │            │ 2  │ 3  │     points); C and the cross lines through it
//   SW ────── mS ────── SE            └────┴────┘     are cut artefacts (orphans only).
#include "tinstream/lod/parent.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "tinstream/lod/error.hpp"

namespace tinstream::lod {

using tile::TinTile;
using tile::Vertex;

namespace {

// The corner shared by the children listed as (child, corner) pairs, from the first child present.
// nullopt when none is present or that corner has no data.
std::optional<Vertex> shared_corner(const std::array<std::optional<TinTile>, 4>& ch,
                                    std::initializer_list<std::pair<int, int>> where) {
  for (auto [c, k] : where) {
    const auto& t = ch[static_cast<std::size_t>(c)];
    if (!t) continue;
    if (t->corner_nodata[static_cast<std::size_t>(k)]) return std::nullopt;
    return t->corners[static_cast<std::size_t>(k)];
  }
  return std::nullopt;
}

void append(std::vector<Vertex>& out, const std::vector<Vertex>& in) {
  out.insert(out.end(), in.begin(), in.end());
}

}  // namespace

double nodata_band_bound(const TinTile& tile, const HeightRange& finest) {
  if (!finest.known() || !(tile.min_z <= tile.max_z)) return 0.0;
  return std::max({0.0, tile.max_z - finest.min, finest.max - tile.min_z});
}

namespace {

bool has_nodata_triangles(const TinTile& t) {
  for (const auto& tr : t.triangles) {
    for (auto v : tr) {
      if (v < 4 && t.corner_nodata[v]) return true;
    }
  }
  return false;
}

}  // namespace

Result<TinTile> build_parent(const geo::TileId& parent, std::array<std::optional<TinTile>, 4> ch,
                             const LodOptions& options, ThinStats* stats,
                             const HeightRange& finest) {
  if (!parent.valid() || parent.z >= static_cast<std::uint32_t>(geo::kMaxLevel)) {
    return invalid_argument("lod: invalid parent tile " + parent.to_string());
  }
  const auto kids = parent.children();
  bool any = false;
  for (std::size_t i = 0; i < 4; ++i) {
    if (!ch[i]) continue;
    any = true;
    if (ch[i]->id != kids[i]) {
      return invalid_argument("lod: child " + std::to_string(i) + " of " + parent.to_string() +
                              " is " + ch[i]->id.to_string() + ", expected " + kids[i].to_string());
    }
  }
  if (!any) return invalid_argument("lod: parent " + parent.to_string() + " has no children");

  ThinInput in;
  in.id = parent;
  const geo::MercatorRect r = parent.bounds();
  const std::array<std::array<double, 2>, 4> corner_xy = {
      {{r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}}};
  for (std::size_t k = 0; k < 4; ++k) {
    if (ch[k]) {
      in.corners[k] = ch[k]->corners[k];
      in.corner_nodata[k] = ch[k]->corner_nodata[k];
    } else {
      in.corners[k] = Vertex{corner_xy[k][0], corner_xy[k][1], 0.0, 0.0};
      in.corner_nodata[k] = true;
    }
  }
  auto side_of = [&](int c, geo::Direction d) -> const std::vector<Vertex>* {
    const auto& t = ch[static_cast<std::size_t>(c)];
    if (!t) return nullptr;
    switch (d) {
      case geo::Direction::north:
        return &t->north;
      case geo::Direction::east:
        return &t->east;
      case geo::Direction::south:
        return &t->south;
      case geo::Direction::west:
        return &t->west;
    }
    return nullptr;
  };
  using D = geo::Direction;
  // Outer border: first half, midpoint, second half, in the parent's edge order.
  auto outer = [&](std::vector<Vertex>& list, int c0, int c1, D d, std::optional<Vertex> mid) {
    if (const auto* s = side_of(c0, d)) append(list, *s);
    if (mid) list.push_back(*mid);
    if (const auto* s = side_of(c1, d)) append(list, *s);
  };
  outer(in.north, 0, 1, D::north, shared_corner(ch, {{0, 1}, {1, 0}}));
  outer(in.east, 1, 3, D::east, shared_corner(ch, {{1, 3}, {3, 1}}));
  outer(in.south, 2, 3, D::south, shared_corner(ch, {{2, 3}, {3, 2}}));
  outer(in.west, 0, 2, D::west, shared_corner(ch, {{0, 2}, {2, 0}}));
  for (const auto& c : ch) {
    if (c) append(in.interior, c->interior);
  }
  // The internal cross: one copy of each shared child side, and the centre.
  auto cross = [&](int a, D da, int b, D db) {
    if (const auto* s = side_of(a, da)) {
      append(in.orphans, *s);
    } else if (const auto* t = side_of(b, db)) {
      append(in.orphans, *t);
    }
  };
  cross(0, D::east, 1, D::west);
  cross(2, D::east, 3, D::west);
  cross(0, D::south, 2, D::north);
  cross(1, D::south, 3, D::north);
  if (auto c = shared_corner(ch, {{0, 3}, {1, 2}, {2, 1}, {3, 0}})) in.orphans.push_back(*c);

  auto thinned = thin_tile(in, options, stats);
  if (!thinned.ok()) return thinned.error();
  TinTile out = std::move(*thinned);

  // Error against the finest surface (parent.hpp).
  std::vector<const TinTile*> present;
  for (const auto& c : ch) {
    if (c) present.push_back(&*c);
  }
  const std::vector<SurfaceDifference> diffs = surface_differences(out, present);
  SurfaceDifference total;
  double child_max = 0, child_sq_area = 0, child_area = 0;
  for (std::size_t i = 0; i < present.size(); ++i) {
    const TinTile& c = *present[i];
    const SurfaceDifference& d = diffs[i];
    total.max_abs = std::max(total.max_abs, d.max_abs);
    total.sum_sq_area += d.sum_sq_area;
    total.area += d.area;
    total.crossings += d.crossings;
    child_max = std::max(child_max, c.geometric_error);
    child_sq_area += d.area * c.rms_error * c.rms_error;
    child_area += d.area;
    out.source_points += c.source_points;
  }
  out.geometric_error = total.max_abs + child_max + error_rounding_allowance(out);
  for (const TinTile* c : present) {
    if (has_nodata_triangles(*c)) {
      out.geometric_error = std::max(
          out.geometric_error, nodata_band_bound(out, finest) + error_rounding_allowance(out));
      break;
    }
  }
  const double child_rms = child_area > 0 ? std::sqrt(child_sq_area / child_area) : 0.0;
  out.rms_error = total.rms() + child_rms;
  return out;
}

}  // namespace tinstream::lod
