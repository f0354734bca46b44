#include "tinstream/geo/tile_id.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace tinstream::geo {

namespace {

// 2^(1 − z) for a level z < 1024 (tiles and their halo cells), built from its exponent bits: a
// column times it is the same double std::ldexp gives (a power of two only moves the exponent, and
// nothing overflows or underflows here), without ldexp's call, which the halo's cell scans and
// TileId::containing make millions of times an ingest (bench/lod, s34-cpu's 1024 profile: ~5 %).
double tile_scale(std::uint32_t z) {
  return std::bit_cast<double>(static_cast<std::uint64_t>(1023 + 1 - static_cast<int>(z)) << 52);
}

}  // namespace

double tile_x_edge(std::uint32_t z, std::uint32_t column) {
  // -1 + 2·column/2^z: both terms are dyadic with ≤ 31 significant bits, the sum is exact.
  return -1.0 + static_cast<double>(column) * tile_scale(z);
}

double tile_y_edge(std::uint32_t z, std::uint32_t row) {
  return 1.0 - static_cast<double>(row) * tile_scale(z);
}

bool TileId::valid() const {
  return z <= static_cast<std::uint32_t>(kMaxLevel) && x < (std::uint64_t{1} << z) &&
         y < (std::uint64_t{1} << z);
}

MercatorRect TileId::bounds() const {
  return {tile_x_edge(z, x), tile_y_edge(z, y + 1), tile_x_edge(z, x + 1), tile_y_edge(z, y)};
}

LonLatRect TileId::lonlat_bounds(const NormalisedMercator& projection) const {
  const MercatorRect r = bounds();
  return {NormalisedMercator::lon_from_x(r.min_x), projection.lat_from_y(r.min_y),
          NormalisedMercator::lon_from_x(r.max_x), projection.lat_from_y(r.max_y)};
}

TileId TileId::parent() const {
  assert(z > 0);
  return {z - 1, x >> 1, y >> 1};
}

std::array<TileId, 4> TileId::children() const {
  assert(z < static_cast<std::uint32_t>(kMaxLevel));
  const std::uint32_t cx = x << 1, cy = y << 1;
  return {TileId{z + 1, cx, cy}, TileId{z + 1, cx + 1, cy}, TileId{z + 1, cx, cy + 1},
          TileId{z + 1, cx + 1, cy + 1}};
}

int TileId::child_index() const {
  assert(z > 0);
  return static_cast<int>(((y & 1u) << 1) | (x & 1u));
}

std::optional<TileId> TileId::neighbour(Direction d) const {
  if (z == 0) return std::nullopt;
  const std::uint32_t n = tiles_per_side();
  switch (d) {
    case Direction::north:
      if (y == 0) return std::nullopt;
      return TileId{z, x, y - 1};
    case Direction::south:
      if (y + 1 == n) return std::nullopt;
      return TileId{z, x, y + 1};
    case Direction::east:
      return TileId{z, (x + 1) % n, y};
    case Direction::west:
      return TileId{z, (x + n - 1) % n, y};
  }
  return std::nullopt;
}

std::uint64_t TileId::morton() const {
  std::uint64_t code = 0;
  for (std::uint32_t bit = 0; bit < z; ++bit) {
    code |= static_cast<std::uint64_t>((x >> bit) & 1u) << (2 * bit);
    code |= static_cast<std::uint64_t>((y >> bit) & 1u) << (2 * bit + 1);
  }
  return code;
}

std::string TileId::quadkey() const {
  std::string key(z, '0');
  for (std::uint32_t i = 0; i < z; ++i) {
    const std::uint32_t bit = z - 1 - i;
    key[i] = static_cast<char>('0' + (((y >> bit) & 1u) << 1 | ((x >> bit) & 1u)));
  }
  return key;
}

std::string TileId::to_string() const {
  return std::to_string(z) + "/" + std::to_string(x) + "/" + std::to_string(y);
}

Result<TileId> TileId::from_quadkey(std::string_view quadkey) {
  if (quadkey.size() > static_cast<std::size_t>(kMaxLevel)) {
    return invalid_argument("quadkey of " + std::to_string(quadkey.size()) +
                            " digits is deeper than the maximum level " +
                            std::to_string(kMaxLevel));
  }
  TileId t{static_cast<std::uint32_t>(quadkey.size()), 0, 0};
  for (std::size_t i = 0; i < quadkey.size(); ++i) {
    const char c = quadkey[i];
    if (c < '0' || c > '3') {
      std::string shown;
      if (c >= 0x20 && c < 0x7f) {
        shown = std::string("'") + c + "'";
      } else {
        shown = "byte " + std::to_string(static_cast<unsigned char>(c));
      }
      return invalid_argument("quadkey has " + shown + " at position " + std::to_string(i) +
                              " (only digits 0-3 are allowed)");
    }
    const auto digit = static_cast<std::uint32_t>(c - '0');
    t.x = (t.x << 1) | (digit & 1u);
    t.y = (t.y << 1) | (digit >> 1);
  }
  return t;
}

Result<TileId> TileId::from_zxy(std::int64_t z, std::int64_t x, std::int64_t y) {
  if (z < 0 || z > kMaxLevel) {
    return invalid_argument("level " + std::to_string(z) + " outside [0, " +
                            std::to_string(kMaxLevel) + "]");
  }
  const std::int64_t n = std::int64_t{1} << z;
  if (x < 0 || x >= n || y < 0 || y >= n) {
    return invalid_argument("tile " + std::to_string(z) + "/" + std::to_string(x) + "/" +
                            std::to_string(y) + " outside the level's range [0, " +
                            std::to_string(n - 1) + "]");
  }
  return TileId{static_cast<std::uint32_t>(z), static_cast<std::uint32_t>(x),
                static_cast<std::uint32_t>(y)};
}

Result<TileId> TileId::from_tms(std::int64_t z, std::int64_t x, std::int64_t y_tms) {
  if (z < 0 || z > kMaxLevel) return from_zxy(z, x, y_tms);
  const std::int64_t n = std::int64_t{1} << z;
  return from_zxy(z, x, n - 1 - y_tms);
}

namespace {

// Index i ∈ [0, n) with edge(i) ≤ coord < edge(i+1) for increasing edges, found from a floating
// estimate and corrected by exact comparisons against the representable edges.
template <typename Edge>
std::uint32_t locate(double coord, std::uint32_t n, Edge edge) {
  // edge(i) is monotone in i; estimate then fix up.
  double estimate = std::floor((coord - edge(0)) / (edge(n) - edge(0)) * n);
  std::int64_t i = std::clamp<std::int64_t>(static_cast<std::int64_t>(estimate), 0, n - 1);
  while (i > 0 && coord < edge(static_cast<std::uint32_t>(i))) --i;
  while (i + 1 < n && coord >= edge(static_cast<std::uint32_t>(i + 1))) ++i;
  return static_cast<std::uint32_t>(i);
}

}  // namespace

TileId TileId::containing(MercatorXY p, std::uint32_t z) {
  assert(z <= static_cast<std::uint32_t>(kMaxLevel));
  const std::uint32_t n = 1u << z;
  const double px = std::isnan(p.x) ? 0.0 : std::clamp(p.x, -1.0, 1.0);
  const double py = std::isnan(p.y) ? 0.0 : std::clamp(p.y, -1.0, 1.0);
  const std::uint32_t column = locate(px, n, [z](std::uint32_t i) { return tile_x_edge(z, i); });
  // Rows grow southward: use the negated coordinate so edges increase with the index.
  const std::uint32_t row = locate(-py, n, [z](std::uint32_t i) { return -tile_y_edge(z, i); });
  return {z, column, row};
}

bool morton_less(const TileId& a, const TileId& b) {
  // Compare the common-prefix ancestors; on a tie the shallower tile (the ancestor) comes first.
  const std::uint32_t level = std::min(a.z, b.z);
  const std::uint64_t ma = TileId{level, a.x >> (a.z - level), a.y >> (a.z - level)}.morton();
  const std::uint64_t mb = TileId{level, b.x >> (b.z - level), b.y >> (b.z - level)}.morton();
  if (ma != mb) return ma < mb;
  return a.z < b.z;
}

}  // namespace tinstream::geo
