#include "tinstream/terrain/quantized_mesh.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "grid_tile.hpp"
#include "qm_decoder.hpp"
#include "tinstream/terrain/gzip.hpp"

namespace tinstream::terrain {
namespace {

using testing::decode_quantized_mesh;
using testing::DecodedMesh;
using testing::make_grid_tile;
using testing::synthetic_height;

// Independent WGS84 geodetic → ECEF (textbook formula), degrees and metres.
std::array<double, 3> ecef_of(double lon, double lat, double h) {
  const double a = 6378137.0, f = 1 / 298.257223563, e2 = f * (2 - f);
  const double lo = lon * M_PI / 180, la = lat * M_PI / 180;
  const double nrad = a / std::sqrt(1 - e2 * std::sin(la) * std::sin(la));
  return {(nrad + h) * std::cos(la) * std::cos(lo), (nrad + h) * std::cos(la) * std::sin(lo),
          (nrad * (1 - e2) + h) * std::sin(la)};
}

struct Decoded {
  DecodedMesh mesh;
  geo::LonLatRect rect;
  double lon(std::uint32_t i) const {
    return rect.west + (rect.east - rect.west) * mesh.u[i] / 32767.0;
  }
  double lat(std::uint32_t i) const {
    return rect.south + (rect.north - rect.south) * mesh.v[i] / 32767.0;
  }
  double height(std::uint32_t i) const {
    return mesh.min_height +
           (static_cast<double>(mesh.max_height) - mesh.min_height) * mesh.h[i] / 32767.0;
  }
  double height_step() const {
    return (static_cast<double>(mesh.max_height) - mesh.min_height) / 32767.0;
  }
};

const geo::TileId kTile = *geo::TileId::from_zxy(12, 2120, 1400);  // near Luxembourg

Decoded encode_decode(const tile::TinTile& t, bool normals = false) {
  auto bytes = encode_quantized_mesh(t, geo::Projection::spherical, {normals});
  EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
  Decoded d{decode_quantized_mesh(*bytes), t.id.lonlat_bounds(geo::NormalisedMercator())};
  return d;
}

TEST(QuantizedMesh, HeaderAndVerticesDecodeToTheTileSurface) {
  const auto t = make_grid_tile(kTile, 17, synthetic_height);
  const Decoded d = encode_decode(t);
  ASSERT_EQ(d.mesh.u.size(), 17u * 17u);
  EXPECT_FLOAT_EQ(d.mesh.min_height, static_cast<float>(t.min_z));
  EXPECT_FLOAT_EQ(d.mesh.max_height, static_cast<float>(t.max_z));
  // Every decoded vertex is one of the tile's vertices: lon/lat within a quantisation step,
  // height within a height step.
  const geo::NormalisedMercator merc;
  std::vector<tile::Vertex> src = {t.corners.begin(), t.corners.end()};
  for (const auto* l : {&t.north, &t.east, &t.south, &t.west, &t.interior})
    src.insert(src.end(), l->begin(), l->end());
  const double du = (d.rect.east - d.rect.west) / 32767.0,
               dv = (d.rect.north - d.rect.south) / 32767.0;
  std::set<std::size_t> matched;
  for (std::uint32_t i = 0; i < d.mesh.u.size(); ++i) {
    bool found = false;
    for (std::size_t k = 0; k < src.size() && !found; ++k) {
      const geo::LonLat ll = merc.inverse({src[k].x, src[k].y});
      if (std::abs(ll.lon - d.lon(i)) <= du && std::abs(ll.lat - d.lat(i)) <= dv &&
          std::abs(src[k].z - d.height(i)) <= d.height_step() + 1e-3) {
        found = true;
        matched.insert(k);
      }
    }
    EXPECT_TRUE(found) << "vertex " << i;
  }
  EXPECT_EQ(matched.size(), src.size());
  // Centre: the ECEF of the rectangle's centre at mid height.
  const auto c = ecef_of((d.rect.west + d.rect.east) / 2, (d.rect.south + d.rect.north) / 2,
                         (t.min_z + t.max_z) / 2);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(d.mesh.centre[k], c[static_cast<std::size_t>(k)], 1e-3);
}

TEST(QuantizedMesh, VIsLinearInLatitudeNotMercator) {
  const auto t = make_grid_tile(kTile, 9, synthetic_height);
  const Decoded d = encode_decode(t);
  const geo::NormalisedMercator merc;
  // The middle interior row in Mercator is at y = mid; in latitude it is not the middle.
  const tile::Vertex& mid = t.interior[3 * 7 + 3];  // i = 4, j = 4 of a 9×9 grid
  const double lat = merc.lat_from_y(mid.y);
  const double expected_v = (lat - d.rect.south) / (d.rect.north - d.rect.south) * 32767.0;
  const double mercator_v = 0.5 * 32767.0;
  bool found = false;
  for (std::uint32_t i = 0; i < d.mesh.u.size(); ++i) {
    if (d.mesh.u[i] == 16384 || d.mesh.u[i] == 16383) {
      if (std::abs(d.mesh.v[i] - expected_v) <= 0.5) found = true;
    }
  }
  EXPECT_TRUE(found);
  EXPECT_GT(std::abs(expected_v - mercator_v), 1.0) << "test tile too small to tell the two apart";
}

TEST(QuantizedMesh, TrianglesInRangeAndCounterClockwise) {
  const auto t = make_grid_tile(kTile, 17, synthetic_height);
  const Decoded d = encode_decode(t);
  ASSERT_EQ(d.mesh.indices.size(), t.triangles.size() * 3);
  for (std::size_t k = 0; k < d.mesh.indices.size(); k += 3) {
    const std::uint32_t a = d.mesh.indices[k], b = d.mesh.indices[k + 1], c = d.mesh.indices[k + 2];
    ASSERT_LT(a, d.mesh.u.size());
    ASSERT_LT(b, d.mesh.u.size());
    ASSERT_LT(c, d.mesh.u.size());
    const double cross = (static_cast<double>(d.mesh.u[b]) - d.mesh.u[a]) *
                             (static_cast<double>(d.mesh.v[c]) - d.mesh.v[a]) -
                         (static_cast<double>(d.mesh.v[b]) - d.mesh.v[a]) *
                             (static_cast<double>(d.mesh.u[c]) - d.mesh.u[a]);
    EXPECT_GT(cross, 0) << "triangle " << k / 3;
  }
}

TEST(QuantizedMesh, EdgeListsHoldExactlyTheBorderVertices) {
  const auto t = make_grid_tile(kTile, 17, synthetic_height);
  const Decoded d = encode_decode(t);
  auto check = [&](const std::vector<std::uint32_t>& list, auto on_side, const char* name) {
    std::set<std::uint32_t> in(list.begin(), list.end());
    EXPECT_EQ(in.size(), list.size()) << name << " has duplicates";
    for (std::uint32_t i = 0; i < d.mesh.u.size(); ++i) {
      EXPECT_EQ(on_side(i), in.count(i) == 1) << name << " vertex " << i;
    }
    EXPECT_EQ(list.size(), 17u) << name;
  };
  check(
      d.mesh.west, [&](std::uint32_t i) { return d.mesh.u[i] == 0; }, "west");
  check(
      d.mesh.east, [&](std::uint32_t i) { return d.mesh.u[i] == 32767; }, "east");
  check(
      d.mesh.south, [&](std::uint32_t i) { return d.mesh.v[i] == 0; }, "south");
  check(
      d.mesh.north, [&](std::uint32_t i) { return d.mesh.v[i] == 32767; }, "north");
}

// Border vertices of neighbours coincide in lon, lat and (within both height steps) height.
void expect_shared_border(const Decoded& a, const std::vector<std::uint32_t>& a_list,
                          const Decoded& b, const std::vector<std::uint32_t>& b_list) {
  ASSERT_EQ(a_list.size(), b_list.size());
  for (std::uint32_t i : a_list) {
    bool found = false;
    for (std::uint32_t j : b_list) {
      if (std::abs(a.lon(i) - b.lon(j)) < 1e-9 && std::abs(a.lat(i) - b.lat(j)) < 1e-9) {
        found = true;
        EXPECT_NEAR(a.height(i), b.height(j), a.height_step() + b.height_step() + 1e-3);
      }
    }
    EXPECT_TRUE(found) << "border vertex " << i << " at " << a.lon(i) << "," << a.lat(i);
  }
}

TEST(QuantizedMesh, NeighbourTilesShareTheirEdgeVertices) {
  const auto east_id = *kTile.neighbour(geo::Direction::east);
  const auto south_id = *kTile.neighbour(geo::Direction::south);
  const Decoded d = encode_decode(make_grid_tile(kTile, 17, synthetic_height));
  const Decoded e = encode_decode(make_grid_tile(east_id, 17, synthetic_height));
  const Decoded s = encode_decode(make_grid_tile(south_id, 17, synthetic_height));
  expect_shared_border(d, d.mesh.east, e, e.mesh.west);
  expect_shared_border(d, d.mesh.south, s, s.mesh.north);
}

bool occluded(const double camera[3], const double point[3]) {
  // Cesium's EllipsoidalOccluder.isScaledSpacePointVisible, negated; all in scaled space.
  const double cv2 = camera[0] * camera[0] + camera[1] * camera[1] + camera[2] * camera[2];
  const double vh2 = cv2 - 1.0;
  const double vt[3] = {point[0] - camera[0], point[1] - camera[1], point[2] - camera[2]};
  const double vt_dot_vc = -(vt[0] * camera[0] + vt[1] * camera[1] + vt[2] * camera[2]);
  const double vt2 = vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2];
  return vt_dot_vc > vh2 && vt_dot_vc * vt_dot_vc / vt2 > vh2;
}

TEST(QuantizedMesh, BoundingSphereAndHorizonPointAreConservative) {
  const auto t = make_grid_tile(kTile, 17, synthetic_height);
  const Decoded d = encode_decode(t);
  const double a = 6378137.0, b = a * (1 - 1 / 298.257223563);
  std::vector<std::array<double, 3>> pts;
  for (std::uint32_t i = 0; i < d.mesh.u.size(); ++i)
    pts.push_back(ecef_of(d.lon(i), d.lat(i), d.height(i)));
  for (const auto& p : pts) {
    const double dist = std::hypot(p[0] - d.mesh.sphere_centre[0], p[1] - d.mesh.sphere_centre[1],
                                   p[2] - d.mesh.sphere_centre[2]);
    EXPECT_LE(dist, d.mesh.sphere_radius + 1e-3);
  }
  ASSERT_TRUE(std::isfinite(d.mesh.horizon_point[0]));
  // Whenever the occlusion point is hidden behind the horizon, every vertex is hidden too.
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), dist(1.0005, 3.0);
  int hidden = 0;
  for (int k = 0; k < 20000; ++k) {
    double c[3] = {unit(rng), unit(rng), unit(rng)};
    const double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    const double r = dist(rng);
    for (double& x : c) x *= r / len;
    if (!occluded(c, d.mesh.horizon_point)) continue;
    ++hidden;
    for (const auto& p : pts) {
      const double s[3] = {p[0] / a, p[1] / a, p[2] / b};
      ASSERT_TRUE(occluded(c, s)) << "a vertex is visible while the occlusion point is hidden";
    }
  }
  EXPECT_GT(hidden, 1000);
}

TEST(QuantizedMesh, OctVertexNormalsPointAwayFromTheEarth) {
  const auto t = make_grid_tile(kTile, 17, synthetic_height);
  const Decoded d = encode_decode(t, true);
  ASSERT_TRUE(d.mesh.oct_normals.has_value());
  for (std::uint32_t i = 0; i < d.mesh.u.size(); ++i) {
    double n[3];
    testing::oct_decode((*d.mesh.oct_normals)[std::size_t{2} * i],
                        (*d.mesh.oct_normals)[std::size_t{2} * i + 1], n);
    const double lo = d.lon(i) * M_PI / 180, la = d.lat(i) * M_PI / 180;
    const double up[3] = {std::cos(la) * std::cos(lo), std::cos(la) * std::sin(lo), std::sin(la)};
    EXPECT_GT(n[0] * up[0] + n[1] * up[1] + n[2] * up[2], 0.95) << "vertex " << i;
  }
  // Without the option, no extension.
  EXPECT_FALSE(encode_decode(t, false).mesh.oct_normals.has_value());
}

TEST(QuantizedMesh, ThirtyTwoBitIndicesAbove65536Vertices) {
  const auto t = make_grid_tile(kTile, 258, synthetic_height);  // 66564 vertices
  const Decoded d = encode_decode(t);
  EXPECT_TRUE(d.mesh.wide_indices);
  EXPECT_EQ(d.mesh.u.size(), 258u * 258u);
  EXPECT_EQ(d.mesh.indices.size(), t.triangles.size() * 3);
  for (std::uint32_t i : d.mesh.indices) ASSERT_LT(i, d.mesh.u.size());
  EXPECT_EQ(d.mesh.west.size(), 258u);
}

// The grid tile with its triangles shuffled and each one rotated (orientation kept): the same
// surface as a tile store could hold it after any re-triangulation.
tile::TinTile shuffled(tile::TinTile t, unsigned seed) {
  std::mt19937 rng(seed);
  std::shuffle(t.triangles.begin(), t.triangles.end(), rng);
  for (auto& tr : t.triangles) {
    for (auto r = rng() % 3; r > 0; --r) tr = {tr[1], tr[2], tr[0]};
  }
  return t;
}

TEST(QuantizedMesh, StoredTriangleOrderAndRotationDoNotChangeTheBytes) {
  const auto grid = make_grid_tile(kTile, 40, synthetic_height);
  const auto a = encode_quantized_mesh(shuffled(grid, 1), geo::Projection::spherical, {true});
  const auto b = encode_quantized_mesh(shuffled(grid, 2), geo::Projection::spherical, {true});
  const auto c = encode_quantized_mesh(grid, geo::Projection::spherical, {true});
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(*a, *b);
  EXPECT_EQ(*a, *c);
}

// The written order is a walk across shared edges (what makes the high-water-mark codes and the
// vertex deltas small and gzip effective), whatever order the tile stores.
TEST(QuantizedMesh, TrianglesAreWrittenAsAWalkAcrossSharedEdges) {
  const auto t = shuffled(make_grid_tile(kTile, 64, synthetic_height), 7);
  const Decoded d = encode_decode(t);
  const auto& ix = d.mesh.indices;
  const std::size_t m = ix.size() / 3;
  ASSERT_EQ(m, t.triangles.size());
  std::size_t sharing = 0;
  for (std::size_t k = 0; k < m; ++k) {
    const std::uint32_t* tr = &ix[3 * k];
    if (k > 0) {
      const std::uint32_t* prev = &ix[3 * (k - 1)];
      int common = 0;
      for (int i = 0; i < 3; ++i) common += std::count(prev, prev + 3, tr[i]) > 0;
      sharing += common == 2;
    }
    // Each triangle starts at its vertex written earliest (indices are numbered by first use).
    EXPECT_TRUE(tr[0] < tr[1] && tr[0] < tr[2])
        << "triangle " << k << ": " << tr[0] << " " << tr[1] << " " << tr[2];
  }
  // A depth-first walk only leaves the last triangle's neighbourhood when it backs up.
  EXPECT_GE(static_cast<double>(sharing) / static_cast<double>(m - 1), 0.9)
      << sharing << " of " << m - 1 << " consecutive pairs share an edge";
}

// Regression (real-data test, level-2 tile over Luxembourg): a sliver that is counter-clockwise in
// exact lon/lat can turn clockwise on the 15-bit grid; it must be left out, not written CW.
TEST(QuantizedMesh, SliversThatQuantisationTurnsClockwiseAreLeftOut) {
  const geo::TileId id = *geo::TileId::from_zxy(2, 2, 1);
  const geo::NormalisedMercator merc;
  const geo::LonLatRect r = id.lonlat_bounds(merc);
  auto q = [](double t) { return std::round(t * 32767.0); };
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-1.5, 1.5);
  const double cu = 16000.3, cv = 16000.7;  // somewhere inside, in quanta
  for (int attempt = 0; attempt < 200000; ++attempt) {
    double uv[3][2];
    for (auto& p : uv) p[0] = cu + jitter(rng), p[1] = cv + jitter(rng);
    auto orient = [](const double a[2], const double b[2], const double c[2]) {
      return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    };
    double rounded[3][2];
    for (int k = 0; k < 3; ++k)
      rounded[k][0] = q(uv[k][0] / 32767.0), rounded[k][1] = q(uv[k][1] / 32767.0);
    if (!(orient(uv[0], uv[1], uv[2]) > 0.05 && orient(rounded[0], rounded[1], rounded[2]) < 0))
      continue;
    // Found one: build a tile of the two corner triangles plus the sliver.
    tile::TinTile t = flat_tile(id);
    for (auto& p : uv) {
      const double lon = r.west + (r.east - r.west) * p[0] / 32767.0;
      const double lat = r.south + (r.north - r.south) * p[1] / 32767.0;
      const geo::MercatorXY m = merc.forward({lon, lat});
      t.interior.push_back({m.x, m.y, 10.0, 1.0});
    }
    t.triangles.push_back({4, 5, 6});
    auto bytes = encode_quantized_mesh(t, geo::Projection::spherical);
    ASSERT_TRUE(bytes.ok());
    const auto m = decode_quantized_mesh(*bytes);
    EXPECT_EQ(m.indices.size(), 6u) << "the clockwise sliver was written";
    for (std::size_t k = 0; k < m.indices.size(); k += 3) {
      const auto a = m.indices[k], b = m.indices[k + 1], c = m.indices[k + 2];
      const double cross =
          (static_cast<double>(m.u[b]) - m.u[a]) * (static_cast<double>(m.v[c]) - m.v[a]) -
          (static_cast<double>(m.v[b]) - m.v[a]) * (static_cast<double>(m.u[c]) - m.u[a]);
      EXPECT_GE(cross, 0);
    }
    EXPECT_EQ(m.u.size(), 7u);  // the sliver's vertices stay (unused)
    return;
  }
  FAIL() << "no sliver found to test with";
}

// #20: a triangle whose vertices round to one quantum (edge points closer than a quantum, coarse
// tiles over dense data) has zero area in (u, v): it draws nothing, and a client interpolating
// a height in it divides by its area. It is left out like a clockwise sliver.
TEST(QuantizedMesh, TrianglesThatQuantisationFlattensAreLeftOut) {
  const geo::TileId id = *geo::TileId::from_zxy(2, 2, 1);
  const geo::NormalisedMercator merc;
  const geo::LonLatRect r = id.lonlat_bounds(merc);
  tile::TinTile t = flat_tile(id);
  // Counter-clockwise in doubles, all three within the quantum around (16000, 16000).
  for (const auto& p :
       {std::array{16000.1, 16000.1}, std::array{16000.3, 16000.1}, std::array{16000.1, 16000.3}}) {
    const double lon = r.west + (r.east - r.west) * p[0] / 32767.0;
    const double lat = r.south + (r.north - r.south) * p[1] / 32767.0;
    const geo::MercatorXY m = merc.forward({lon, lat});
    t.interior.push_back({m.x, m.y, 10.0, 1.0});
  }
  t.triangles.push_back({4, 5, 6});
  auto bytes = encode_quantized_mesh(t, geo::Projection::spherical);
  ASSERT_TRUE(bytes.ok());
  const auto m = decode_quantized_mesh(*bytes);
  ASSERT_EQ(m.u.size(), 7u);
  EXPECT_EQ(m.u[4], m.u[5]);  // the three vertices did share a quantum (unused ones come last)
  EXPECT_EQ(m.v[4], m.v[6]);
  EXPECT_EQ(m.indices.size(), 6u) << "the flat triangle was written";
  for (std::size_t k = 0; k < m.indices.size(); k += 3) {
    const auto a = m.indices[k], b = m.indices[k + 1], c = m.indices[k + 2];
    const double cross =
        (static_cast<double>(m.u[b]) - m.u[a]) * (static_cast<double>(m.v[c]) - m.v[a]) -
        (static_cast<double>(m.v[b]) - m.v[a]) * (static_cast<double>(m.u[c]) - m.u[a]);
    EXPECT_GT(cross, 0);
  }
}

TEST(QuantizedMesh, EllipsoidalLayersAreRefused) {
  const auto t = make_grid_tile(kTile, 5, synthetic_height);
  auto r = encode_quantized_mesh(t, geo::Projection::ellipsoidal);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::unsupported);
}

TEST(QuantizedMesh, TileWithoutTrianglesIsAnError) {
  tile::TinTile t = make_grid_tile(kTile, 3, synthetic_height);
  t.triangles.clear();
  EXPECT_FALSE(encode_quantized_mesh(t, geo::Projection::spherical).ok());
  t = make_grid_tile(kTile, 3, synthetic_height);
  t.triangles[0][1] = 999;
  EXPECT_FALSE(encode_quantized_mesh(t, geo::Projection::spherical).ok());
}

TEST(QuantizedMesh, FlatTileCoversTheTile) {
  const auto t = flat_tile(*geo::TileId::from_zxy(1, 1, 0));
  auto bytes = encode_quantized_mesh(t, geo::Projection::spherical);
  ASSERT_TRUE(bytes.ok());
  const auto m = decode_quantized_mesh(*bytes);
  EXPECT_EQ(m.u.size(), 4u);
  EXPECT_EQ(m.indices.size(), 6u);
  EXPECT_EQ(m.west.size(), 2u);
  EXPECT_EQ(m.north.size(), 2u);
}

// A stored tile's rectangle: its corners at the given heights (NW, NE, SW, SE), no triangles
// needed (filler_tile reads borders only).
tile::TinTile stored_corners(const geo::TileId& id, std::array<double, 4> z) {
  tile::TinTile t = flat_tile(id);
  for (int k = 0; k < 4; ++k) t.corners[k].z = z[k];
  return t;
}

TEST(FillerTile, TakesItsStoredNeighboursBorderAndIsAValidTile) {
  const geo::TileId id = *geo::TileId::from_zxy(2, 1, 1);
  const geo::TileId east = *geo::TileId::from_zxy(2, 2, 1),
                    south_west = *geo::TileId::from_zxy(2, 0, 2);
  tile::TinTile e = stored_corners(east, {100, 7, 200, 7});
  const geo::MercatorRect er = east.bounds();
  e.west.push_back({er.min_x, (er.min_y + er.max_y) / 2, 150, 0});
  const tile::TinTile d = stored_corners(south_west, {7, 300, 7, 7});
  int asked = 0;
  auto filler =
      filler_tile(id, 2, [&](const geo::TileId& n) -> Result<std::optional<tile::TinTile>> {
        ++asked;
        if (n == east) return std::optional<tile::TinTile>(e);
        if (n == south_west) return std::optional<tile::TinTile>(d);
        return std::optional<tile::TinTile>();
      });
  ASSERT_TRUE(filler.ok()) << filler.error().message;
  EXPECT_EQ(asked, 8);
  const tile::TinTile& f = *filler;
  EXPECT_TRUE(tile::check_structure(f).ok()) << tile::check_structure(f).error().message;
  EXPECT_EQ(f.corners[0].z, 0.0);    // NW: no stored tile touches it
  EXPECT_EQ(f.corners[1].z, 100.0);  // NE = east's NW
  EXPECT_EQ(f.corners[2].z, 300.0);  // SW = south-west's NE
  EXPECT_EQ(f.corners[3].z, 200.0);  // SE = east's SW
  ASSERT_EQ(f.east.size(), 1u);
  EXPECT_EQ(f.east[0].x, er.min_x);
  EXPECT_EQ(f.east[0].y, e.west[0].y);
  EXPECT_EQ(f.east[0].z, 150.0);
  EXPECT_TRUE(f.north.empty() && f.south.empty() && f.west.empty());
  EXPECT_EQ(f.triangles.size(), 5u);  // the border's five points fanned to the centre
  EXPECT_TRUE(encode_quantized_mesh(f, geo::Projection::spherical).ok());
}

TEST(FillerTile, WrapsAroundTheAntimeridianAndIsFlatWithoutStoredNeighbours) {
  const geo::TileId id = *geo::TileId::from_zxy(1, 1, 0), other = *geo::TileId::from_zxy(1, 0, 0);
  tile::TinTile o = stored_corners(other, {500, 8, 600, 8});
  o.west.push_back(
      {other.bounds().min_x, (other.bounds().min_y + other.bounds().max_y) / 2, 550, 0});
  auto filler =
      filler_tile(id, 1, [&](const geo::TileId& n) -> Result<std::optional<tile::TinTile>> {
        if (n == other) return std::optional<tile::TinTile>(o);
        return std::optional<tile::TinTile>();
      });
  ASSERT_TRUE(filler.ok());
  EXPECT_TRUE(tile::check_structure(*filler).ok());
  // The east side (x = 1) is the other tile's west side (x = −1); the west side its east side.
  EXPECT_EQ(filler->corners[1].z, 500.0);
  EXPECT_EQ(filler->corners[3].z, 600.0);
  EXPECT_EQ(filler->corners[0].z, 8.0);
  ASSERT_EQ(filler->east.size(), 1u);
  EXPECT_EQ(filler->east[0].x, 1.0);
  EXPECT_EQ(filler->east[0].z, 550.0);

  auto flat = filler_tile(id, 1, [](const geo::TileId&) -> Result<std::optional<tile::TinTile>> {
    return std::optional<tile::TinTile>();
  });
  ASSERT_TRUE(flat.ok());
  EXPECT_EQ(flat->triangles, flat_tile(id).triangles);
  auto failing = filler_tile(id, 1, [](const geo::TileId&) -> Result<std::optional<tile::TinTile>> {
    return Error(ErrorCode::corrupt_data, "tile 1/0/0: broken blob");
  });
  ASSERT_FALSE(failing.ok());
  EXPECT_NE(failing.error().message.find("broken blob"), std::string::npos);
}

TEST(FillerTile, AboveTheCoarsestStoredLevelAsksForNoNeighbour) {
  // No stored tile of level 2 where the layer's coarsest level is 3: the same tile as when every
  // lookup finds nothing, without a lookup.
  const geo::TileId id = *geo::TileId::from_zxy(2, 1, 1);
  int asked = 0;
  const StoredTileLookup nothing = [&](const geo::TileId&) -> Result<std::optional<tile::TinTile>> {
    ++asked;
    return std::optional<tile::TinTile>();
  };
  auto looked_up = filler_tile(id, 2, nothing);
  ASSERT_TRUE(looked_up.ok());
  EXPECT_EQ(asked, 8);
  asked = 0;
  auto skipped = filler_tile(id, 3, nothing);
  ASSERT_TRUE(skipped.ok());
  EXPECT_EQ(asked, 0);
  EXPECT_EQ(skipped->triangles, looked_up->triangles);
  EXPECT_EQ(skipped->interior.size(), looked_up->interior.size());
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(skipped->corners[k].x, looked_up->corners[k].x);
    EXPECT_EQ(skipped->corners[k].y, looked_up->corners[k].y);
    EXPECT_EQ(skipped->corners[k].z, looked_up->corners[k].z);
  }
  EXPECT_EQ(skipped->triangles, flat_tile(id).triangles);
}

std::vector<std::uint8_t> independent_gunzip(const std::vector<std::uint8_t>& gz) {
  z_stream zs{};
  EXPECT_EQ(inflateInit2(&zs, 31), Z_OK);
  std::vector<std::uint8_t> out(1 << 22);
  zs.next_in = const_cast<Bytef*>(gz.data());
  zs.avail_in = static_cast<uInt>(gz.size());
  zs.next_out = out.data();
  zs.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(inflate(&zs, Z_FINISH), Z_STREAM_END);
  out.resize(zs.total_out);
  inflateEnd(&zs);
  return out;
}

// Found by qmesh_fuzzer (core/terrain/fuzz/regressions): a vertex whose triangles are all
// degenerate has a zero normal, normalised to NaN, which oct_encode cast to a byte (undefined
// behaviour; UBSan aborts). It is encoded as "up" now, like Cesium's default.
TEST(QuantizedMesh, OctEncodeOfAMissingNormalIsUp) {
  const auto up = oct_encode({0, 0, 1});
  EXPECT_EQ(up, (std::array<std::uint8_t, 2>{128, 128}));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(oct_encode({nan, 0, 0}), up);
  EXPECT_EQ(oct_encode({0, 0, 0}), up);
  EXPECT_EQ(oct_encode({std::numeric_limits<double>::infinity(), 1, 0}), up);
}

TEST(Gzip, RoundTripsAndRewrapsZlib) {
  std::vector<std::uint8_t> data(100000);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>((i * 7) % 251);
  const auto gz = gzip_compress(data);
  EXPECT_EQ(independent_gunzip(gz), data);
  EXPECT_EQ(*gzip_decompress(gz), data);

  std::vector<std::uint8_t> zl(compressBound(static_cast<uLong>(data.size())));
  uLongf len = static_cast<uLongf>(zl.size());
  ASSERT_EQ(compress2(zl.data(), &len, data.data(), static_cast<uLong>(data.size()), 6), Z_OK);
  zl.resize(len);
  auto rewrapped = zlib_to_gzip(zl);
  ASSERT_TRUE(rewrapped.ok());
  EXPECT_EQ(independent_gunzip(*rewrapped), data);

  EXPECT_FALSE(zlib_to_gzip(std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6, 7}).ok());
  auto truncated = gz;
  truncated.resize(gz.size() / 2);
  EXPECT_FALSE(gzip_decompress(truncated).ok());
  EXPECT_FALSE(gzip_decompress(gz, 1000).ok());
}

}  // namespace
}  // namespace tinstream::terrain
