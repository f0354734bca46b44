#include "tinstream/terrain/quantized_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "tinstream/geo/ecef.hpp"

namespace tinstream::terrain {
namespace {

constexpr double kQuantMax = 32767.0;
constexpr std::uint8_t kExtOctVertexNormals = 1;

Vec3 sub(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 add(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 scale(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double norm(Vec3 a) { return std::sqrt(dot(a, a)); }

// Little-endian byte writer (the format is little-endian; so are all our targets, but write
// byte by byte anyway so the encoding does not depend on the host).
class Writer {
 public:
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) {
    for (int i = 0; i < 2; ++i) out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void u32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void f32(float f) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    u32(bits);
  }
  void f64(double d) {
    std::uint64_t bits;
    std::memcpy(&bits, &d, 8);
    for (int i = 0; i < 8; ++i) out_.push_back(static_cast<std::uint8_t>(bits >> (8 * i)));
  }
  void align(std::size_t n) {
    while (out_.size() % n != 0) out_.push_back(0);
  }
  std::size_t size() const { return out_.size(); }
  std::vector<std::uint8_t> take() { return std::move(out_); }

 private:
  std::vector<std::uint8_t> out_;
};

// Interleaves the low 16 bits of x with zeros (bit i → bit 2i): half of a Morton code.
std::uint32_t spread_bits(std::uint32_t x) {
  x &= 0xffffu;
  x = (x | (x << 8)) & 0x00ff00ffu;
  x = (x | (x << 4)) & 0x0f0f0f0fu;
  x = (x | (x << 2)) & 0x33333333u;
  x = (x | (x << 1)) & 0x55555555u;
  return x;
}

// The order the triangles are written in, chosen for the compressor. Vertices are numbered by
// first use and delta-coded, indices are high-water-mark codes, and gzip runs over both; all three
// do best when each triangle shares an edge with the one before it. So: a depth-first walk across
// shared edges, moving to the first unvisited neighbour and backing up the walk's stack when there
// is none; walk starts and ties follow the Morton order of the quantised centroids, then the
// vertex indices. Each triangle is then rotated (orientation kept) to start at its vertex written
// earliest (an unwritten one counts as latest). The result depends only on the set of triangles
// (their stored order and rotation do not matter), so a tile always encodes to the same bytes.
// Measured on the 833 tiles of an SRTM layer (bench/server): 42.0 MB of gzip tiles in the stored
// order, 29.7 MB in Morton order alone, 20.8 MB in this order.
std::vector<tile::Triangle> locality_order(const std::vector<tile::Triangle>& triangles,
                                           const std::vector<std::uint16_t>& qu,
                                           const std::vector<std::uint16_t>& qv,
                                           std::size_t vertices) {
  constexpr std::uint32_t kNo = std::numeric_limits<std::uint32_t>::max();
  const std::size_t m = triangles.size();
  // Canonical rotation (smallest index first), then the walk's base order.
  std::vector<tile::Triangle> rotated(m);
  std::vector<std::uint32_t> morton(m), rank(m);
  for (std::size_t i = 0; i < m; ++i) {
    tile::Triangle t = triangles[i];
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
    rotated[i] = t;
    const std::uint32_t cu = (std::uint32_t{qu[t[0]]} + qu[t[1]] + qu[t[2]]) / 3;
    const std::uint32_t cv = (std::uint32_t{qv[t[0]]} + qv[t[1]] + qv[t[2]]) / 3;
    morton[i] = spread_bits(cu) | (spread_bits(cv) << 1);
    rank[i] = static_cast<std::uint32_t>(i);
  }
  std::sort(rank.begin(), rank.end(), [&](std::uint32_t a, std::uint32_t b) {
    return morton[a] != morton[b] ? morton[a] < morton[b] : rotated[a] < rotated[b];
  });
  std::vector<tile::Triangle> base(m);
  for (std::size_t k = 0; k < m; ++k) base[k] = rotated[rank[k]];

  // Neighbours: the triangle holding the reverse of each directed edge, found among the edges
  // leaving the edge's end vertex (compressed rows by start vertex, each row sorted by end vertex
  // then triangle, so a lookup is a binary search: a vertex shared by many triangles — say, a
  // hostile tile repeating one triangle 100k times — costs log of its degree, not its degree).
  std::vector<std::uint32_t> row(vertices + 1, 0);
  for (const auto& t : base) {
    for (std::uint32_t v : t) ++row[v + 1];
  }
  for (std::size_t v = 0; v < vertices; ++v) row[v + 1] += row[v];
  std::vector<std::uint32_t> fill(row.begin(), row.end() - 1);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edge(3 * m);  // (to, triangle) by row
  for (std::size_t k = 0; k < m; ++k) {
    const auto& t = base[k];
    for (int e = 0; e < 3; ++e) {
      edge[fill[t[static_cast<std::size_t>(e)]]++] = {t[static_cast<std::size_t>((e + 1) % 3)],
                                                      static_cast<std::uint32_t>(k)};
    }
  }
  for (std::size_t v = 0; v < vertices; ++v) {
    std::sort(edge.begin() + row[v], edge.begin() + row[v + 1]);
  }
  std::vector<std::array<std::uint32_t, 3>> across(m);
  for (std::size_t k = 0; k < m; ++k) {
    const auto& t = base[k];
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t from = t[static_cast<std::size_t>((e + 1) % 3)];
      const std::uint32_t to = t[static_cast<std::size_t>(e)];
      // The first (to, ·) in the row: the smallest triangle holding the edge from → to.
      const auto first = std::lower_bound(edge.begin() + row[from], edge.begin() + row[from + 1],
                                          std::pair<std::uint32_t, std::uint32_t>{to, 0});
      across[k][static_cast<std::size_t>(e)] =
          first != edge.begin() + row[from + 1] && first->first == to ? first->second : kNo;
    }
  }

  std::vector<std::uint8_t> visited(m, 0);
  auto next_of = [&](std::uint32_t t) {
    std::uint32_t best = kNo;
    for (std::uint32_t j : across[t]) {
      if (j != kNo && !visited[j]) best = std::min(best, j);
    }
    return best;
  };
  std::vector<std::uint32_t> walk, stack;
  walk.reserve(m);
  for (std::uint32_t start = 0; start < m; ++start) {
    std::uint32_t cur = visited[start] ? kNo : start;
    while (cur != kNo) {
      visited[cur] = 1;
      walk.push_back(cur);
      stack.push_back(cur);
      cur = next_of(cur);
      while (cur == kNo && !stack.empty()) {
        cur = next_of(stack.back());
        if (cur == kNo) stack.pop_back();
      }
    }
  }

  // Rotation: the smallest tuple of first uses (kNo for a vertex not written yet).
  std::vector<std::uint32_t> first_use(vertices, kNo);
  std::uint32_t used = 0;
  std::vector<tile::Triangle> out;
  out.reserve(m);
  for (std::uint32_t k : walk) {
    const tile::Triangle& t = base[k];
    tile::Triangle best = t;
    auto uses = [&](const tile::Triangle& r) {
      return std::array<std::uint32_t, 3>{first_use[r[0]], first_use[r[1]], first_use[r[2]]};
    };
    for (const tile::Triangle& r :
         {tile::Triangle{t[1], t[2], t[0]}, tile::Triangle{t[2], t[0], t[1]}}) {
      if (uses(r) < uses(best)) best = r;
    }
    for (std::uint32_t v : best) {
      if (first_use[v] == kNo) first_use[v] = used++;
    }
    out.push_back(best);
  }
  return out;
}

std::uint16_t zigzag(int v) {
  return static_cast<std::uint16_t>((static_cast<unsigned>(v) << 1) ^
                                    static_cast<unsigned>(v >> 31));
}

std::uint16_t quantise(double t) {
  // NaN (a flat tile's 0/0 height range, a NaN coordinate of a corrupt blob) is 0, not a NaN
  // cast to an integer (undefined; found by qmesh_fuzzer).
  const double q = std::round((t > 0 ? std::min(t, 1.0) : 0.0) * kQuantMax);
  return static_cast<std::uint16_t>(q);
}

struct Sphere {
  Vec3 centre;
  double radius = 0;
};

Sphere bounding_sphere(std::span<const Vec3> pts) {
  // Two candidates, the smaller wins: the box centre with its farthest point, and Ritter's sphere.
  Vec3 lo = pts[0], hi = pts[0];
  for (const Vec3& p : pts) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  Sphere box{scale(add(lo, hi), 0.5), 0};
  for (const Vec3& p : pts) box.radius = std::max(box.radius, norm(sub(p, box.centre)));

  // Ritter: start from the farthest pair found by two sweeps, then grow.
  Vec3 a = pts[0];
  Vec3 b = a;
  double best = -1;
  for (const Vec3& p : pts) {
    const double d = norm(sub(p, a));
    if (d > best) best = d, b = p;
  }
  best = -1;
  Vec3 c = b;
  for (const Vec3& p : pts) {
    const double d = norm(sub(p, b));
    if (d > best) best = d, c = p;
  }
  Sphere ritter{scale(add(b, c), 0.5), norm(sub(b, c)) * 0.5};
  for (const Vec3& p : pts) {
    const double d = norm(sub(p, ritter.centre));
    if (d > ritter.radius) {
      const double r = (ritter.radius + d) * 0.5;
      ritter.centre = add(ritter.centre, scale(sub(p, ritter.centre), (r - ritter.radius) / d));
      ritter.radius = r;
    }
  }
  // Guard against rounding in the growth step.
  for (const Vec3& p : pts) ritter.radius = std::max(ritter.radius, norm(sub(p, ritter.centre)));
  return ritter.radius < box.radius ? ritter : box;
}

}  // namespace

std::optional<Vec3> horizon_occlusion_point(std::span<const Vec3> ecef_points,
                                            Vec3 direction_point) {
  const double a = geo::kWgs84A;
  const double b = geo::kWgs84A * (1.0 - geo::kWgs84F);
  auto to_scaled = [&](Vec3 p) { return Vec3{p.x / a, p.y / a, p.z / b}; };
  Vec3 dir = to_scaled(direction_point);
  const double dir_len = norm(dir);
  if (!(dir_len > 0)) return std::nullopt;
  dir = scale(dir, 1.0 / dir_len);
  double max_magnitude = 0;
  for (const Vec3& p : ecef_points) {
    const Vec3 s = to_scaled(p);
    double mag2 = dot(s, s);
    double mag = std::sqrt(mag2);
    if (!(mag > 0)) return std::nullopt;
    const Vec3 d = scale(s, 1.0 / mag);
    // Points below the ellipsoid count as on it.
    mag2 = std::max(1.0, mag2);
    mag = std::max(1.0, mag);
    const double cos_alpha = dot(d, dir);
    const double sin_alpha = norm(cross(d, dir));
    const double cos_beta = 1.0 / mag;
    const double sin_beta = std::sqrt(mag2 - 1.0) * cos_beta;
    const double denom = cos_alpha * cos_beta - sin_alpha * sin_beta;
    if (!(denom > 0)) return std::nullopt;
    max_magnitude = std::max(max_magnitude, 1.0 / denom);
  }
  if (!std::isfinite(max_magnitude)) return std::nullopt;
  return scale(dir, max_magnitude);
}

std::array<std::uint8_t, 2> oct_encode(Vec3 n) {
  double l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  // A vertex whose triangles are all degenerate has no normal (zero or NaN): up, not a NaN cast
  // to a byte (undefined; found by qmesh_fuzzer).
  if (!(l1 > 0) || !std::isfinite(l1)) n = {0, 0, 1}, l1 = 1;
  double x = n.x / l1;
  double y = n.y / l1;
  if (n.z < 0) {
    const double ox = x, oy = y;
    x = (1.0 - std::abs(oy)) * (ox < 0 ? -1.0 : 1.0);
    y = (1.0 - std::abs(ox)) * (oy < 0 ? -1.0 : 1.0);
  }
  auto to_snorm = [](double v) {
    return static_cast<std::uint8_t>(std::round((std::clamp(v, -1.0, 1.0) * 0.5 + 0.5) * 255.0));
  };
  return {to_snorm(x), to_snorm(y)};
}

tile::TinTile flat_tile(const geo::TileId& id) {
  tile::TinTile t;
  t.id = id;
  const geo::MercatorRect r = id.bounds();
  t.corners[0] = {r.min_x, r.max_y, 0, 0};
  t.corners[1] = {r.max_x, r.max_y, 0, 0};
  t.corners[2] = {r.min_x, r.min_y, 0, 0};
  t.corners[3] = {r.max_x, r.min_y, 0, 0};
  // NW(0) SW(2) SE(3) and NW(0) SE(3) NE(1): counter-clockwise in x-east, y-north.
  t.triangles = {{0, 2, 3}, {0, 3, 1}};
  return t;
}

namespace {

// ---- encode_quantized_mesh, step by step ----------------------------------------------------

// Border sides a vertex lies on (bits, a corner has two).
constexpr std::uint8_t kWest = 1, kSouth = 2, kEast = 4, kNorth = 8;

// The tile's vertices in the tile numbering (tin_tile.hpp), each with its border sides.
struct SidedVertices {
  std::vector<tile::Vertex> vertices;
  std::vector<std::uint8_t> sides;
};

// Errors: more vertices than 32-bit indices can count, a triangle index out of range.
Result<SidedVertices> gather_vertices(const tile::TinTile& tile) {
  SidedVertices out;
  out.vertices.assign(tile.corners.begin(), tile.corners.end());
  out.sides = {kNorth | kWest, kNorth | kEast, kSouth | kWest, kSouth | kEast};
  auto append = [&](const std::vector<tile::Vertex>& list, std::uint8_t bits) {
    for (const auto& v : list) {
      out.vertices.push_back(v);
      out.sides.push_back(bits);
    }
  };
  append(tile.north, kNorth);
  append(tile.east, kEast);
  append(tile.south, kSouth);
  append(tile.west, kWest);
  append(tile.interior, 0);
  const std::size_t n = out.vertices.size();
  if (n > std::numeric_limits<std::uint32_t>::max() / 2) {
    return invalid_argument("tile " + tile.id.to_string() + ": too many vertices");
  }
  for (const auto& t : tile.triangles) {
    for (std::uint32_t i : t) {
      if (i >= n) {
        return invalid_argument("tile " + tile.id.to_string() + ": triangle index " +
                                std::to_string(i) + " out of range");
      }
    }
  }
  return out;
}

// The height range the tile's heights are quantised in (and the header's min/max height).
struct HeightRange {
  double min = 0, max = 0;
  double span() const { return max - min; }
};

// Errors: a non-finite height.
Result<HeightRange> height_range(const tile::TinTile& tile,
                                 const std::vector<tile::Vertex>& vertices) {
  HeightRange h{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const auto& v : vertices) {
    h.min = std::min(h.min, v.z);
    h.max = std::max(h.max, v.z);
  }
  if (!std::isfinite(h.min) || !std::isfinite(h.max)) {
    return invalid_argument("tile " + tile.id.to_string() + ": non-finite height");
  }
  return h;
}

// u, v, height of each vertex on the 15-bit grid (0 … 32767).
struct QuantisedVertices {
  std::vector<std::uint16_t> u, v, h;
};

// Quantises in the tile's numbering: u and v linear in longitude and latitude over `rect`,
// heights over `heights`. Border vertices are pinned to their sides, so rounding cannot move
// them off and neighbours share their edge vertices.
QuantisedVertices quantise_vertices(const SidedVertices& in, const geo::NormalisedMercator& merc,
                                    const geo::LonLatRect& rect, const HeightRange& heights) {
  const std::size_t n = in.vertices.size();
  QuantisedVertices q{std::vector<std::uint16_t>(n), std::vector<std::uint16_t>(n),
                      std::vector<std::uint16_t>(n)};
  const double h_range = heights.span();
  for (std::size_t k = 0; k < n; ++k) {
    const tile::Vertex& v = in.vertices[k];
    const std::uint8_t bits = in.sides[k];
    const double lon = geo::NormalisedMercator::lon_from_x(v.x);
    const double lat = merc.lat_from_y(v.y);
    double u = (lon - rect.west) / (rect.east - rect.west);
    double vv = (lat - rect.south) / (rect.north - rect.south);
    if (bits & kWest) u = 0;
    if (bits & kEast) u = 1;
    if (bits & kSouth) vv = 0;
    if (bits & kNorth) vv = 1;
    q.u[k] = quantise(u);
    q.v[k] = quantise(vv);
    q.h[k] = h_range > 0 ? quantise((v.z - heights.min) / h_range) : 0;
  }
  return q;
}

// The triangles without those that rounding to the 15-bit grid turns clockwise or flat: they are
// slivers thinner than one quantum (coarse tiles over dense data, where several vertices share a
// grid cell; edge points closer than a quantum at any level), and drawn clockwise they would fold
// over their neighbours; zero-area ones draw nothing, and a client interpolating heights in them
// divides by their area (#20; `tinstream verify` checks that none is written).
std::vector<tile::Triangle> drop_flipped(const std::vector<tile::Triangle>& triangles,
                                         const QuantisedVertices& q) {
  std::vector<tile::Triangle> kept;
  kept.reserve(triangles.size());
  for (const auto& t : triangles) {
    const double cross =
        (static_cast<double>(q.u[t[1]]) - q.u[t[0]]) *
            (static_cast<double>(q.v[t[2]]) - q.v[t[0]]) -
        (static_cast<double>(q.v[t[1]]) - q.v[t[0]]) * (static_cast<double>(q.u[t[2]]) - q.u[t[0]]);
    if (cross > 0) kept.push_back(t);
  }
  return kept;
}

// The output numbering: vertices in order of first use by the triangle list (the high-water-mark
// code needs it), unused vertices last.
struct Renumbering {
  std::vector<std::uint32_t> new_index;  // old → new
  std::vector<std::uint32_t> order;      // new → old
};

Renumbering renumber_by_first_use(const std::vector<tile::Triangle>& triangles, std::size_t n) {
  constexpr std::uint32_t kUnset = std::numeric_limits<std::uint32_t>::max();
  Renumbering r{std::vector<std::uint32_t>(n, kUnset), {}};
  r.order.reserve(n);
  auto number = [&](std::uint32_t i) {
    if (r.new_index[i] == kUnset) {
      r.new_index[i] = static_cast<std::uint32_t>(r.order.size());
      r.order.push_back(i);
    }
  };
  for (const auto& t : triangles) {
    for (std::uint32_t i : t) number(i);
  }
  for (std::uint32_t i = 0; i < n; ++i) number(i);
  return r;
}

QuantisedVertices reorder(const QuantisedVertices& q, const std::vector<std::uint32_t>& order) {
  const std::size_t n = order.size();
  QuantisedVertices out{std::vector<std::uint16_t>(n), std::vector<std::uint16_t>(n),
                        std::vector<std::uint16_t>(n)};
  for (std::size_t k = 0; k < n; ++k) {
    out.u[k] = q.u[order[k]];
    out.v[k] = q.v[order[k]];
    out.h[k] = q.h[order[k]];
  }
  return out;
}

// ECEF of the positions Cesium will reconstruct (quantised lon/lat/height), so that bounding
// volumes and normals match what is drawn.
std::vector<Vec3> reconstructed_ecef(const QuantisedVertices& q, const geo::LonLatRect& rect,
                                     const HeightRange& heights) {
  std::vector<Vec3> ecef(q.u.size());
  for (std::size_t k = 0; k < ecef.size(); ++k) {
    const double dlon = rect.west + (rect.east - rect.west) * q.u[k] / kQuantMax;
    const double dlat = rect.south + (rect.north - rect.south) * q.v[k] / kQuantMax;
    const double dh = heights.min + heights.span() * q.h[k] / kQuantMax;
    const geo::Ecef e = geo::to_ecef({dlon, dlat, dh});
    ecef[k] = {e.x, e.y, e.z};
  }
  return ecef;
}

// The header's centre: the rectangle's middle at the middle height, in ECEF.
Vec3 tile_centre(const geo::LonLatRect& rect, const HeightRange& heights) {
  const geo::Ecef c = geo::to_ecef({(rect.west + rect.east) / 2, (rect.south + rect.north) / 2,
                                    (heights.min + heights.max) / 2});
  return {c.x, c.y, c.z};
}

// QuantizedMeshHeader: centre, height range, bounding sphere, horizon occlusion point.
void write_header(Writer& w, const Vec3& centre, const HeightRange& heights,
                  const std::vector<Vec3>& ecef) {
  const Sphere sphere = bounding_sphere(ecef);
  const std::optional<Vec3> hop = horizon_occlusion_point(ecef, sphere.centre);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  w.f64(centre.x);
  w.f64(centre.y);
  w.f64(centre.z);
  w.f32(static_cast<float>(heights.min));
  w.f32(static_cast<float>(heights.max));
  w.f64(sphere.centre.x);
  w.f64(sphere.centre.y);
  w.f64(sphere.centre.z);
  w.f64(sphere.radius);
  w.f64(hop ? hop->x : nan);
  w.f64(hop ? hop->y : nan);
  w.f64(hop ? hop->z : nan);
}

// vertexCount, then u[], v[], height[] as zig-zag deltas.
void write_vertices(Writer& w, const QuantisedVertices& q) {
  w.u32(static_cast<std::uint32_t>(q.u.size()));
  for (const auto* column : {&q.u, &q.v, &q.h}) {
    int prev = 0;
    for (std::uint16_t value : *column) {
      w.u16(zigzag(static_cast<int>(value) - prev));
      prev = value;
    }
  }
}

// An index: u16, or u32 for meshes of more than 65536 vertices.
void put_index(Writer& w, bool wide, std::uint32_t i) {
  if (wide) {
    w.u32(i);
  } else {
    w.u16(static_cast<std::uint16_t>(i));
  }
}

// triangleCount, then the indices (new numbering) as high-water-mark codes.
void write_triangles(Writer& w, bool wide, const std::vector<tile::Triangle>& triangles,
                     const std::vector<std::uint32_t>& new_index) {
  w.align(wide ? 4 : 2);
  w.u32(static_cast<std::uint32_t>(triangles.size()));
  std::uint32_t highest = 0;
  for (const auto& t : triangles) {
    for (std::uint32_t old : t) {
      const std::uint32_t i = new_index[old];
      const std::uint32_t code = highest - i;  // i ≤ highest by construction of the numbering
      put_index(w, wide, code);
      if (code == 0) ++highest;
    }
  }
}

// The four edge index lists, in the order Cesium's skirt builder sorts them into: west
// south→north, south east→west, east north→south, north west→east.
void write_edge_lists(Writer& w, bool wide, const std::vector<std::uint8_t>& sides,
                      const Renumbering& numbering, const QuantisedVertices& q) {
  const auto n = static_cast<std::uint32_t>(numbering.order.size());
  auto edge = [&](std::uint8_t bit, auto less) {
    std::vector<std::uint32_t> list;
    for (std::uint32_t k = 0; k < n; ++k) {
      if (sides[numbering.order[k]] & bit) list.push_back(k);
    }
    std::stable_sort(list.begin(), list.end(), less);
    w.u32(static_cast<std::uint32_t>(list.size()));
    for (std::uint32_t k : list) put_index(w, wide, k);
  };
  edge(kWest, [&](std::uint32_t a, std::uint32_t b) { return q.v[a] < q.v[b]; });
  edge(kSouth, [&](std::uint32_t a, std::uint32_t b) { return q.u[a] > q.u[b]; });
  edge(kEast, [&](std::uint32_t a, std::uint32_t b) { return q.v[a] > q.v[b]; });
  edge(kNorth, [&](std::uint32_t a, std::uint32_t b) { return q.u[a] < q.u[b]; });
}

// The octvertexnormals extension: area-weighted face normals in ECEF (relative to the centre for
// precision), summed per vertex. CCW in lon/lat seen from above ⇒ the cross product points away
// from the Earth.
void write_oct_normals(Writer& w, const std::vector<tile::Triangle>& triangles,
                       const std::vector<std::uint32_t>& new_index, const std::vector<Vec3>& ecef,
                       const Vec3& centre) {
  const std::size_t n = ecef.size();
  std::vector<Vec3> normals(n);
  for (const auto& t : triangles) {
    const std::uint32_t i0 = new_index[t[0]], i1 = new_index[t[1]], i2 = new_index[t[2]];
    const Vec3 p0 = sub(ecef[i0], centre), p1 = sub(ecef[i1], centre), p2 = sub(ecef[i2], centre);
    const Vec3 f = cross(sub(p1, p0), sub(p2, p0));
    for (std::uint32_t i : {i0, i1, i2}) normals[i] = add(normals[i], f);
  }
  w.u8(kExtOctVertexNormals);
  w.u32(static_cast<std::uint32_t>(2 * n));
  for (std::size_t k = 0; k < n; ++k) {
    Vec3 nv = normals[k];
    double len = norm(nv);
    if (!(len > 0)) {
      // Degenerate fan (or unused vertex): the ellipsoid's geodetic normal.
      const double a = geo::kWgs84A, b = a * (1.0 - geo::kWgs84F);
      nv = {ecef[k].x / (a * a), ecef[k].y / (a * a), ecef[k].z / (b * b)};
      len = norm(nv);
    }
    const auto oct = oct_encode(scale(nv, 1.0 / len));
    w.u8(oct[0]);
    w.u8(oct[1]);
  }
}

}  // namespace

// quantise → drop flipped → order → renumber → bounds → serialise.
Result<std::vector<std::uint8_t>> encode_quantized_mesh(const tile::TinTile& tile,
                                                        geo::Projection projection,
                                                        const QuantizedMeshOptions& options) {
  if (projection != geo::Projection::spherical) {
    return unsupported("tile " + tile.id.to_string() +
                       ": quantized-mesh needs a spherical-Mercator layer (EPSG:3857 tiling); "
                       "ellipsoidal-Mercator tiles do not coincide with Cesium's tiles");
  }
  if (!tile.id.valid()) return invalid_argument("quantized-mesh: invalid tile id");
  if (tile.triangles.empty()) {
    return invalid_argument("tile " + tile.id.to_string() + " has no triangles");
  }
  auto sided = gather_vertices(tile);
  if (!sided) return sided.error();
  const std::size_t n = sided->vertices.size();
  const geo::NormalisedMercator merc(projection);
  const geo::LonLatRect rect = tile.id.lonlat_bounds(merc);
  auto heights = height_range(tile, sided->vertices);
  if (!heights) return heights.error();

  const QuantisedVertices q_tile = quantise_vertices(*sided, merc, rect, *heights);
  const std::vector<tile::Triangle> triangles =
      locality_order(drop_flipped(tile.triangles, q_tile), q_tile.u, q_tile.v, n);
  const Renumbering numbering = renumber_by_first_use(triangles, n);
  const QuantisedVertices q = reorder(q_tile, numbering.order);
  const std::vector<Vec3> ecef = reconstructed_ecef(q, rect, *heights);
  const Vec3 centre = tile_centre(rect, *heights);

  Writer w;
  const bool wide = n > 65536;
  write_header(w, centre, *heights, ecef);
  write_vertices(w, q);
  write_triangles(w, wide, triangles, numbering.new_index);
  write_edge_lists(w, wide, sided->sides, numbering, q);
  if (options.oct_vertex_normals)
    write_oct_normals(w, triangles, numbering.new_index, ecef, centre);
  return w.take();
}

}  // namespace tinstream::terrain
