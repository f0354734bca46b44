#include "tinstream/client/render_mesh.hpp"

#include <zlib.h>

#include <GeographicLib/Math.hpp>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <unordered_map>
#include <unordered_set>

#include "tinstream/geo/ecef.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::client {

std::string_view to_string(ContentEncoding e) {
  switch (e) {
    case ContentEncoding::identity:
      return "identity";
    case ContentEncoding::deflate:
      return "deflate";
    case ContentEncoding::gzip:
      return "gzip";
  }
  return "identity";
}

namespace {

Result<std::vector<std::uint8_t>> gunzip(std::span<const std::uint8_t> bytes,
                                         std::size_t max_output) {
  z_stream zs{};
  if (inflateInit2(&zs, 16 + MAX_WBITS) != Z_OK) return io_error("gzip: inflateInit2 failed");
  std::vector<std::uint8_t> out(
      std::min<std::size_t>(std::max<std::size_t>(bytes.size() * 4, 4096), max_output + 1));
  zs.next_in = const_cast<Bytef*>(bytes.data());
  zs.avail_in = static_cast<uInt>(bytes.size());
  int rc = Z_OK;
  std::size_t produced = 0;
  while (rc == Z_OK) {
    if (produced == out.size()) {
      if (out.size() > max_output) break;
      out.resize(std::min(out.size() * 2, max_output + 1));
    }
    zs.next_out = out.data() + produced;
    zs.avail_out = static_cast<uInt>(out.size() - produced);
    rc = inflate(&zs, Z_NO_FLUSH);
    produced = out.size() - zs.avail_out;
  }
  inflateEnd(&zs);
  if (produced > max_output) return corrupt_data("gzip: inflates past the size limit");
  if (rc != Z_STREAM_END) return corrupt_data("gzip: truncated or malformed stream");
  out.resize(produced);
  return out;
}

// 10-bit signed normalised component of the 2_10_10_10 format.
std::uint32_t snorm10(double v) {
  const auto i = round_half_away(std::clamp(v, -1.0, 1.0) * 511.0);
  return static_cast<std::uint32_t>(i) & 0x3FFu;
}

std::uint32_t pack_normal(Vec3 n, bool skirt) {
  return snorm10(n.x) | (snorm10(n.y) << 10) | (snorm10(n.z) << 20) | (skirt ? 1u << 30 : 0u);
}

std::uint16_t unorm16(double t) {
  return static_cast<std::uint16_t>(round_half_away(std::clamp(t, 0.0, 1.0) * 65535.0));
}

Vec3 to_vec(const geo::Ecef& e) { return {e.x, e.y, e.z}; }

// The border vertex indices of each side, corners included, in edge order (tile numbering).
std::array<std::vector<std::uint32_t>, 4> border_loops(const tile::TinTile& t) {
  std::array<std::vector<std::uint32_t>, 4> sides;
  std::uint32_t next = 4;
  const auto side = [&](std::uint32_t first, std::size_t count, std::uint32_t last) {
    std::vector<std::uint32_t> s{first};
    for (std::size_t i = 0; i < count; ++i) s.push_back(next++);
    s.push_back(last);
    return s;
  };
  sides[0] = side(0, t.north.size(), 1);  // north: NW → NE
  sides[1] = side(1, t.east.size(), 3);   // east: NE → SE
  sides[2] = side(2, t.south.size(), 3);  // south: SW → SE
  sides[3] = side(0, t.west.size(), 2);   // west: NW → SW
  return sides;
}

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t{a} << 32) | b;
}

}  // namespace

Result<std::vector<std::uint8_t>> inflate_payload(std::span<const std::uint8_t> bytes,
                                                  ContentEncoding encoding,
                                                  std::size_t max_output) {
  switch (encoding) {
    case ContentEncoding::deflate:
      return tile::decompress(bytes, max_output);
    case ContentEncoding::gzip:
      return gunzip(bytes, max_output);
    case ContentEncoding::identity:
      if (bytes.size() > max_output) return corrupt_data("payload larger than the size limit");
      return std::vector<std::uint8_t>(bytes.begin(), bytes.end());
  }
  return unsupported("unknown content encoding");
}

std::int32_t round_half_away(double v) {
  if (std::isnan(v)) return 0;                  // what std::lround gave here, truncated to 32 bits
  const auto i = static_cast<std::int32_t>(v);  // towards zero
  const double fraction = v - i;                // exact: the bits of v below the units
  return i + (fraction >= 0.5 ? 1 : 0) - (fraction <= -0.5 ? 1 : 0);
}

std::size_t TileMesh::byte_size() const {
  return vertices.size() * sizeof(MeshVertex) + indices16.size() * 2 + indices32.size() * 4;
}

namespace {

// cos φ and sin φ of normalised Mercator y (GeodeticTerms' header comment).
std::pair<double, double> latitude_terms(const geo::NormalisedMercator& projection, double y) {
  const double e = projection.eccentricity();
  if (e == 0) {
    // Spherical Mercator: φ is the Gudermannian of πy, cos φ = sech πy and sin φ = tanh πy.
    // With t = e^(2π|y|) − 1 ≥ 0 (expm1): tanh = t / (t + 2), sech = 2 √(t + 1) / (t + 2) — one
    // expm1, one sqrt and one division instead of sinh and hypot. |y| keeps t + 1 ≥ 1 (no
    // cancellation towards the south pole); the sign goes back on sin φ.
    const double t = std::expm1(2 * std::numbers::pi * std::abs(y));
    const double inverse = 1 / (t + 2);
    return {2 * std::sqrt(t + 1) * inverse, std::copysign(t * inverse, y)};
  }
  const double tau = GeographicLib::Math::tauf(std::sinh(y * std::numbers::pi), e);
  const double cos_lat = 1 / std::hypot(1.0, tau);
  return {cos_lat, tau * cos_lat};
}

GeodeticTerms terms_from(std::pair<double, double> lat, double cos_lon, double sin_lon) {
  constexpr double kE2 = geo::kWgs84F * (2 - geo::kWgs84F);
  const auto [cos_lat, sin_lat] = lat;
  return {cos_lat * cos_lon, cos_lat * sin_lon, sin_lat,
          geo::kWgs84A / std::sqrt(1 - kE2 * sin_lat * sin_lat)};
}

}  // namespace

LongitudeNear::LongitudeNear(double centre)
    : centre_x(centre),
      cos_centre(std::cos(centre * std::numbers::pi)),
      sin_centre(std::sin(centre * std::numbers::pi)) {}

std::pair<double, double> LongitudeNear::cos_sin(double x) const {
  const double d = (x - centre_x) * std::numbers::pi;
  if (!(std::abs(d) <= kReach)) {
    const double lon = x * std::numbers::pi;
    return {std::cos(lon), std::sin(lon)};
  }
  // Taylor series of cos d and sin d to d⁸ and d⁷ (Horner); |d| ≤ 0.05 leaves out d¹⁰/10! and
  // d⁹/9!, both below 6e-18.
  const double d2 = d * d;
  const double cos_d = 1 + d2 * (-1.0 / 2 + d2 * (1.0 / 24 + d2 * (-1.0 / 720 + d2 / 40320)));
  const double sin_d = d * (1 + d2 * (-1.0 / 6 + d2 * (1.0 / 120 - d2 / 5040)));
  return {cos_centre * cos_d - sin_centre * sin_d, sin_centre * cos_d + cos_centre * sin_d};
}

GeodeticTerms GeodeticTerms::from_mercator(const geo::NormalisedMercator& projection, double x,
                                           double y) {
  const double lon = x * std::numbers::pi;
  return terms_from(latitude_terms(projection, y), std::cos(lon), std::sin(lon));
}

GeodeticTerms GeodeticTerms::from_mercator(const geo::NormalisedMercator& projection,
                                           const LongitudeNear& near, double x, double y) {
  const auto [cos_lon, sin_lon] = near.cos_sin(x);
  return terms_from(latitude_terms(projection, y), cos_lon, sin_lon);
}

Vec3 GeodeticTerms::ecef(double height) const {
  constexpr double kE2 = geo::kWgs84F * (2 - geo::kWgs84F);
  const double r = prime_vertical + height;
  return {r * cos_lat_cos_lon, r * cos_lat_sin_lon,
          (prime_vertical * (1 - kE2) + height) * sin_lat};
}

double skirt_margin(const tile::TinTile& tile, const LayerDescription& layer) {
  const geo::MercatorRect r = tile.id.bounds();
  const double lat = geo::NormalisedMercator(layer.projection).lat_from_y((r.min_y + r.max_y) / 2);
  const double width_m =
      r.width() * std::numbers::pi * geo::kWgs84A * std::cos(lat * std::numbers::pi / 180.0);
  return std::max(1e-5 * width_m, 0.05);
}

namespace {

// A point of a cut skirt's cross-section: ECEF, normalised Mercator and height.
struct CutPoint {
  Vec3 ecef;
  double x, y, z;
};

CutPoint between(const CutPoint& p, const CutPoint& q, double t) {
  return CutPoint{p.ecef + (q.ecef - p.ecef) * t, p.x + (q.x - p.x) * t, p.y + (q.y - p.y) * t,
                  p.z + (q.z - p.z) * t};
}

// The steps of build_render_mesh, in this order; each reads what the steps before it left.
class MeshBuilder {
 public:
  MeshBuilder(const tile::TinTile& tile, const LayerDescription& layer, TileKey key);

  TileMesh build() && {
    select_drawn();
    place_vertices();
    emit_surface();
    add_side_skirts();
    add_cut_skirts();
    write_indices();
    fit_bounds();
    return std::move(mesh_);
  }

 private:
  void select_drawn();
  void place_vertices();
  void emit_surface();
  void add_side_skirts();
  void add_cut_skirts();
  void write_indices();
  void fit_bounds();

  void emit(Vec3 p, double height, Vec3 n, bool skirt, const tile::Vertex& v);
  std::uint32_t skirt_vertex(std::uint32_t v);
  CutPoint along_edge(std::uint32_t a, std::uint32_t b, double t) const;
  // The cross-section of drawn triangle t with the mid line (x = mid when vertical, else y =
  // mid), split where it crosses the other mid line.
  void cut_triangle(const tile::Triangle& t, bool vertical,
                    std::unordered_set<std::uint64_t>& cut_edges);
  void emit_cut(const CutPoint& p, const CutPoint& q, Vec3 n, bool vertical);

  const tile::TinTile& tile_;
  const LayerDescription& layer_;
  const geo::NormalisedMercator projection_;
  const std::vector<tile::Vertex> vertices_;
  const geo::MercatorRect rect_;
  const double mid_x_, mid_y_;
  const double inv_w_, inv_h_;
  const LongitudeNear longitude_{mid_x_};  // cos, sin of the longitudes of this tile
  TileMesh mesh_;

  std::vector<tile::Triangle> drawn_;  // inside the data footprint
  // Drawn triangles (their indices into drawn_, in order) that reach x = mid, y = mid: the only
  // ones a cut can cross.
  std::vector<std::uint32_t> reach_mid_x_, reach_mid_y_;
  std::vector<std::uint8_t> used_;    // 1: a vertex of a drawn triangle (bytes, not bits: cheaper)
  std::vector<GeodeticTerms> terms_;  // per vertex
  std::vector<Vec3> ecef_, normal_;   // per vertex, double precision
  double deepest_ = 0;                // the lowest a skirt may hang (for the box)
  std::vector<std::uint32_t> skirt_triangles_;
  std::unordered_map<std::uint32_t, std::uint32_t> skirt_of_;  // border vertex → skirt vertex
  std::vector<Vec3> skirt_points_;  // every skirt vertex at its deepest (for the box)
  std::array<std::vector<std::uint32_t>, 4> cut_triangles_;
  std::array<std::vector<SkirtSpan>, 4> cut_spans_;
};

MeshBuilder::MeshBuilder(const tile::TinTile& tile, const LayerDescription& layer, TileKey key)
    : tile_(tile),
      layer_(layer),
      projection_(layer.projection),
      vertices_(tile.vertices()),
      rect_(tile.id.bounds()),
      mid_x_((rect_.min_x + rect_.max_x) / 2),
      mid_y_((rect_.min_y + rect_.max_y) / 2),
      inv_w_(1.0 / rect_.width()),
      inv_h_(1.0 / rect_.height()) {
  mesh_.key = key;
  mesh_.geometric_error = tile.geometric_error;
  mesh_.skirt_margin = skirt_margin(tile, layer);
}

// Drawn triangles (the data footprint) and the vertices they use; the quadrants they reach.
void MeshBuilder::select_drawn() {
  drawn_.reserve(tile_.triangles.size());
  used_.assign(vertices_.size(), 0);
  const std::vector<std::uint8_t> footprint = tile_.footprint_mask();
  for (std::size_t i = 0; i < tile_.triangles.size(); ++i) {
    const tile::Triangle& t = tile_.triangles[i];
    if (!footprint[i]) {
      ++mesh_.nodata_triangles;
      continue;
    }
    drawn_.push_back(t);
    double lo_x = vertices_[t[0]].x, hi_x = lo_x, lo_y = vertices_[t[0]].y, hi_y = lo_y;
    for (const std::uint32_t v : t) {
      used_[v] = 1;
      lo_x = std::min(lo_x, vertices_[v].x);
      hi_x = std::max(hi_x, vertices_[v].x);
      lo_y = std::min(lo_y, vertices_[v].y);
      hi_y = std::max(hi_y, vertices_[v].y);
    }
    // Quadkey digits: 0 NW, 1 NE, 2 SW, 3 SE.
    const bool west = lo_x<mid_x_, east = hi_x> mid_x_, north = hi_y > mid_y_,
               south = lo_y < mid_y_;
    const auto index = static_cast<std::uint32_t>(drawn_.size() - 1);
    if (lo_x <= mid_x_ && hi_x >= mid_x_) reach_mid_x_.push_back(index);
    if (lo_y <= mid_y_ && hi_y >= mid_y_) reach_mid_y_.push_back(index);
    mesh_.quadrant_data |=
        static_cast<std::uint8_t>((north && west ? 1 : 0) | (north && east ? 2 : 0) |
                                  (south && west ? 4 : 0) | (south && east ? 8 : 0));
  }
  mesh_.data_triangles = static_cast<std::uint32_t>(drawn_.size());
  // Nothing drawn (a coarse tile of a small dataset whose few data vertices all touch NODATA
  // corners): the globe shows through where the data are, so the error of what is drawn is at
  // least the data's height above the ellipsoid; the streamer refines on it instead of taking
  // an empty tile for a good enough one.
  if (drawn_.empty()) {
    for (std::size_t i = 0; i < vertices_.size(); ++i) {
      if (tile_.is_nodata_vertex(i)) continue;
      mesh_.geometric_error = std::max(mesh_.geometric_error, std::abs(vertices_[i].z));
    }
  }
}

// Double-precision ECEF of every vertex; the drawn height range; the mesh's origin and frame.
void MeshBuilder::place_vertices() {
  ecef_.resize(vertices_.size());
  terms_.resize(vertices_.size());
  double min_z = std::numeric_limits<double>::infinity(), max_z = -min_z;
  for (std::size_t i = 0; i < vertices_.size(); ++i) {
    terms_[i] =
        GeodeticTerms::from_mercator(projection_, longitude_, vertices_[i].x, vertices_[i].y);
    ecef_[i] = terms_[i].ecef(vertices_[i].z);
    if (used_[i]) {
      min_z = std::min(min_z, vertices_[i].z);
      max_z = std::max(max_z, vertices_[i].z);
    }
  }
  if (drawn_.empty()) min_z = max_z = 0;
  mesh_.min_z = min_z;
  mesh_.max_z = max_z;
  const geo::LonLat centre_ll = projection_.inverse({mid_x_, mid_y_});
  mesh_.centre = to_vec(geo::to_ecef({centre_ll.lon, centre_ll.lat, (min_z + max_z) / 2}));
  mesh_.frame = enu_frame(centre_ll.lon, centre_ll.lat);
}

void MeshBuilder::emit(Vec3 p, double height, Vec3 n, bool skirt, const tile::Vertex& v) {
  const Vec3 local = p - mesh_.centre;
  mesh_.vertices.push_back(
      {{static_cast<float>(local.x), static_cast<float>(local.y), static_cast<float>(local.z)},
       static_cast<float>(height),
       pack_normal(n, skirt),
       unorm16((v.x - rect_.min_x) * inv_w_),
       unorm16((rect_.max_y - v.y) * inv_h_)});
}

// Area-weighted vertex normals (the cross product's length is twice the area), then every
// vertex in tile numbering.
void MeshBuilder::emit_surface() {
  normal_.resize(vertices_.size());
  for (const tile::Triangle& t : drawn_) {
    const Vec3 n = cross(ecef_[t[1]] - ecef_[t[0]], ecef_[t[2]] - ecef_[t[0]]);
    for (const std::uint32_t v : t) normal_[v] += n;
  }
  mesh_.vertices.reserve(vertices_.size() + 2 * (tile_.north.size() + tile_.east.size() +
                                                 tile_.south.size() + tile_.west.size() + 4));
  for (std::size_t i = 0; i < vertices_.size(); ++i) {
    const double len = length(normal_[i]);
    normal_[i] = len > 0 ? normal_[i] / len : mesh_.frame[2];
    emit(ecef_[i], vertices_[i].z, normal_[i], false, vertices_[i]);
  }
}

std::uint32_t MeshBuilder::skirt_vertex(std::uint32_t v) {
  const auto [it, fresh] =
      skirt_of_.try_emplace(v, static_cast<std::uint32_t>(mesh_.vertices.size()));
  if (fresh) {
    skirt_points_.push_back(terms_[v].ecef(std::min(vertices_[v].z, deepest_)));
    emit(ecef_[v], vertices_[v].z, normal_[v], true, vertices_[v]);
  }
  return it->second;
}

// Skirts: under every border segment that is an edge of a drawn triangle, side by side. A
// skirt vertex sits at its border vertex (the shader lowers it); for the box, its deepest
// point: the layer's lowest height less the margin (the floor never lies below it).
void MeshBuilder::add_side_skirts() {
  deepest_ = std::min(layer_.min_z, mesh_.min_z) - mesh_.skirt_margin;
  mesh_.skirt_lowest = deepest_;
  std::unordered_set<std::uint64_t> border_edges;
  const std::uint32_t border_end = static_cast<std::uint32_t>(
      4 + tile_.north.size() + tile_.east.size() + tile_.south.size() + tile_.west.size());
  for (const tile::Triangle& t : drawn_) {
    const bool b0 = t[0] < border_end, b1 = t[1] < border_end, b2 = t[2] < border_end;
    if (b0 && b1) border_edges.insert(edge_key(t[0], t[1]));
    if (b1 && b2) border_edges.insert(edge_key(t[1], t[2]));
    if (b2 && b0) border_edges.insert(edge_key(t[2], t[0]));
  }
  const auto sides = border_loops(tile_);
  for (std::size_t s = 0; s < sides.size(); ++s) {
    const std::size_t before = skirt_triangles_.size();
    const bool along_x = s == 0 || s == 2;
    for (std::size_t i = 0; i + 1 < sides[s].size(); ++i) {
      const std::uint32_t a = sides[s][i], b = sides[s][i + 1];
      if (!border_edges.contains(edge_key(a, b))) continue;
      const std::uint32_t sa = skirt_vertex(a), sb = skirt_vertex(b);
      skirt_triangles_.insert(skirt_triangles_.end(), {a, sa, sb, a, sb, b});
      const double ca = along_x ? vertices_[a].x : vertices_[a].y,
                   cb = along_x ? vertices_[b].x : vertices_[b].y;
      mesh_.skirt_spans.push_back({std::min(ca, cb), std::max(ca, cb)});
    }
    mesh_.skirt_index_count[s] = static_cast<std::uint32_t>(skirt_triangles_.size() - before);
  }
}

CutPoint MeshBuilder::along_edge(std::uint32_t a, std::uint32_t b, double t) const {
  if (a > b) std::swap(a, b), t = 1 - t;  // both triangles of an edge get the same point
  const tile::Vertex &va = vertices_[a], &vb = vertices_[b];
  return CutPoint{ecef_[a] + (ecef_[b] - ecef_[a]) * t, va.x + (vb.x - va.x) * t,
                  va.y + (vb.y - va.y) * t, va.z + (vb.z - va.z) * t};
}

void MeshBuilder::emit_cut(const CutPoint& p, const CutPoint& q, Vec3 n, bool vertical) {
  const double cp = vertical ? p.y : p.x, cq = vertical ? q.y : q.x;
  if (cp == cq) return;
  const std::size_t group =
      vertical ? (std::min(cp, cq) >= mid_y_ ? 0 : 1) : (std::max(cp, cq) <= mid_x_ ? 2 : 3);
  const auto first = static_cast<std::uint32_t>(mesh_.vertices.size());
  for (const CutPoint* c : {&p, &q}) {
    const tile::Vertex v{c->x, c->y, c->z, 0};
    emit(c->ecef, c->z, n, false, v);
    emit(c->ecef, c->z, n, true, v);
    skirt_points_.push_back(GeodeticTerms::from_mercator(projection_, longitude_, c->x, c->y)
                                .ecef(std::min(c->z, deepest_)));
  }
  cut_triangles_[group].insert(cut_triangles_[group].end(),
                               {first, first + 1, first + 3, first, first + 3, first + 2});
  cut_spans_[group].push_back({std::min(cp, cq), std::max(cp, cq)});
}

void MeshBuilder::cut_triangle(const tile::Triangle& t, bool vertical,
                               std::unordered_set<std::uint64_t>& cut_edges) {
  const double m = vertical ? mid_x_ : mid_y_, other = vertical ? mid_y_ : mid_x_;
  const auto c = [&](std::uint32_t v) { return vertical ? vertices_[v].x : vertices_[v].y; };
  std::array<CutPoint, 3> points_at{};  // at most one per edge
  std::size_t count = 0;
  const auto push = [&](const CutPoint& p) { points_at[count++] = p; };
  std::uint32_t on_line[2]{}, on = 0;
  for (std::size_t e = 0; e < 3; ++e) {
    const std::uint32_t a = t[e], b = t[(e + 1) % 3];
    if (c(a) == m) {
      if (on < 2) on_line[on] = a;
      ++on;
      push(along_edge(a, a, 0));
    } else if ((c(a) < m) != (c(b) < m) && c(b) != m) {
      push(along_edge(a, b, (m - c(a)) / (c(b) - c(a))));
    }
  }
  if (count != 2) return;  // touches the line at a vertex, or degenerate
  if (on == 2 && !cut_edges.insert(edge_key(on_line[0], on_line[1])).second) return;
  const Vec3 n = normalize(cross(ecef_[t[1]] - ecef_[t[0]], ecef_[t[2]] - ecef_[t[0]]));
  const CutPoint &p = points_at[0], &q = points_at[1];
  const double ap = vertical ? p.y : p.x, aq = vertical ? q.y : q.x;
  if ((ap < other) != (aq < other) && ap != other && aq != other) {
    const CutPoint mid = between(p, q, (other - ap) / (aq - ap));
    emit_cut(p, mid, n, vertical);
    emit_cut(mid, q, n, vertical);
  } else {
    emit_cut(p, q, n, vertical);
  }
}

// Cut skirts: the drawn surface's cross-sections along x = mid and y = mid, split at the
// centre into the four half-lines between two quadrants. A point of a cross-section lies on a
// triangle's edge (or is its vertex); position, height and uv are affine in the triangle, so
// interpolating them along the edge gives the very line the fragment shader's mask cuts along.
void MeshBuilder::add_cut_skirts() {
  std::unordered_set<std::uint64_t> cut_edges;  // an edge on a mid line is cut once
  // A triangle that does not reach a mid line has no cross-section with it.
  for (const std::uint32_t i : reach_mid_x_) cut_triangle(drawn_[i], true, cut_edges);
  for (const std::uint32_t i : reach_mid_y_) cut_triangle(drawn_[i], false, cut_edges);
  for (std::size_t g = 0; g < 4; ++g) {
    mesh_.cut_index_count[g] = static_cast<std::uint32_t>(cut_triangles_[g].size());
    skirt_triangles_.insert(skirt_triangles_.end(), cut_triangles_[g].begin(),
                            cut_triangles_[g].end());
    mesh_.skirt_spans.insert(mesh_.skirt_spans.end(), cut_spans_[g].begin(), cut_spans_[g].end());
  }
}

// Indices: surface first, then skirts; 16-bit when every index fits.
void MeshBuilder::write_indices() {
  const std::size_t total = drawn_.size() * 3 + skirt_triangles_.size();
  mesh_.surface_index_count = static_cast<std::uint32_t>(drawn_.size() * 3);
  const auto fill = [&](auto& out) {
    out.resize(total);
    using T = typename std::remove_reference_t<decltype(out)>::value_type;
    T* next = out.data();
    for (const tile::Triangle& t : drawn_)
      for (const std::uint32_t v : t) *next++ = static_cast<T>(v);
    for (const std::uint32_t v : skirt_triangles_) *next++ = static_cast<T>(v);
  };
  if (mesh_.vertices.size() <= 65536) {
    fill(mesh_.indices16);
  } else {
    fill(mesh_.indices32);
  }
}

// The box holds every vertex drawn (used surface vertices and all skirt vertices) and the whole
// tile at the heights of its data: the NODATA corners with their heights clamped into the range of
// the data vertices (a legacy corner at 0 m does not stretch the box down to the ellipsoid). The
// streamer culls and measures distances with this box, and a tile's children may have data where
// it draws nothing — at a coarse level a tile's footprint can even be empty (a few data vertices,
// every triangle touching a NODATA corner), and a box of drawn vertices alone then sat at the
// tile's centre, so the tile was culled and never refined.
void MeshBuilder::fit_bounds() {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < vertices_.size(); ++i) {
    if (tile_.is_nodata_vertex(i)) continue;
    lo = std::min(lo, vertices_[i].z);
    hi = std::max(hi, vertices_[i].z);
  }
  std::vector<Vec3> points;
  points.reserve(vertices_.size() + skirt_points_.size());
  for (std::size_t i = 0; i < vertices_.size(); ++i) {
    if (used_[i] || !tile_.is_nodata_vertex(i)) {
      points.push_back(ecef_[i]);
    } else if (lo <= hi) {
      points.push_back(terms_[i].ecef(std::clamp(vertices_[i].z, lo, hi)));
    }
  }
  points.insert(points.end(), skirt_points_.begin(), skirt_points_.end());
  if (points.empty()) points.push_back(mesh_.centre);
  mesh_.bounds = fit_obb(points, mesh_.centre, mesh_.frame);
}

}  // namespace

TileMesh build_render_mesh(const tile::TinTile& tile, const LayerDescription& layer, TileKey key) {
  return MeshBuilder(tile, layer, key).build();
}

Result<TileMesh> decode_render_mesh(std::span<const std::uint8_t> payload, ContentEncoding encoding,
                                    const LayerDescription& layer, TileKey key) {
  const std::string name = "tile " + key.tile.quadkey() + " (" + key.tile.to_string() +
                           ") of layer \"" + layer.name + "\"";
  auto raw = inflate_payload(payload, encoding);
  if (!raw) return Error(raw.error().code, name + ": " + raw.error().message);
  auto decoded = tile::decode(*raw);
  if (!decoded) return Error(decoded.error().code, name + ": " + decoded.error().message);
  if (decoded->id != key.tile)
    return corrupt_data(name + ": the payload holds tile " + decoded->id.to_string());
  return build_render_mesh(*decoded, layer, key);
}

}  // namespace tinstream::client
