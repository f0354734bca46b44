#include "tinstream/client/skirts.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <utility>

namespace tinstream::client {

namespace {

struct Cell {
  std::uint32_t z;
  std::uint64_t x, y;
};

Cell ancestor(const Cell& c, std::uint32_t level) {
  const std::uint32_t d = c.z - level;
  return {level, c.x >> d, c.y >> d};
}

// T's same-level neighbour across `side`, wrapping east–west; false beyond a pole row.
bool across(const geo::TileId& t, std::size_t side, Cell& out) {
  const std::uint64_t n = std::uint64_t{1} << t.z;
  out = {t.z, t.x, t.y};
  switch (side) {
    case 0:
      if (t.y == 0) return false;
      --out.y;
      return true;
    case 1:
      out.x = (out.x + 1) % n;
      return true;
    case 2:
      if (t.y + 1 >= n) return false;
      ++out.y;
      return true;
    default:
      out.x = (out.x + n - 1) % n;
      return true;
  }
}

// Quadkey digit of `c` in its parent: 0 NW, 1 NE, 2 SW, 3 SE.
unsigned digit(const Cell& c) { return static_cast<unsigned>((c.x & 1) | ((c.y & 1) << 1)); }

// Whether drawn tile `n` (another level than `t`) meets side `side` of `t` with a drawn part.
bool touches(const geo::TileId& t, std::size_t side, const geo::TileId& n, std::uint8_t mask) {
  Cell a;
  if (!across(t, side, a)) return false;
  if (n.z < t.z) {  // coarser: n holds a, and its quadrant there is drawn
    const Cell up = ancestor(a, n.z);
    if (up.x != n.x || up.y != n.y) return false;
    return (mask >> digit(ancestor(a, n.z + 1))) & 1u;
  }
  // Finer: n lies in a, along the edge a shares with t, and its quadrants facing t are drawn.
  const Cell cn{n.z, n.x, n.y};
  const Cell up = ancestor(cn, t.z);
  if (up.x != a.x || up.y != a.y) return false;
  const std::uint32_t d = n.z - t.z;
  const std::uint64_t last = (std::uint64_t{1} << d) - 1;  // a's last row/column at n's level
  static constexpr std::array<std::uint8_t, 4> kFacing{0b1100, 0b0101, 0b0011, 0b1010};
  const bool on_edge = side == 0   ? (cn.y & last) == last
                       : side == 1 ? (cn.x & last) == 0
                       : side == 2 ? (cn.y & last) == 0
                                   : (cn.x & last) == last;
  return on_edge && (mask & kFacing[side]) != 0;
}

// The drawn stretch of side `side` of tile n under `mask`, along the side's coordinate (x for
// north and south, y for east and west): each half of the side belongs to one quadrant.
std::array<SkirtSpan, 2> drawn_halves(const geo::TileId& n, std::size_t side, std::uint8_t mask) {
  const geo::MercatorRect r = n.bounds();
  const bool along_x = side == 0 || side == 2;
  const double lo = along_x ? r.min_x : r.min_y, hi = along_x ? r.max_x : r.max_y,
               mid = (lo + hi) / 2;
  // The quadrant digits of the low and the high half of each side.
  static constexpr std::array<std::array<unsigned, 2>, 4> kHalves{{{0, 1}, {3, 1}, {2, 3}, {2, 0}}};
  const auto& [low, high] = kHalves[side];
  return {((mask >> low) & 1u) ? SkirtSpan{lo, mid} : SkirtSpan{mid, mid},
          ((mask >> high) & 1u) ? SkirtSpan{mid, hi} : SkirtSpan{hi, hi}};
}

// Where N's skirt quads of group g (skirts: 0–3 the sides, 4–7 the cuts) begin and end.
std::pair<std::uint32_t, std::uint32_t> group_range(const ResidentTile& r, std::size_t g) {
  std::uint32_t first = 0;
  for (std::size_t i = 0; i < g; ++i)
    first += (i < 4 ? r.gpu.skirt_index_count[i] : r.gpu.cut_index_count[i - 4]) / 6;
  const std::uint32_t count =
      (g < 4 ? r.gpu.skirt_index_count[g] : r.gpu.cut_index_count[g - 4]) / 6;
  return {first, first + count};
}

// The group of N's skirt quads along the line that side `side` of T shares with N (touches()
// holds): N's opposite side, or, where N holds T (a parent drawn beside its child), the cut of N
// that the line lies on.
std::size_t facing_group(const geo::TileId& t, std::size_t side, const geo::TileId& n) {
  const Cell ct{t.z, t.x, t.y};
  if (n.z < t.z) {
    const Cell up = ancestor(ct, n.z);
    if (up.x == n.x && up.y == n.y) {
      const Cell q = ancestor(ct, n.z + 1);
      return side == 1 || side == 3 ? 4 + ((q.y & 1) ? 1 : 0) : 4 + ((q.x & 1) ? 3 : 2);
    }
  }
  return (side + 2) % 4;
}

// What N draws along group g: the spans of its skirt quads there (its data's border segments, or
// its surface's cross-section along a cut), a side's clipped to the quadrants N draws, merged and
// sorted, into `out` (a scratch vector the caller reuses: no allocation per pair and frame).
void data_along(const DrawItem& n, std::size_t g, std::vector<SkirtSpan>& out) {
  out.clear();
  const ResidentTile& r = *n.tile;
  const auto [first, end] = group_range(r, g);
  if (end > r.skirt_spans.size()) return;
  const std::array<SkirtSpan, 2> halves =
      g < 4 ? drawn_halves(n.key.tile, g, n.quadrant_mask)
            : std::array<SkirtSpan, 2>{SkirtSpan{-4, 4}, SkirtSpan{4, 4}};
  for (const SkirtSpan& half : halves)
    for (std::uint32_t i = first; i < end; ++i) {
      const double lo = std::max(half.lo, r.skirt_spans[i].lo),
                   hi = std::min(half.hi, r.skirt_spans[i].hi);
      if (lo < hi) out.push_back({lo, hi});
    }
  std::sort(out.begin(), out.end(),
            [](const SkirtSpan& a, const SkirtSpan& b) { return a.lo < b.lo; });
  std::size_t kept = 0;  // merged in place
  for (const SkirtSpan& s : out)
    if (kept > 0 && s.lo <= out[kept - 1].hi) {
      out[kept - 1].hi = std::max(out[kept - 1].hi, s.hi);
    } else {
      out[kept++] = s;
    }
  out.resize(kept);
}

// Marks the quads [first, end) of `spans` that overlap `data` (sorted, disjoint) over
// a positive length; whether any was.
bool mark_overlaps(const std::vector<SkirtSpan>& spans, std::uint32_t first, std::uint32_t end,
                   const std::vector<SkirtSpan>& data, std::vector<std::uint8_t>& hung) {
  bool any = false;
  for (std::uint32_t q = first; q < end && q < spans.size(); ++q) {
    const SkirtSpan& s = spans[q];
    // The first data span that ends after s begins; it overlaps s when it begins before s ends.
    const auto it = std::upper_bound(data.begin(), data.end(), s.lo,
                                     [](double v, const SkirtSpan& d) { return v < d.hi; });
    if (it != data.end() && it->lo < s.hi) {
      hung[q] = 1;
      any = true;
    }
  }
  return any;
}

// The cut c (Cut) between two quadrants a and b, and the side of a's cell that faces b's (b's
// faces back across the opposite side).
constexpr std::array<unsigned, 4> kCutA{0, 2, 0, 1};
constexpr std::array<unsigned, 4> kCutB{1, 3, 2, 3};
constexpr std::array<std::size_t, 4> kCutSideOfA{1, 1, 2, 2};

}  // namespace

void plan_skirts(std::vector<DrawItem>& draws) {
  std::vector<std::uint8_t> hung;
  std::vector<SkirtSpan> data;  // data_along's
  for (DrawItem& t : draws) {
    t.skirt_sides = 0;
    t.skirt_runs.clear();
    const ResidentTile& r = *t.tile;
    std::array<std::uint32_t, 9> group_first{};  // quad index where each group starts
    for (std::size_t g = 0; g < 8; ++g) group_first[g + 1] = group_range(r, g).second;
    hung.assign(group_first[8], 0);
    // Cuts this frame: the tile draws exactly one of the cut's two quadrants; the cell of the
    // drawn one and its side facing the other stand in for a tile and its side.
    std::array<geo::TileId, 4> cut_cell{};
    std::array<std::size_t, 4> cut_side{};
    std::array<bool, 4> cut_active{};
    const unsigned mask = t.quadrant_mask;
    for (std::size_t c = 0; c < 4; ++c) {
      const unsigned qa = kCutA[c], qb = kCutB[c];
      // Unsigned, not bool: GCC 12.2 -O2 miscompiled the bool form of this loop when it stored
      // std::optional<std::pair<TileId, size_t>> per cut (mask 0b0011 gave cut 0 only; -O0,
      // clang and -fsanitize=undefined right). Skirts.AParentDrawnInSomeQuadrants… catches it.
      const unsigned da = (mask >> qa) & 1u, db = (mask >> qb) & 1u;
      if (da == db) continue;
      const unsigned q = da != 0 ? qa : qb;
      const geo::TileId& id = t.key.tile;
      cut_cell[c] = geo::TileId{id.z + 1, 2 * id.x + (q & 1u), 2 * id.y + (q >> 1)};
      cut_side[c] = da != 0 ? kCutSideOfA[c] : (kCutSideOfA[c] + 2) % 4;
      cut_active[c] = true;
    }
    double deepest_error = 0, lowest = std::numeric_limits<double>::infinity();
    for (const DrawItem& n : draws) {
      if (n.key.layer != t.key.layer || n.key.kind != t.key.kind || n.key.tile.z == t.key.tile.z ||
          n.quadrant_mask == 0)
        continue;
      bool met = false;
      const auto hang = [&](const geo::TileId& id, std::size_t side, std::size_t group) {
        if (!touches(id, side, n.key.tile, n.quadrant_mask)) return;
        data_along(n, facing_group(id, side, n.key.tile), data);
        if (mark_overlaps(r.skirt_spans, group_first[group], group_first[group + 1], data, hung)) {
          t.skirt_sides = static_cast<std::uint8_t>(t.skirt_sides | (1u << group));
          met = true;
        }
      };
      for (std::size_t s = 0; s < 4; ++s) hang(t.key.tile, s, s);
      if (n.key.tile.z > t.key.tile.z)
        for (std::size_t c = 0; c < 4; ++c)
          if (cut_active[c]) hang(cut_cell[c], cut_side[c], 4 + c);
      if (!met) continue;
      deepest_error = std::max(deepest_error, n.tile->geometric_error);
      lowest = std::min(lowest, n.tile->min_z);
    }
    if (t.skirt_sides == 0) {
      t.skirt_depth = t.skirt_floor = 0;
      continue;
    }
    // Runs of hung quads; a run never mixes side and cut quads (the renderer draws cuts unmasked).
    for (std::uint32_t q = 0; q < hung.size(); ++q) {
      if (!hung[q]) continue;
      if (!t.skirt_runs.empty() && t.skirt_runs.back()[0] + t.skirt_runs.back()[1] == q &&
          q != group_first[4])
        ++t.skirt_runs.back()[1];
      else
        t.skirt_runs.push_back({q, 1});
    }
    t.skirt_depth = r.geometric_error + deepest_error + r.skirt_margin;
    t.skirt_floor = std::max(lowest - r.skirt_margin, r.skirt_lowest);
  }
}

}  // namespace tinstream::client
