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
std::optional<Vertex> shared_corner(const std::array<std::optional<LodTile>, 4>& ch,
                                    std::initializer_list<std::pair<int, int>> where) {
  for (auto [c, k] : where) {
    const auto& t = ch[static_cast<std::size_t>(c)];
    if (!t) continue;
    if (t->tile.corner_nodata[static_cast<std::size_t>(k)]) return std::nullopt;
    return t->tile.corners[static_cast<std::size_t>(k)];
  }
  return std::nullopt;
}

void append(std::vector<Vertex>& out, const std::vector<Vertex>& in) {
  out.insert(out.end(), in.begin(), in.end());
}

// The children's points as the parent's thinning input (the merge rule of parent.hpp).
ThinInput merge_children(const geo::TileId& parent, const Children& children) {
  const auto& ch = children.tiles;
  ThinInput in;
  in.id = parent;
  const geo::MercatorRect r = parent.bounds();
  const std::array<std::array<double, 2>, 4> corner_xy = {
      {{r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}}};
  for (std::size_t k = 0; k < 4; ++k) {
    if (ch[k]) {
      in.corners[k] = ch[k]->tile.corners[k];
      in.corner_nodata[k] = ch[k]->tile.corner_nodata[k];
    } else {
      in.corners[k] = Vertex{corner_xy[k][0], corner_xy[k][1], children.absent_corner_z[k], 0.0};
      in.corner_nodata[k] = true;
    }
  }
  auto side_of = [&](int c, geo::Direction d) -> const std::vector<Vertex>* {
    const auto& t = ch[static_cast<std::size_t>(c)];
    if (!t) return nullptr;
    switch (d) {
      case geo::Direction::north:
        return &t->tile.north;
      case geo::Direction::east:
        return &t->tile.east;
      case geo::Direction::south:
        return &t->tile.south;
      case geo::Direction::west:
        return &t->tile.west;
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
    if (c) append(in.interior, c->tile.interior);
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
  return in;
}

}  // namespace

Result<LodTile> build_parent(const geo::TileId& parent, Children children,
                             const LodOptions& options, ThinStats* stats) {
  if (!parent.valid() || parent.z >= static_cast<std::uint32_t>(geo::kMaxLevel)) {
    return invalid_argument("lod: invalid parent tile " + parent.to_string());
  }
  const auto kids = parent.children();
  bool any = false;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& c = children.tiles[i];
    if (!c) continue;
    any = true;
    if (c->tile.id != kids[i]) {
      return invalid_argument("lod: child " + std::to_string(i) + " of " + parent.to_string() +
                              " is " + c->tile.id.to_string() + ", expected " +
                              kids[i].to_string());
    }
    if (!c->bounds.empty() && c->bounds.size() != c->tile.triangles.size()) {
      return invalid_argument("lod: child " + c->tile.id.to_string() + " has " +
                              std::to_string(c->bounds.size()) + " triangle bounds for " +
                              std::to_string(c->tile.triangles.size()) + " triangles");
    }
  }
  if (!any) return invalid_argument("lod: parent " + parent.to_string() + " has no children");

  ThinInput in = merge_children(parent, children);
  // The children's witnesses join the candidates only where the children's own points exceed the
  // budget: when they fit, the parent keeps them all (thin_tile drops at most the few corners it
  // adds), and a witness could only displace a child's vertex whose removal the thinning judges
  // at the known points alone, not at the finest data under it (measured on one-tile levels of a
  // 512 x 512 DEM: 1.44x the error of the level below with witnesses, bench/lod/RESULTS.md).
  const std::size_t merged = 4 + in.north.size() + in.east.size() + in.south.size() +
                             in.west.size() + in.interior.size() + in.orphans.size();
  if (merged > options.max_points) {
    for (const auto& c : children.tiles) {
      if (c) append(in.interior, c->witnesses);
    }
  }
  auto thinned = thin_tile(in, options, stats);
  if (!thinned.ok()) return thinned.error();
  LodTile out;
  out.tile = std::move(*thinned);

  // Error against the finest data (error.hpp), chained through the children's witnesses and
  // bounds; the parent's own witnesses come out of it.
  std::vector<ChainInput> finer;
  for (const auto& c : children.tiles) {
    if (!c) continue;
    out.tile.source_points += c->tile.source_points;
    finer.push_back(c->as_chain_input());
  }
  ChainedError e = chain_error(out.tile, finer, witness_count(options));
  out.tile.geometric_error = e.geometric_error;
  out.tile.rms_error = e.rms_error;
  out.bounds = std::move(e.bounds);
  out.reaches = std::move(e.reaches);
  out.witnesses = std::move(e.witnesses);
  return out;
}

Result<TinTile> build_parent(const geo::TileId& parent,
                             std::array<std::optional<TinTile>, 4> children,
                             const LodOptions& options, ThinStats* stats) {
  Children ch;
  const geo::MercatorRect r = parent.bounds();
  for (std::size_t k = 0; k < 4; ++k) {
    if (children[k]) ch.tiles[k] = LodTile{std::move(*children[k]), {}, {}, {}};
  }
  for (std::size_t k = 0; k < 4; ++k) {
    if (ch.tiles[k]) continue;
    const double x = (k & 1) ? r.max_x : r.min_x, y = (k & 2) ? r.min_y : r.max_y;
    std::optional<NearestVertex> best;
    for (const auto& c : ch.tiles) {
      if (!c) continue;
      const auto n = nearest_data_vertex(c->tile, x, y);
      if (n && (!best || n->closer_than(*best))) best = n;
    }
    ch.absent_corner_z[k] = best ? best->z : 0.0;
  }
  auto built = build_parent(parent, std::move(ch), options, stats);
  if (!built) return built.error();
  return std::move(built->tile);
}

}  // namespace tinstream::lod
