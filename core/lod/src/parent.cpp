// A parent tile from its four children and its sources (the tiles some levels below): merge
// (corners and outer border from the children, the rest from the sources, whose points on their
// inner grid lines are candidates too), thin, measure. With the children as sources:
//
//        parent                      children (quadkey digits)
//   NW ────── mN ────── NE            ┌────┬────┐
//   │          │         │            │ 0  │ 1  │     mN, mE, mS, mW: midpoints of the parent's
//   mW ─────── C ─────── mE           ├────┼────┤     sides (children's corners, kept as edge
//   │          │         │            │ 2  │ 3  │     points); C and the cross lines through it
//   SW ────── mS ────── SE            └────┴────┘     are candidates like the children's
//                                                       interior points.
#include "tinstream/lod/parent.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include "tinstream/lod/error.hpp"

namespace tinstream::lod {

using tile::TinTile;
using tile::Vertex;

namespace {

void append(std::vector<Vertex>& out, const std::vector<Vertex>& in) {
  out.insert(out.end(), in.begin(), in.end());
}

// Tiles `depth` levels under a parent as a sparse n × n grid (n = 2^depth), column i from the
// west, row j from the north.
class TileGrid {
 public:
  template <typename Tiles, typename Get>
  TileGrid(const geo::TileId& parent, std::uint32_t depth, const Tiles& tiles, Get get)
      : n_(std::uint64_t{1} << depth) {
    for (const auto& t : tiles) {
      const TinTile* tt = get(t);
      if (!tt) continue;
      const std::uint64_t i = tt->id.x - (std::uint64_t{parent.x} << depth);
      const std::uint64_t j = tt->id.y - (std::uint64_t{parent.y} << depth);
      cells_.emplace(std::pair{i, j}, tt);
    }
  }
  std::uint64_t n() const { return n_; }
  const std::map<std::pair<std::uint64_t, std::uint64_t>, const TinTile*>& cells() const {
    return cells_;
  }
  const TinTile* at(std::uint64_t i, std::uint64_t j) const {
    if (i >= n_ || j >= n_) return nullptr;  // off the grid (unsigned wrap included)
    const auto it = cells_.find({i, j});
    return it == cells_.end() ? nullptr : it->second;
  }
  // The data corner at grid vertex (gi, gj) (0 … n each way), from the first present tile of
  // those that meet there, in the order NW, NE, SW, SE of the vertex; nullopt when none is
  // present or that corner has no data.
  std::optional<Vertex> corner(std::uint64_t gi, std::uint64_t gj) const {
    const std::array<std::tuple<std::uint64_t, std::uint64_t, std::size_t>, 4> around = {
        {{gi - 1, gj - 1, 3}, {gi, gj - 1, 2}, {gi - 1, gj, 1}, {gi, gj, 0}}};
    for (const auto& [i, j, k] : around) {
      const TinTile* t = at(i, j);
      if (!t) continue;
      if (t->corner_nodata[k]) return std::nullopt;
      return t->corners[k];
    }
    return std::nullopt;
  }

  // The points of the outer side `d`, in the parent's edge order (west to east, north to
  // south): each present tile's side, with the data corners between consecutive tiles.
  std::vector<Vertex> outer_side(geo::Direction d) const {
    using D = geo::Direction;
    const bool along_x = d == D::north || d == D::south;
    const std::uint64_t fixed = (d == D::north || d == D::west) ? 0 : n_ - 1;
    const std::uint64_t vfixed = fixed == 0 ? 0 : n_;
    std::vector<std::pair<std::uint64_t, const TinTile*>> line;  // by position along the side
    for (const auto& [ij, t] : cells_) {
      const auto [i, j] = ij;
      if ((along_x ? j : i) == fixed) line.emplace_back(along_x ? i : j, t);
    }
    std::sort(line.begin(), line.end());
    auto vertex = [&](std::uint64_t s) { return along_x ? corner(s, vfixed) : corner(vfixed, s); };
    std::vector<Vertex> out;
    for (std::size_t q = 0; q < line.size(); ++q) {
      const auto [s, t] = line[q];
      const bool previous_present = q > 0 && line[q - 1].first + 1 == s;
      if (s > 0 && !previous_present) {
        if (auto c = vertex(s)) out.push_back(*c);
      }
      append(out, side(*t, d));
      if (s + 1 < n_) {
        if (auto c = vertex(s + 1)) out.push_back(*c);
      }
    }
    return out;
  }

  // outer_side for the children's grid (n = 2): where a child is absent, its stretch of side `d`
  // as `absent` has it (the side of the tile across), and the midpoint too where both children
  // along the side are absent. The parent across builds its side from its own children, which
  // are those tiles across: both get the same points (issue #20).
  std::vector<Vertex> outer_side(geo::Direction d, const AbsentBorder& absent) const {
    using D = geo::Direction;
    const bool along_x = d == D::north || d == D::south;
    const std::uint64_t fixed = (d == D::north || d == D::west) ? 0 : 1;
    const std::uint64_t vfixed = fixed == 0 ? 0 : 2;
    const auto di = static_cast<std::size_t>(d);
    const std::array<const TinTile*, 2> tiles = {along_x ? at(0, fixed) : at(fixed, 0),
                                                 along_x ? at(1, fixed) : at(fixed, 1)};
    std::vector<Vertex> out;
    append(out, tiles[0] ? side(*tiles[0], d) : absent.sides[di][0]);
    if (tiles[0] || tiles[1]) {
      if (auto c = along_x ? corner(1, vfixed) : corner(vfixed, 1)) out.push_back(*c);
    } else if (absent.midpoints[di]) {
      out.push_back(*absent.midpoints[di]);
    }
    append(out, tiles[1] ? side(*tiles[1], d) : absent.sides[di][1]);
    return out;
  }

  // The points on the inner grid lines (one copy of each shared side, then the inner grid
  // vertices): points of the finer surface inside the parent, candidates like the others.
  void inner_lines(std::vector<Vertex>& out) const {
    // (line, position along it, side): vertical lines, then horizontal ones, each in order.
    std::vector<std::tuple<std::uint64_t, std::uint64_t, const std::vector<Vertex>*>> vertical,
        horizontal;
    std::set<std::pair<std::uint64_t, std::uint64_t>> vertices;  // (gj, gi)
    for (const auto& [ij, t] : cells_) {
      const auto [i, j] = ij;
      if (i + 1 < n_) vertical.emplace_back(i + 1, j, &t->east);
      if (i > 0 && !at(i - 1, j)) vertical.emplace_back(i, j, &t->west);
      if (j + 1 < n_) horizontal.emplace_back(j + 1, i, &t->south);
      if (j > 0 && !at(i, j - 1)) horizontal.emplace_back(j, i, &t->north);
      for (std::uint64_t c = 0; c < 4; ++c) {
        const std::uint64_t gi = i + (c & 1), gj = j + (c >> 1);
        if (gi > 0 && gi < n_ && gj > 0 && gj < n_) vertices.emplace(gj, gi);
      }
    }
    std::sort(vertical.begin(), vertical.end());
    std::sort(horizontal.begin(), horizontal.end());
    for (const auto& [line, s, side_points] : vertical) append(out, *side_points);
    for (const auto& [line, s, side_points] : horizontal) append(out, *side_points);
    for (const auto& [gj, gi] : vertices) {
      if (auto c = corner(gi, gj)) out.push_back(*c);
    }
  }

 private:
  static const std::vector<Vertex>& side(const TinTile& t, geo::Direction d) {
    switch (d) {
      case geo::Direction::north:
        return t.north;
      case geo::Direction::east:
        return t.east;
      case geo::Direction::south:
        return t.south;
      case geo::Direction::west:
        break;
    }
    return t.west;
  }

  std::uint64_t n_;
  std::map<std::pair<std::uint64_t, std::uint64_t>, const TinTile*> cells_;
};

// The thinning input of a parent (the merge rule of parent.hpp): corners and outer border from
// the children, interior points and the points on their inner grid lines from the sources (and,
// for sources deeper than the children, their points on the outer border as orphans: part of the
// surface, but the border's candidates are the children's, which the neighbour shares).
ThinInput merge(const geo::TileId& parent, const ChildViews& children, const SourceViews& sources) {
  const TileGrid kids(parent, 1, children.tiles,
                      [](const LodTile* t) { return t ? &t->tile : nullptr; });
  ThinInput in;
  in.id = parent;
  const geo::MercatorRect r = parent.bounds();
  const std::array<std::array<double, 2>, 4> corner_xy = {
      {{r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}}};
  for (std::size_t k = 0; k < 4; ++k) {
    if (const auto& c = children.tiles[k]) {
      in.corners[k] = c->tile.corners[k];
      in.corner_nodata[k] = c->tile.corner_nodata[k];
    } else {
      const AbsentCorner& absent = children.absent_corners[k];
      in.corners[k] = Vertex{corner_xy[k][0], corner_xy[k][1], absent.z, 0.0};
      in.corner_nodata[k] = absent.nodata;
    }
  }
  using D = geo::Direction;
  if (children.absent_border) {
    const AbsentBorder& across = *children.absent_border;
    in.north = kids.outer_side(D::north, across);
    in.east = kids.outer_side(D::east, across);
    in.south = kids.outer_side(D::south, across);
    in.west = kids.outer_side(D::west, across);
  } else {
    in.north = kids.outer_side(D::north);
    in.east = kids.outer_side(D::east);
    in.south = kids.outer_side(D::south);
    in.west = kids.outer_side(D::west);
  }
  // The interior's size is known: reserved (with the witnesses that build_from_sources may
  // append), so that up to a million points (64 sources) are not copied by doubling.
  auto reserve = [&](const auto& tiles, std::size_t n) {
    for (const LodTile* t : tiles) {
      if (t) n += t->tile.interior.size() + t->witnesses.size();
    }
    in.interior.reserve(n);
  };
  // The inner grid lines' points are candidates: they are points of the finer surface (a finest
  // tile's side points lie on the finest TIN's edges), and on a seam where the sources' interior
  // points are sparse (their own sides carried the detail there), nothing else can bring the
  // parent close to the surface (measured: the 250 m Luxembourg DEM's level 9, 22.4 → 6.5 m,
  // bench/lod/RESULTS.md).
  std::vector<Vertex> seams;
  if (sources.depth == 1 || sources.candidates_from_children) {
    kids.inner_lines(seams);
    reserve(children.tiles, seams.size());
    for (const auto& c : children.tiles) {
      if (c) append(in.interior, c->tile.interior);
    }
    append(in.interior, seams);
    return in;
  }
  const TileGrid grid(parent, sources.depth, sources.tiles,
                      [](const LodTile* t) { return &t->tile; });
  grid.inner_lines(seams);
  reserve(sources.tiles, seams.size());
  for (const LodTile* t : sources.tiles) append(in.interior, t->tile.interior);
  append(in.interior, seams);
  for (const D d : {D::north, D::east, D::south, D::west}) append(in.orphans, grid.outer_side(d));
  return in;
}

// The area of a tile's data footprint (its triangles without a NODATA vertex), in normalised
// Mercator units.
double footprint_area(const TinTile& t) {
  double twice = 0;
  for (std::size_t k = 0; k < t.triangles.size(); ++k) {
    if (t.is_nodata_triangle(k)) continue;
    const Vertex& a = t.vertex(t.triangles[k][0]);
    const Vertex& b = t.vertex(t.triangles[k][1]);
    const Vertex& c = t.vertex(t.triangles[k][2]);
    twice += std::abs((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
  }
  return 0.5 * twice;
}

// One thinning of a parent from given candidates (merge's ThinInput) and its error chained
// through the finer tiles (build_from_sources: the setup once, an attempt or two).
struct Attempt {
  const ChildViews& children;
  const std::vector<const LodTile*>& finer;  // the tiles thinned from and measured against
  const LodOptions& thin_options;            // the parent's budget and exchange steps
  std::size_t witnesses;                     // witness_count of the caller's options
  const TieContext& ties;

  struct Thinned {
    tile::TinTile tile;  // source_points and the recorded error not yet set
    ChainedError error;
    ThinStats stats;
  };

  // `from_children`: the candidates are the children's (their witnesses join them, else the
  // finer tiles').
  Result<Thinned> thin(ThinInput in, bool from_children) const {
    // The finer tiles' witnesses join the candidates only where their own points exceed the
    // budget: when they fit, the parent keeps them all (thin_tile drops at most the few corners
    // it adds), and a witness could only displace a finer vertex whose removal the thinning
    // judges at the known points alone, not at the finest data under it (measured on one-tile
    // levels of a 512 x 512 DEM: 1.44x the error of the level below with witnesses,
    // bench/lod/RESULTS.md).
    const std::size_t merged = 4 + in.north.size() + in.east.size() + in.south.size() +
                               in.west.size() + in.interior.size() + in.orphans.size();
    if (merged > thin_options.max_points) {
      if (from_children) {
        for (const auto& c : children.tiles) {
          if (c) append(in.interior, c->witnesses);
        }
      } else {
        for (const LodTile* t : finer) append(in.interior, t->witnesses);
      }
    }
    Thinned out;
    auto thinned = thin_tile(in, thin_options, &out.stats, &ties);
    if (!thinned.ok()) return thinned.error();
    out.tile = std::move(*thinned);
    // Error against the finest data (error.hpp), chained through the finer tiles' witnesses and
    // bounds; the parent's own witnesses come out of it.
    std::vector<ChainInput> chain;
    chain.reserve(finer.size());
    for (const LodTile* t : finer) chain.push_back(t->as_chain_input());
    out.error = chain_error(out.tile, chain, witnesses);
    return out;
  }
};

}  // namespace

std::size_t coverage_budget(double covered, const LodOptions& options) {
  const std::size_t floor_points = std::min(options.max_points, outline_budget(options));
  if (!(covered < 0.25)) return options.max_points;
  const double by_area =
      std::ceil(4.0 * static_cast<double>(options.max_points) * std::max(covered, 0.0));
  return std::max(floor_points, static_cast<std::size_t>(by_area));
}

std::size_t outline_budget(const LodOptions& options) {
  return std::max<std::size_t>(
      4, static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(options.max_points)))));
}

Result<LodTile> build_from_sources(const geo::TileId& parent, const Children& children,
                                   const Sources& sources, const LodOptions& options,
                                   ThinStats* stats) {
  ChildViews child_views;
  child_views.absent_corners = children.absent_corners;
  child_views.absent_border = &children.absent_border;
  for (std::size_t k = 0; k < 4; ++k) {
    if (const auto& c = children.tiles[k]) child_views.tiles[k] = &*c;
  }
  SourceViews source_views;
  source_views.depth = sources.depth;
  source_views.candidates_from_children = sources.candidates_from_children;
  source_views.tiles.reserve(sources.tiles.size());
  for (const auto& t : sources.tiles) source_views.tiles.push_back(&t);
  return build_from_sources(parent, child_views, source_views, options, stats);
}

Result<LodTile> build_from_sources(const geo::TileId& parent, const ChildViews& children,
                                   const SourceViews& sources, const LodOptions& options,
                                   ThinStats* stats) {
  if (!parent.valid() || parent.z >= static_cast<std::uint32_t>(geo::kMaxLevel) ||
      sources.depth < 1 || sources.depth > geo::kMaxLevel - parent.z) {
    return invalid_argument("lod: invalid parent tile " + parent.to_string() + " or source depth " +
                            std::to_string(sources.depth));
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
  }
  if (!any) return invalid_argument("lod: parent " + parent.to_string() + " has no children");
  if (sources.depth > 1 && sources.tiles.empty()) {
    return invalid_argument("lod: parent " + parent.to_string() + " has no source tiles");
  }
  std::set<geo::TileId> seen;
  for (const LodTile* t : sources.tiles) {
    if (!t) return invalid_argument("lod: parent " + parent.to_string() + " has a null source");
    const geo::TileId& id = t->tile.id;
    if (sources.depth == 1 || id.z != parent.z + sources.depth ||
        (id.x >> sources.depth) != parent.x || (id.y >> sources.depth) != parent.y) {
      return invalid_argument("lod: tile " + id.to_string() + " is not a source of " +
                              parent.to_string() + " at depth " + std::to_string(sources.depth));
    }
    if (!seen.insert(id).second) {
      return invalid_argument("lod: source tile " + id.to_string() + " given twice");
    }
  }
  // The tiles the parent is thinned from and measured against.
  std::vector<const LodTile*> finer;
  if (sources.depth == 1) {
    for (const auto& c : children.tiles) {
      if (c) finer.push_back(c);
    }
  } else {
    finer = sources.tiles;
  }
  for (const LodTile* t : finer) {
    if (!t->bounds.empty() && t->bounds.size() != t->tile.triangles.size()) {
      return invalid_argument("lod: tile " + t->tile.id.to_string() + " has " +
                              std::to_string(t->bounds.size()) + " triangle bounds for " +
                              std::to_string(t->tile.triangles.size()) + " triangles");
    }
  }

  // The parent's budget (parent.hpp, "Budget"): 4 × max_points times the share of the parent
  // that its children's data footprints cover, at least the outline budget, plus the border
  // points, whose per-side budget stays that of max_points (the neighbours share it). The border
  // comes from the children whatever the candidates are (merge), so one merge sizes it.
  ThinInput in = merge(parent, children, sources);
  double covered = 0;
  for (const LodTile* c : children.tiles) {
    if (c) covered += footprint_area(c->tile);
  }
  const geo::MercatorRect pr = parent.bounds();
  covered /= (pr.max_x - pr.min_x) * (pr.max_y - pr.min_y);
  LodOptions thin_options = options;
  thin_options.border_points_per_side = side_budget(options);
  std::size_t border = 0;
  for (const auto* side : {&in.north, &in.east, &in.south, &in.west}) {
    border += std::min(side->size(), thin_options.border_points_per_side);
  }
  thin_options.max_points =
      std::min(options.max_points, coverage_budget(covered, options) + border);
  // At the outline floor (the budget no longer follows the area), exchange steps after the drop
  // stage, as many as the floor has vertices: there the greedy stage's last error is the tile's
  // (bench/lod/RESULTS.md 2026-11-28, "exchange steps at the outline floor").
  const std::size_t floor_points = std::min(options.max_points, outline_budget(options));
  if (coverage_budget(covered, options) <= floor_points && floor_points < options.max_points) {
    thin_options.exchange_steps = floor_points;
  }
  // Cocircular quadrilaterals (a grid's cells) take the diagonal the finer tiles' vertices
  // favour, else the one a finer tile or child drew (they saw more of the data).
  TieContext ties;
  for (const LodTile* t : finer) {
    ties.drawn.push_back(&t->tile);
    for (const auto* list :
         {&t->tile.interior, &t->tile.north, &t->tile.east, &t->tile.south, &t->tile.west}) {
      ties.known.emplace_back(*list);
    }
  }
  if (sources.depth > 1) {
    for (const auto& c : children.tiles) {
      if (c) ties.drawn.push_back(&c->tile);
    }
  }
  // The largest error of the finer tiles (and children), which the parent records at least.
  double finer_error = 0;
  for (const LodTile* t : finer) finer_error = std::max(finer_error, t->tile.geometric_error);
  for (const auto& c : children.tiles) {
    if (c) finer_error = std::max(finer_error, c->tile.geometric_error);
  }
  const Attempt attempt{children, finer, thin_options, witness_count(options), ties};

  // A parent that takes its one child's vertices as candidates (Sources::candidates_from_children)
  // but keeps fewer than they are is thinned from its sources instead: dropping a thinned child's
  // vertices judges each removal at the known points only (measured: Terrain-RGB's level 13, 15
  // vertices fewer than its child, 0.60 → 2.06 m, 2.9× Delatin's error; bench/lod/RESULTS.md).
  const bool from_children = sources.candidates_from_children &&
                             thin_options.max_points >= 4 + in.north.size() + in.east.size() +
                                                            in.south.size() + in.west.size() +
                                                            in.interior.size();
  SourceViews own = sources;
  own.candidates_from_children = false;
  // (Without candidates_from_children, `in` already holds the sources' candidates.)
  const bool keep_in = from_children || !sources.candidates_from_children;
  auto kept = attempt.thin(keep_in ? std::move(in) : merge(parent, children, own), from_children);
  if (!kept.ok()) return kept.error();
  // A parent that keeps its one child's vertices but measures worse than the child is thinned
  // from its sources instead (the better of the two stays): its corners lie farther out than the
  // child's, so its Delaunay triangulation can join three nearly collinear vertices of the data's
  // outline into a flat data triangle where the child had a NODATA fan, and the data's edge
  // points under that triangle's long side measure its chord (measured: nm_4_6_crop.las's levels
  // 10-0, 0.198 -> 0.575 m; bench/lod/RESULTS.md 2026-11-28 15:00). Only the kept attempt's
  // thinning counters reach `stats`. An excess within rounding (kRethinNoise) is none: the chained
  // error of the child's vertices, summed again through a different triangulation, can come out
  // an ulp or two above the child's (Luxembourg at 2048, tile 4/8/5: 134.51196204836035 against
  // 134.51196204836029 m); the parent records at least the finer error, so a re-thinned tile
  // could record less by that rounding at most (bench/lod/RESULTS.md 2026-11-28 17:17).
  constexpr double kRethinNoise = 1e-9;  // relative to the finer error
  if (from_children && kept->error.geometric_error > finer_error * (1 + kRethinNoise)) {
    auto again = attempt.thin(merge(parent, children, own), false);
    if (!again.ok()) return again.error();
    if (std::max(again->error.geometric_error, finer_error) <
        std::max(kept->error.geometric_error, finer_error)) {
      kept = std::move(again);
    }
  }
  if (stats) *stats = kept->stats;
  LodTile out;
  out.tile = std::move(kept->tile);
  for (const LodTile* t : finer) out.tile.source_points += t->tile.source_points;
  // Monotone up the pyramid (a client refines while a tile's error is too large, so a parent's
  // must not promise less than a child's): the chained bound, an upper bound of the parent's error
  // over the data, can come out below a child's (or a source's) looser one; the larger still
  // bounds it.
  ChainedError& e = kept->error;
  out.tile.geometric_error = std::max(e.geometric_error, finer_error);
  out.tile.rms_error = e.rms_error;
  out.bounds = std::move(e.bounds);
  out.reaches = std::move(e.reaches);
  out.witnesses = std::move(e.witnesses);
  return out;
}

Result<LodTile> build_parent(const geo::TileId& parent, const Children& children,
                             const LodOptions& options, ThinStats* stats) {
  return build_from_sources(parent, children, Sources{}, options, stats);
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
    ch.absent_corners[k].z = best ? best->z : 0.0;
  }
  auto built = build_parent(parent, ch, options, stats);
  if (!built) return built.error();
  return std::move(built->tile);
}

}  // namespace tinstream::lod
