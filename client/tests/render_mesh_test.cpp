// Native tile → render mesh, checked against docs/tile-format.md and independent geodesy.
#include "tinstream/client/render_mesh.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>

#include "grid_tile.hpp"
#include "tinstream/geo/ecef.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::client {
namespace {

constexpr double kPi = std::numbers::pi;

// Spherical normalised Mercator inverse written out (docs/DESIGN.md §2):
// λ = πx, φ = atan(sinh(πy)).
Vec3 expected_ecef(double x, double y, double z) {
  const double lon = x * 180.0, lat = std::atan(std::sinh(kPi * y)) * 180.0 / kPi;
  const geo::Ecef e = geo::to_ecef({lon, lat, z});
  return {e.x, e.y, e.z};
}

Vec3 world_of(const TileMesh& m, std::size_t i) {
  const MeshVertex& v = m.vertices[i];
  return m.centre + Vec3{v.position[0], v.position[1], v.position[2]};
}

LayerDescription layer_for(const geo::TileId& id) {
  LayerDescription l;
  l.name = "t";
  l.min_level = 0;
  l.max_level = id.z + 2;
  l.level_max_error.assign(l.max_level + 1, 1.0);
  return l;
}

std::uint32_t index_at(const TileMesh& m, std::size_t i) {
  return m.indices16.empty() ? m.indices32[i] : m.indices16[i];
}

Vec3 unpack_normal(std::uint32_t n) {
  const auto comp = [&](int shift) {
    int v = static_cast<int>((n >> shift) & 0x3FF);
    if (v >= 512) v -= 1024;
    return v / 511.0;
  };
  return {comp(0), comp(10), comp(20)};
}

TEST(RenderMesh, SpecWorldTileDecodes) {
  std::ifstream in(
      std::string(TINSTREAM_SOURCE_DIR) + "/core/tile/fuzz/corpus/world_two_triangles.tint",
      std::ios::binary);
  ASSERT_TRUE(in) << "seed corpus file missing";
  const std::vector<std::uint8_t> bytes{std::istreambuf_iterator<char>(in), {}};
  const TileKey key{TileKind::terrain, 0, {0, 0, 0}};
  auto mesh = decode_render_mesh(bytes, ContentEncoding::identity, layer_for({0, 0, 0}), key);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  auto tile = tile::decode(bytes);
  ASSERT_TRUE(tile.ok());
  EXPECT_EQ(mesh->data_triangles, 2u);
  EXPECT_EQ(mesh->surface_index_count, 6u);
  // The spec's triangles (SW, SE, NE), (SW, NE, NW) in order.
  const std::uint32_t expected[6] = {2, 3, 1, 2, 1, 0};
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(index_at(*mesh, i), expected[i]);
  // Corners at (∓1, ±1) in normalised Mercator; floats relative to a centre on the equator hold
  // the world tile to about a metre.
  const double cx[4] = {-1, 1, -1, 1}, cy[4] = {1, 1, -1, -1};
  for (std::size_t i = 0; i < 4; ++i) {
    const Vec3 want = expected_ecef(cx[i], cy[i], tile->corners[i].z);
    EXPECT_LT(length(world_of(*mesh, i) - want), 1.0) << "corner " << i;
  }
  // Four sides, each one segment: four skirt quads under the four corners. The diagonal SW–NE
  // crosses both mid lines at the centre: each half-line is one cut quad (4 vertices each).
  EXPECT_EQ(mesh->vertices.size(), 8u + 4 * 4);
  EXPECT_EQ(mesh->index_count(), 6u + 4 * 6 + 4 * 6);
  EXPECT_EQ(mesh->cut_index_count, (std::array<std::uint32_t, 4>{6, 6, 6, 6}));
}

TEST(RenderMesh, FastEcefAgreesWithGeographicLib) {
  // GeodeticTerms (no degrees; expm1/sqrt or sinh/tauf/hypot, one sincos) against
  // geo::to_ecef(projection.inverse) (GeographicLib's degree functions and Geocentric) on a 129 ×
  // 129 grid over the whole map, both projections, heights from the Dead Sea to above Everest, and
  // the map's corners and axes exactly. Measured: 2.8e-9 m at worst (rounding of ~6.4e6 m
  // coordinates); bound 1e-8 m, far below what the mesh keeps (floats relative to a level-20 tile's
  // centre: ~4 µm). An error in the formulas (e² or the sign of the eccentricity, degrees for
  // radians, N(φ) without the 1 − e² on z) is metres to kilometres off.
  double worst = 0;
  for (const geo::Projection p : {geo::Projection::spherical, geo::Projection::ellipsoidal}) {
    const geo::NormalisedMercator projection(p);
    for (int i = 0; i <= 128; ++i)
      for (int j = 0; j <= 128; ++j)
        for (const double h : {-430.5, 0.0, 1234.567, 9000.0}) {
          const double x = -1 + i / 64.0, y = -1 + j / 64.0;
          const geo::LonLat ll = projection.inverse({x, y});
          const geo::Ecef want = geo::to_ecef({ll.lon, ll.lat, h});
          const Vec3 got = GeodeticTerms::from_mercator(projection, x, y).ecef(h);
          worst = std::max({worst, std::abs(got.x - want.x), std::abs(got.y - want.y),
                            std::abs(got.z - want.z)});
        }
  }
  EXPECT_LT(worst, 1e-8) << "metres";
  EXPECT_GT(worst, 0.0);  // the paths differ (GeographicLib's was not called twice)
}

TEST(RenderMesh, SphericalLatitudeTermsAgreeWithSinhAndHypotWithinFourUlps) {
  // On a spherical layer GeodeticTerms takes cos φ = sech πy and sin φ = tanh πy from one expm1
  // of 2π|y| (no sinh, no hypot). Against the sinh/hypot formulation it replaced (written out
  // here), over 2²⁰ + 1 rows from pole to pole: within 4 ulps of 1 (8.9e-16; 6e-9 m of ECEF at
  // most). Taking expm1 of 2πy with its sign (no |y|) cancels in t + 1 towards the south pole
  // and is ~6 ulps off there. With it, the render meshes of the test stores kept every normal,
  // height, uv and index and all but 465 of 7.5 M position floats, each of those at most one
  // float step or 1e-8 m away (bench/client/RESULTS.md, 2026-11-28 11:20).
  const geo::NormalisedMercator projection(geo::Projection::spherical);
  double worst = 0;
  for (int j = 0; j <= 1 << 20; ++j) {
    const double y = -1 + j / double(1 << 19);
    const GeodeticTerms terms = GeodeticTerms::from_mercator(projection, 0, y);
    const double tau = std::sinh(y * std::numbers::pi);
    const double cos_lat = 1 / std::hypot(1.0, tau), sin_lat = tau * cos_lat;
    worst = std::max(
        {worst, std::abs(terms.cos_lat_cos_lon - cos_lat), std::abs(terms.sin_lat - sin_lat)});
    ASSERT_EQ(terms.cos_lat_sin_lon, 0.0);
  }
  EXPECT_LE(worst, 4 * std::numeric_limits<double>::epsilon());
}

TEST(RenderMesh, LongitudeNearAgreesWithCosAndSinWithinFourUlps) {
  // LongitudeNear (angle addition from a tile's centre, Taylor series of the difference) against
  // std::cos / std::sin of πx: tiles of levels 0 to 24 across the map, 257 x over each and a
  // margin around it, both sides of the antimeridian. Measured 2 ulps of 1. A series one term
  // short (no d⁷) is ~1.5e-13 off at |d| = 0.05; a reach of 0.2 without more terms ~3e-12.
  double worst = 0;
  int near_used = 0;
  for (std::uint32_t z = 0; z <= 24; ++z) {
    const double width = 2.0 / static_cast<double>(1u << z);
    for (const double centre : {-1 + width / 2, -0.6543210987 + width / 2, width / 2,
                                0.123456789 + width / 2, 1 - width / 2}) {
      const LongitudeNear near(centre);
      for (int k = -160; k <= 160; ++k) {
        const double x = centre + width * k / 256.0;
        const auto [c, s] = near.cos_sin(x);
        const double lon = x * std::numbers::pi;
        worst = std::max({worst, std::abs(c - std::cos(lon)), std::abs(s - std::sin(lon))});
        near_used += std::abs((x - centre) * std::numbers::pi) <= LongitudeNear::kReach;
      }
    }
  }
  EXPECT_LE(worst, 4 * std::numeric_limits<double>::epsilon());
  EXPECT_GE(near_used, 18 * 5 * 321);
}

TEST(RenderMesh, RoundHalfAwayIsLround) {
  // The packing's inline rounding against std::lround (what it replaced) over the whole range
  // the packing uses (±511 for normals, 0..65535 for uv): every integer, every half, their
  // neighbouring doubles (0.49999999999999994 must not round up, as v + 0.5 would), and a
  // dense sweep of fractions; then NaN (0, as lround's LONG_MIN truncated to 10 or 16 bits).
  std::size_t checked = 0;
  const auto check = [&](double v) {
    ASSERT_EQ(round_half_away(v), static_cast<std::int32_t>(std::lround(v))) << v;
    ++checked;
  };
  for (int k = -2 * 65536; k <= 2 * 65536; ++k) {
    const double half = k / 2.0;
    check(half);
    check(std::nextafter(half, -1e9));
    check(std::nextafter(half, 1e9));
  }
  for (int k = -70000 * 64; k <= 70000 * 64; ++k) check(k / 64.0 + 1.0 / 3.0);
  check(0.49999999999999994);
  check(-0.49999999999999994);
  check(-0.0);
  EXPECT_EQ(round_half_away(std::nan("")), 0);
  EXPECT_GT(checked, 9'000'000u);
}

TEST(RenderMesh, FineTileKeepsMillimetres) {
  const geo::TileId id{20, 549321, 355123};
  const tile::TinTile t =
      tinstream::testing::make_grid_tile(id, 9, tinstream::testing::synthetic_height);
  const auto payload = tile::compress(tile::encode(t));
  auto mesh = decode_render_mesh(payload, ContentEncoding::deflate, layer_for(id),
                                 {TileKind::terrain, 0, id});
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  const auto vertices = t.vertices();
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const Vec3 want = expected_ecef(vertices[i].x, vertices[i].y, vertices[i].z);
    EXPECT_LT(length(world_of(*mesh, i) - want), 1e-3) << "vertex " << i;
    EXPECT_FLOAT_EQ(mesh->vertices[i].height, static_cast<float>(vertices[i].z));
  }
  // u runs west → east, v north → south: NW (0, 0), SE (1, 1).
  EXPECT_EQ(mesh->vertices[0].u, 0);
  EXPECT_EQ(mesh->vertices[0].v, 0);
  EXPECT_EQ(mesh->vertices[3].u, 65535);
  EXPECT_EQ(mesh->vertices[3].v, 65535);
  // A full tile: every border segment gets a skirt, 8 per side for a 9×9 grid.
  EXPECT_EQ(mesh->data_triangles, 2u * 8 * 8);
  // The mid lines run along grid lines: 4 grid edges per half-line, each cut once.
  EXPECT_EQ(mesh->index_count() - mesh->surface_index_count, 4u * 8 * 6 + 4u * 4 * 6);
  EXPECT_EQ(mesh->skirt_index_count, (std::array<std::uint32_t, 4>{48, 48, 48, 48}));
  EXPECT_EQ(mesh->cut_index_count, (std::array<std::uint32_t, 4>{24, 24, 24, 24}));
  EXPECT_EQ(mesh->skirt_spans.size(), 4u * 8 + 4u * 4);
  EXPECT_EQ(mesh->quadrant_data, 0xF);
}

TEST(RenderMesh, BoundsHoldEveryVertexSkirtsIncluded) {
  const geo::TileId id{14, 8490, 5610};
  const tile::TinTile t =
      tinstream::testing::make_grid_tile(id, 17, tinstream::testing::synthetic_height);
  const TileMesh mesh = build_render_mesh(t, layer_for(id), {TileKind::terrain, 0, id});
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
    EXPECT_TRUE(mesh.bounds.contains(world_of(mesh, i))) << "vertex " << i;
}

TEST(RenderMesh, SkirtVerticesSitOnTheBorderAndTheBoxHoldsTheirDeepest) {
  const geo::TileId id{16, 33960, 22440};
  const tile::TinTile t =
      tinstream::testing::make_grid_tile(id, 5, [](double, double) { return 250.0; });
  LayerDescription layer = layer_for(id);
  layer.min_z = 200;
  const TileMesh mesh = build_render_mesh(t, layer, {TileKind::terrain, 0, id});
  // 1e-5 of the tile's width (about 390 m at this latitude) is below the 5 cm minimum.
  EXPECT_DOUBLE_EQ(mesh.skirt_margin, 0.05);
  EXPECT_DOUBLE_EQ(mesh.skirt_lowest, 200 - mesh.skirt_margin);
  // A 5×5 grid: 4 segments per side, one quad (6 indices) each, side by side N, E, S, W.
  for (std::size_t s = 0; s < 4; ++s) EXPECT_EQ(mesh.skirt_index_count[s], 4u * 6) << s;
  const std::size_t surface = t.vertex_count();
  // One skirt vertex per border vertex, then 4 per cut quad (2 grid edges per half-line).
  ASSERT_EQ(mesh.vertices.size(), surface + 16 + std::size_t{8} * 4);
  // Each north skirt quad (a, sa, sb, a, sb, b) hangs from a north border vertex pair.
  const auto north = t.border(geo::Direction::north);
  for (std::size_t q = 0; q < 4; ++q) {
    const std::size_t at = mesh.surface_index_count + q * 6;
    const Vec3 a = world_of(mesh, index_at(mesh, at)), b = world_of(mesh, index_at(mesh, at + 5));
    EXPECT_LT(length(a - expected_ecef(north[q].x, north[q].y, 250.0)), 1e-3) << q;
    EXPECT_LT(length(b - expected_ecef(north[q + 1].x, north[q + 1].y, 250.0)), 1e-3) << q;
  }
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    // Cut vertices: on the cross-section, then lowered, by turns.
    const bool skirt = i >= surface + 16 ? (i - surface - 16) % 2 == 1 : i >= surface;
    EXPECT_EQ((mesh.vertices[i].normal >> 30) & 3u, skirt ? 1u : 0u);
    // Flat at 250 m: the normal is the geodetic up (cos φ cos λ, cos φ sin λ, sin φ).
    const geo::Geodetic g =
        geo::from_ecef({world_of(mesh, i).x, world_of(mesh, i).y, world_of(mesh, i).z});
    const double lon = g.lon * kPi / 180, lat = g.lat * kPi / 180;
    const Vec3 up{std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
    EXPECT_GT(dot(unpack_normal(mesh.vertices[i].normal), up), 0.999) << i;
    // Skirt vertices sit at their border vertex (the shader lowers them) ...
    EXPECT_NEAR(g.height, 250.0, 1e-3) << i;
    // ... and the box holds them at the lowest a floor may put them.
    if (skirt) {
      const geo::Ecef deep = geo::to_ecef({g.lon, g.lat, 200 - mesh.skirt_margin});
      EXPECT_TRUE(mesh.bounds.contains({deep.x, deep.y, deep.z})) << i;
    }
  }
}

TEST(RenderMesh, NodataTrianglesAreNotDrawn) {
  const geo::TileId id{12, 2121, 1401};
  tile::TinTile t = tinstream::testing::make_grid_tile(id, 3, tinstream::testing::synthetic_height);
  // NE, SW and SE without data (z = 0), as tiles at the data's edge have them.
  for (std::size_t c : {1u, 2u, 3u}) {
    t.corner_nodata[c] = true;
    t.corners[c].z = 0;
  }
  LayerDescription layer = layer_for(id);
  layer.min_z = 170;  // synthetic_height ≥ 300 − 120 + 0.37·lat
  const TileMesh mesh = build_render_mesh(t, layer, {TileKind::terrain, 0, id});
  // Of the 8 triangles of the 3×3 grid, 4 touch a NODATA corner; the 4 left reach NW (two),
  // NE and SW (one each).
  EXPECT_EQ(mesh.data_triangles, 4u);
  EXPECT_EQ(mesh.nodata_triangles, 4u);
  EXPECT_EQ(mesh.quadrant_data, 0b0111);
  for (std::size_t i = 0; i < mesh.surface_index_count; ++i) {
    const std::uint32_t v = index_at(mesh, i);
    EXPECT_TRUE(v == 0 || v >= 4) << "a NODATA corner is drawn";
  }
  // Skirts only under the border segments of drawn triangles: NW–N (north) and NW–W (west);
  // none along the east and south sides, whose every segment touches a NODATA corner.
  // Cut quads under the drawn edges on the mid lines: N–C, C–S (x = mid), W–C, C–E (y = mid).
  EXPECT_EQ(mesh.index_count() - mesh.surface_index_count, std::size_t{12 + 24});  // 6 quads
  EXPECT_EQ(mesh.skirt_index_count, (std::array<std::uint32_t, 4>{6, 0, 0, 6}));
  EXPECT_EQ(mesh.cut_index_count, (std::array<std::uint32_t, 4>{6, 6, 6, 6}));
  // The box ignores the NODATA corners at z = 0 (the surface is near 300 m, the layer's lowest
  // height, where skirts may reach, 170 m).
  EXPECT_GT(mesh.min_z, 100);
  EXPECT_LT(mesh.bounds.half[2], 100);
}

// A coarse tile of a small dataset: one data vertex inside four NODATA corners, so every triangle
// touches a NODATA corner and nothing is drawn. Its box must still hold the tile (the corners at
// the data's height) and the data vertex: the streamer culls and refines with it, and the
// children's data lie there. A box of the drawn vertices alone sat at the tile's centre at 0 m:
// the viewer culled such a level-0 tile over Oregon and never asked for its children.
TEST(RenderMesh, ATileThatDrawsNothingStillBoundsItsRectangleAtItsDataHeights) {
  const geo::TileId id{12, 2121, 1401};
  const geo::MercatorRect r = id.bounds();
  tile::TinTile t;
  t.id = id;
  t.corners = {tile::Vertex{r.min_x, r.max_y, 0, 0}, tile::Vertex{r.max_x, r.max_y, 0, 0},
               tile::Vertex{r.min_x, r.min_y, 0, 0}, tile::Vertex{r.max_x, r.min_y, 0, 0}};
  t.corner_nodata = {true, true, true, true};
  const double data_z = 2500;
  t.interior.push_back({r.min_x + 0.3 * r.width(), r.min_y + 0.6 * r.height(), data_z, 1});
  t.triangles = {{0, 2, 4}, {2, 3, 4}, {3, 1, 4}, {1, 0, 4}};
  t.update_z_range();
  const TileMesh mesh = build_render_mesh(t, layer_for(id), {TileKind::terrain, 0, id});
  EXPECT_EQ(mesh.data_triangles, 0u);
  EXPECT_EQ(mesh.nodata_triangles, 4u);
  EXPECT_EQ(mesh.surface_index_count, 0u);
  for (const auto& c : t.corners) {
    EXPECT_TRUE(mesh.bounds.contains(expected_ecef(c.x, c.y, data_z))) << c.x << "," << c.y;
  }
  const tile::Vertex& d = t.interior[0];
  EXPECT_TRUE(mesh.bounds.contains(expected_ecef(d.x, d.y, d.z)));
  // The corners' 0 m did not stretch the box towards the ellipsoid.
  EXPECT_FALSE(mesh.bounds.contains(expected_ecef(d.x, d.y, 0)));
  // Drawing nothing, it shows the globe where the data are: its error is at least their height,
  // whatever the header says, so the streamer refines it.
  EXPECT_GE(mesh.geometric_error, data_z);
}

TEST(RenderMesh, WideIndicesBeyond65536Vertices) {
  const geo::TileId id{18, 135000, 90000};
  const tile::TinTile t =
      tinstream::testing::make_grid_tile(id, 260, tinstream::testing::synthetic_height);
  const TileMesh mesh = build_render_mesh(t, layer_for(id), {TileKind::terrain, 0, id});
  EXPECT_TRUE(mesh.indices16.empty());
  EXPECT_EQ(mesh.indices32.size(), mesh.index_count());
  EXPECT_EQ(mesh.byte_size(), mesh.vertices.size() * 24 + mesh.indices32.size() * 4);
}

TEST(RenderMesh, GzipAndDeflatePayloadsGiveTheSameMesh) {
  const geo::TileId id{13, 4242, 2800};
  const auto raw =
      tile::encode(tinstream::testing::make_grid_tile(id, 7, tinstream::testing::synthetic_height));
  // gzip through zlib itself (not the code under test).
  std::vector<std::uint8_t> gz(compressBound(static_cast<uLong>(raw.size())) + 64);
  z_stream zs{};
  ASSERT_EQ(deflateInit2(&zs, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY), Z_OK);
  zs.next_in = const_cast<Bytef*>(raw.data());
  zs.avail_in = static_cast<uInt>(raw.size());
  zs.next_out = gz.data();
  zs.avail_out = static_cast<uInt>(gz.size());
  ASSERT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
  gz.resize(zs.total_out);
  deflateEnd(&zs);
  const TileKey key{TileKind::terrain, 0, id};
  auto a = decode_render_mesh(gz, ContentEncoding::gzip, layer_for(id), key);
  auto b = decode_render_mesh(tile::compress(raw), ContentEncoding::deflate, layer_for(id), key);
  auto c = decode_render_mesh(raw, ContentEncoding::identity, layer_for(id), key);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(a->vertices.size(), b->vertices.size());
  EXPECT_EQ(0, std::memcmp(a->vertices.data(), b->vertices.data(), a->vertices.size() * 24));
  EXPECT_EQ(0, std::memcmp(c->vertices.data(), b->vertices.data(), c->vertices.size() * 24));
}

TEST(RenderMesh, BadPayloadsAreErrorsNamingTheTile) {
  const geo::TileId id{13, 4242, 2800};
  const TileKey key{TileKind::terrain, 0, id};
  const auto raw =
      tile::encode(tinstream::testing::make_grid_tile(id, 5, tinstream::testing::synthetic_height));
  // Truncated.
  auto truncated = decode_render_mesh(std::span(raw).first(raw.size() - 3),
                                      ContentEncoding::identity, layer_for(id), key);
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.error().message.find(id.quadkey()), std::string::npos);
  // Not a zlib stream.
  auto junk = decode_render_mesh(raw, ContentEncoding::deflate, layer_for(id), key);
  ASSERT_FALSE(junk.ok());
  EXPECT_NE(junk.error().message.find(id.quadkey()), std::string::npos);
  // Another tile's bytes.
  const TileKey other{TileKind::terrain, 0, {13, 4243, 2800}};
  auto wrong = decode_render_mesh(raw, ContentEncoding::identity, layer_for(id), other);
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().message.find("holds tile 13/4242/2800"), std::string::npos);
}

}  // namespace
}  // namespace tinstream::client
