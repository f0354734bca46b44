// Raster-DEM tiles decode to the TIN's heights at their pixel centres, within half the
// encoding's step — NODATA triangles too, their corners carrying continued heights — and NODATA
// triangles are wall-free (also with legacy corners at height 0), transparent or opaque as asked.
#include "tinstream/terrain/raster_dem.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "grid_tile.hpp"
#include "test_tiles.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::terrain {
namespace {

// Brute force, independent of the renderer's scan: every triangle that contains the point
// (closed, exact orientation), with the TIN's height there in long double.
struct Hit {
  long double height;
  bool nodata;
  bool legacy;                // a NODATA corner outside the tile's data range (e.g. at 0 m)
  double data_min, data_max;  // over the triangle's data vertices
};

std::vector<Hit> triangles_at(const tile::TinTile& t, double px, double py) {
  const auto vs = t.vertices();
  std::vector<Hit> hits;
  for (const auto& tri : t.triangles) {
    const tile::Vertex &a = vs[tri[0]], &b = vs[tri[1]], &c = vs[tri[2]];
    const kernel::XY pa{a.x, a.y}, pb{b.x, b.y}, pc{c.x, c.y}, p{px, py};
    if (kernel::orient2d(pa, pb, p) < 0 || kernel::orient2d(pb, pc, p) < 0 ||
        kernel::orient2d(pc, pa, p) < 0) {
      continue;
    }
    const long double det =
        (static_cast<long double>(b.x) - a.x) * (static_cast<long double>(c.y) - a.y) -
        (static_cast<long double>(b.y) - a.y) * (static_cast<long double>(c.x) - a.x);
    const long double wb =
        ((static_cast<long double>(px) - a.x) * (static_cast<long double>(c.y) - a.y) -
         (static_cast<long double>(py) - a.y) * (static_cast<long double>(c.x) - a.x)) /
        det;
    const long double wc =
        ((static_cast<long double>(b.x) - a.x) * (static_cast<long double>(py) - a.y) -
         (static_cast<long double>(b.y) - a.y) * (static_cast<long double>(px) - a.x)) /
        det;
    Hit h{(1 - wb - wc) * a.z + wb * b.z + wc * c.z, false, false, 1e300, -1e300};
    for (const auto idx : tri) {
      if (idx < 4 && t.corner_nodata[idx]) {
        h.nodata = true;
        h.legacy |= vs[idx].z < t.min_z || vs[idx].z > t.max_z;
      } else {
        h.data_min = std::min(h.data_min, vs[idx].z);
        h.data_max = std::max(h.data_max, vs[idx].z);
      }
    }
    hits.push_back(h);
  }
  return hits;
}

// Checks every pixel of the raster of `t` against the brute-force TIN (NODATA transparent), then
// that the opaque form differs only in the alpha of those pixels.
void expect_raster_matches_tin(const tile::TinTile& t, DemEncoding encoding, std::uint32_t size) {
  auto raster = render_raster_dem(t, encoding, size, DemNodata::transparent);
  ASSERT_TRUE(raster.ok()) << raster.error().message;
  ASSERT_EQ(raster->rgba.size(), std::size_t{size} * size * 4);
  const geo::MercatorRect r = t.id.bounds();
  const double step = dem_step(encoding);
  std::uint64_t nodata = 0;
  for (std::uint32_t j = 0; j < size; ++j) {
    for (std::uint32_t i = 0; i < size; ++i) {
      const double px = r.min_x + (i + 0.5) * (r.width() / size);
      const double py = r.max_y - (j + 0.5) * (r.height() / size);
      const auto hits = triangles_at(t, px, py);
      ASSERT_FALSE(hits.empty()) << i << "," << j;
      const std::uint8_t* p = &raster->rgba[(std::size_t{j} * size + i) * 4];
      const double decoded = decode_dem_height(encoding, p[0], p[1], p[2]);
      // The renderer may have taken any of the triangles sharing this centre.
      bool ok = false;
      for (const Hit& h : hits) {
        const std::uint8_t alpha = h.nodata ? 0 : 255;
        if (h.legacy) {
          // No wall: within the heights of the triangle's data vertices.
          ok |= p[3] == alpha && decoded >= h.data_min - step && decoded <= h.data_max + step;
        } else {
          // The triangle's plane (hillshading shows no crease inside it).
          ok |=
              p[3] == alpha && std::abs(decoded - static_cast<double>(h.height)) <= step / 2 + 1e-9;
        }
      }
      ASSERT_TRUE(ok) << "pixel " << i << "," << j << " of " << t.id.to_string() << ": decoded "
                      << decoded << " alpha " << int(p[3]) << ", TIN "
                      << static_cast<double>(hits[0].height) << (hits[0].nodata ? " (NODATA)" : "");
      nodata += p[3] == 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(raster->nodata_pixels, nodata);
  auto opaque = render_raster_dem(t, encoding, size, DemNodata::opaque);
  ASSERT_TRUE(opaque.ok()) << opaque.error().message;
  EXPECT_EQ(opaque->nodata_pixels, nodata);
  ASSERT_EQ(opaque->rgba.size(), raster->rgba.size());
  for (std::size_t k = 0; k < opaque->rgba.size(); k += 4) {
    ASSERT_EQ(opaque->rgba[k + 3], 255) << "pixel " << k / 4;
    for (std::size_t c = 0; c < 3; ++c) ASSERT_EQ(opaque->rgba[k + c], raster->rgba[k + c]);
  }
}

TEST(RasterDem, EncodingsRoundTripWithinHalfAStep) {
  for (const auto e : {DemEncoding::terrarium, DemEncoding::mapbox}) {
    const double step = dem_step(e);
    for (const double h : {-430.0, -0.001, 0.0, 0.2, 123.456, 4807.81, 8848.86}) {
      const auto rgb = encode_dem_height(e, h);
      EXPECT_NEAR(decode_dem_height(e, rgb[0], rgb[1], rgb[2]), h, step / 2 + 1e-12)
          << to_string(e) << " " << h;
    }
  }
  // The published definitions, on fixed bytes (not on our encoder).
  EXPECT_DOUBLE_EQ(decode_dem_height(DemEncoding::terrarium, 128, 0, 0), 0.0);
  EXPECT_DOUBLE_EQ(decode_dem_height(DemEncoding::terrarium, 130, 1, 128), 513.5);
  EXPECT_DOUBLE_EQ(decode_dem_height(DemEncoding::mapbox, 1, 134, 160), 0.0);
  // Out of range: clamped, not wrapped.
  const auto low = encode_dem_height(DemEncoding::mapbox, -20000);
  EXPECT_DOUBLE_EQ(decode_dem_height(DemEncoding::mapbox, low[0], low[1], low[2]), -10000);
  const auto high = encode_dem_height(DemEncoding::terrarium, 1e9);
  EXPECT_EQ(high, (std::array<std::uint8_t, 3>{255, 255, 255}));
  EXPECT_EQ(*parse_dem_encoding("mapbox"), DemEncoding::mapbox);
  EXPECT_FALSE(parse_dem_encoding("mapzen").ok());
  EXPECT_EQ(*parse_dem_nodata("transparent"), DemNodata::transparent);
  EXPECT_EQ(*parse_dem_nodata("opaque"), DemNodata::opaque);
  EXPECT_FALSE(parse_dem_nodata("flagged").ok());
}

TEST(RasterDem, IrregularTinsWithNodataCornersDecodeToTheTinAtPixelCentres) {
  std::mt19937_64 rng(19);
  for (int round = 0; round < 6; ++round) {
    const geo::TileId id = tile::testing::random_tile_id(rng, 20);
    const auto nx = 1 + static_cast<std::uint32_t>(rng() % 9);
    const auto ny = 1 + static_cast<std::uint32_t>(rng() % 9);
    const tile::TinTile t = tile::testing::make_grid_tile(id, nx, ny, rng, round % 2 == 0);
    for (const auto e : {DemEncoding::terrarium, DemEncoding::mapbox}) {
      expect_raster_matches_tin(t, e, round < 3 ? 256 : 64);
    }
  }
}

// Tiles as the ingest writes them: NODATA corners carry heights continued from the data, within the
// tile's data range. Their NODATA triangles decode to the triangle's plane, as CesiumJS draws them;
// an interpolation over the data vertices alone curves inside them (MapLibre's hillshade showed
// its creases as ridges along the data's edge).
TEST(RasterDem, NodataTrianglesWithContinuedCornersDecodeToTheirPlane) {
  std::mt19937_64 rng(23);
  std::uint64_t nodata_pixels = 0;
  for (int round = 0; round < 6; ++round) {
    const geo::TileId id = tile::testing::random_tile_id(rng, 20);
    const auto nx = 2 + static_cast<std::uint32_t>(rng() % 8);
    const auto ny = 2 + static_cast<std::uint32_t>(rng() % 8);
    tile::TinTile t = tile::testing::make_grid_tile(id, nx, ny, rng, true);
    t.corner_nodata = {true, round % 2 == 0, round % 3 == 0, true};
    t.update_z_range();
    std::uniform_real_distribution<double> within(t.min_z, t.max_z);
    for (std::size_t c = 0; c < 4; ++c) {
      if (t.corner_nodata[c]) t.corners[c].z = within(rng);
    }
    for (const auto e : {DemEncoding::terrarium, DemEncoding::mapbox}) {
      expect_raster_matches_tin(t, e, 64);
    }
    nodata_pixels += render_raster_dem(t, DemEncoding::mapbox, 64)->nodata_pixels;
  }
  EXPECT_GT(nodata_pixels, 0u);  // the NODATA triangles were there to be checked
}

// A 33 × 33 vertex grid on a 128-pixel raster: every cell spans 4 × 4 pixels and its diagonal
// passes through pixel centres, which therefore lie on edges shared by two triangles.
TEST(RasterDem, PixelCentresOnSharedEdgesTakeTheCommonValue) {
  const tile::TinTile t = testing::make_grid_tile({12, 2145, 1434}, 33, testing::synthetic_height);
  expect_raster_matches_tin(t, DemEncoding::terrarium, 128);
}

TEST(RasterDem, MalformedTilesAreRefused) {
  std::mt19937_64 rng(3);
  tile::TinTile t = tile::testing::make_grid_tile({5, 3, 4}, 3, 3, rng, false);
  t.triangles.pop_back();  // a hole
  auto r = render_raster_dem(t, DemEncoding::mapbox, 256);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("no triangle covers pixel"), std::string::npos);
  t.triangles.push_back({0, 1, 999});
  EXPECT_FALSE(render_raster_dem(t, DemEncoding::mapbox, 256).ok());
  EXPECT_FALSE(render_raster_dem(t, DemEncoding::mapbox, 0).ok());
  // A hostile tile: thousands of copies of a triangle over the whole tile (bounded work).
  tile::TinTile hostile = tile::testing::make_grid_tile({5, 3, 4}, 1, 1, rng, false);
  const auto whole = hostile.triangles;
  for (int i = 0; i < 20000; ++i)
    hostile.triangles.push_back(whole[static_cast<std::size_t>(i % 2)]);
  auto refused = render_raster_dem(hostile, DemEncoding::terrarium, 256);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("overlap"), std::string::npos);
  // Non-finite coordinates.
  tile::TinTile nan = tile::testing::make_grid_tile({5, 3, 4}, 2, 2, rng, false);
  nan.interior[0].x = std::nan("");
  EXPECT_EQ(render_raster_dem(nan, DemEncoding::terrarium, 64).error().code,
            ErrorCode::corrupt_data);
}

}  // namespace
}  // namespace tinstream::terrain
