#include "tinstream/client/skirts.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>

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

}  // namespace

void plan_skirts(std::vector<DrawItem>& draws) {
  for (DrawItem& t : draws) {
    t.skirt_sides = 0;
    double deepest_error = 0, lowest = std::numeric_limits<double>::infinity();
    for (const DrawItem& n : draws) {
      if (n.key.layer != t.key.layer || n.key.kind != t.key.kind || n.key.tile.z == t.key.tile.z ||
          n.quadrant_mask == 0)
        continue;
      bool met = false;
      for (std::size_t s = 0; s < 4; ++s)
        if (touches(t.key.tile, s, n.key.tile, n.quadrant_mask)) {
          t.skirt_sides = static_cast<std::uint8_t>(t.skirt_sides | (1u << s));
          met = true;
        }
      if (!met) continue;
      deepest_error = std::max(deepest_error, n.tile->geometric_error);
      lowest = std::min(lowest, n.tile->min_z);
    }
    if (t.skirt_sides == 0) {
      t.skirt_depth = t.skirt_floor = 0;
      continue;
    }
    const ResidentTile& r = *t.tile;
    t.skirt_depth = r.geometric_error + deepest_error + r.skirt_margin;
    t.skirt_floor = std::max(lowest - r.skirt_margin, r.skirt_lowest);
  }
}

}  // namespace tinstream::client
