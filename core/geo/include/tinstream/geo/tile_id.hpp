// tinstream/geo/tile_id.hpp — the global Mercator quadtree (docs/DESIGN.md §2).
//
// Level z, column x (west → east), row y (north → south), as Bing/XYZ. Tile (z, x, y) covers
//   x ∈ [-1 + 2x/2^z, -1 + 2(x+1)/2^z],   y ∈ [1 − 2(y+1)/2^z, 1 − 2y/2^z]   (normalised Mercator)
// Every bound is a dyadic rational and exactly representable as a double for z ≤ kMaxLevel.
//
// Quadkey: z digits, digit = 2·ybit + xbit, most significant level first, Bing-compatible:
//   ""  = the world (z = 0)        "0" NW   "1" NE
//                                  "2" SW   "3" SE
// Morton order = pre-order of the quadtree = lexicographic order of quadkeys: a parent comes
// before its children, children in digit order. `morton_less` implements it for mixed levels.
//
// Cesium/TMS count rows from the south: y_tms = 2^z − 1 − y (`tms_row`).
#pragma once

#include <array>
#include <compare>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"

namespace tinstream::geo {

inline constexpr int kMaxLevel = 30;

// An axis-aligned rectangle in normalised Mercator.
struct MercatorRect {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;
  bool contains(MercatorXY p) const {  // closed rectangle
    return p.x >= min_x && p.x <= max_x && p.y >= min_y && p.y <= max_y;
  }
  double width() const { return max_x - min_x; }
  double height() const { return max_y - min_y; }
  // Open rectangles overlap: two that only touch along a side or at a corner do not.
  bool overlaps(const MercatorRect& o) const {
    return min_x < o.max_x && o.min_x < max_x && min_y < o.max_y && o.min_y < max_y;
  }
};

// A rectangle in geodetic degrees (west/south/east/north).
struct LonLatRect {
  double west = 0, south = 0, east = 0, north = 0;
};

enum class Direction : std::uint8_t { north = 0, east = 1, south = 2, west = 3 };

struct TileId {
  std::uint32_t z = 0;
  std::uint32_t x = 0;
  std::uint32_t y = 0;

  // clang-tidy 14 reads the comparison category's literal 0 in a defaulted <=> as a null pointer.
  // NOLINTNEXTLINE(modernize-use-nullptr)
  friend auto operator<=>(const TileId&, const TileId&) = default;

  // Requires for all members below: valid().
  bool valid() const;
  std::uint32_t tiles_per_side() const { return 1u << z; }

  MercatorRect bounds() const;
  LonLatRect lonlat_bounds(const NormalisedMercator& projection) const;

  // Requires z > 0.
  TileId parent() const;
  // Requires z < kMaxLevel. Order: NW, NE, SW, SE (quadkey digits 0..3).
  std::array<TileId, 4> children() const;
  // The quadkey digit of this tile within its parent (0..3). Requires z > 0.
  int child_index() const;
  // Same-level neighbour. East/west wrap around the antimeridian (for z > 0); north/south do not
  // (nullopt at the poles' edge of the map).
  std::optional<TileId> neighbour(Direction d) const;

  std::uint32_t tms_row() const { return tiles_per_side() - 1 - y; }
  // Interleaved bits of x and y (y bit above x bit, as quadkey digits); unique within a level.
  std::uint64_t morton() const;
  std::string quadkey() const;
  std::string to_string() const;  // "z/x/y"

  static Result<TileId> from_quadkey(std::string_view quadkey);
  // Validated constructor from level, column and row.
  static Result<TileId> from_zxy(std::int64_t z, std::int64_t x, std::int64_t y);
  // From TMS row numbering (Cesium).
  static Result<TileId> from_tms(std::int64_t z, std::int64_t x, std::int64_t y_tms);
  // The tile at level z containing p. Tiles are half-open [min, max) in x and (min, max] in y
  // (i.e. a point on a shared border belongs to the tile east of it / south of it), except at the
  // map's east and south edges, which belong to the last column/row. Points outside [-1, 1]² are
  // clamped. Exact: decided by comparisons against the exact tile bounds.
  static TileId containing(MercatorXY p, std::uint32_t z);
};

// Pre-order (quadkey-lexicographic) comparison across levels.
bool morton_less(const TileId& a, const TileId& b);

// Exact bound of column/row index i at level z in normalised Mercator.
double tile_x_edge(std::uint32_t z, std::uint32_t column);  // west edge of column
double tile_y_edge(std::uint32_t z, std::uint32_t row);     // north edge of row

}  // namespace tinstream::geo
