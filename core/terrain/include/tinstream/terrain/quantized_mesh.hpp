// tinstream/terrain/quantized_mesh.hpp — Cesium quantized-mesh-1.0 encoding of a TIN tile.
//
// Format: https://github.com/CesiumGS/quantized-mesh (little-endian):
//   QuantizedMeshHeader (88 bytes): centre (ECEF f64×3), min/max height (f32×2), bounding sphere
//     (f64×4), horizon occlusion point (ellipsoid-scaled ECEF f64×3)
//   vertexCount u32; u[], v[], height[] as zig-zag-delta u16 in 0..32767
//   triangleCount u32; indices high-water-mark encoded (u16, or u32 when vertexCount > 65536,
//     then aligned to 4 bytes)
//   west, south, east, north edge index lists (count u32 + indices) — for skirts
//   extensions: id u8, length u32, bytes (1 = octvertexnormals, 2 oct-encoded bytes per vertex)
//
// Tiling: only layers in *spherical* normalised Mercator coincide with Cesium's
// WebMercatorTilingScheme (EPSG:3857, one root tile, TMS rows y_tms = 2^z − 1 − y). Tiles of
// ellipsoidal layers cover different latitudes than the EPSG:3857 tile of the same z/x/y, so
// encode() refuses them with ErrorCode::unsupported instead of producing misplaced terrain.
//
// Quantisation (docs/DESIGN.md §2, "Cesium's v"):
// u = (lon − west)/(east − west), v = (lat − south)/(north − south) in the tile's geodetic
// rectangle — linear in *latitude*, which is how CesiumJS and cesium-native interpolate v even for
// Web Mercator tiles. Every vertex keeps its true lon/lat; straight triangle edges in Mercator
// become straight in lon/lat instead (a sub-pixel change for tiles of level ≥ 6, visible only as
// slightly different interior shading at coarse levels). Border vertices land exactly on u/v = 0 or
// 32767, so neighbours share their edge vertices.
//
// Triangles that rounding to the 15-bit grid turns clockwise or flat are left out (slivers
// thinner than one quantum, which happen in coarse tiles over dense data and where two edge
// points are closer than a quantum); all others are written, so every triangle in the output is
// counter-clockwise with a non-zero area in (u, v).
// Vertices are renumbered in order of first use by the triangle list (required by the
// high-water-mark code). Pure functions, thread-safe.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::terrain {

struct QuantizedMeshOptions {
  bool oct_vertex_normals = false;  // append the `octvertexnormals` extension (id 1)
};

// The uncompressed quantized-mesh bytes of `tile`, a tile of a layer in `projection`.
// Errors: unsupported for ellipsoidal layers; invalid_argument for a tile without triangles or
// with out-of-range indices.
Result<std::vector<std::uint8_t>> encode_quantized_mesh(const tile::TinTile& tile,
                                                        geo::Projection projection,
                                                        const QuantizedMeshOptions& options = {});

// A flat tile at height 0 (four corners, two triangles).
tile::TinTile flat_tile(const geo::TileId& id);

// The tile served in place of one that is not stored but that Cesium needs (synthetic_tiles() in
// layer_json.hpp: levels 0 and 1, the ancestors of the coarsest stored level). It meets its
// stored same-level neighbours without a crack: it takes every vertex of theirs that lies on its
// border (the shared side's vertices, a diagonal neighbour's shared corner) with its height; a
// corner no stored tile touches is at height 0; a centre vertex at the corners' mean height is
// fanned to the border. With no stored neighbour it is flat_tile(id). `stored(id)` returns the
// stored tile of that id, nullopt when there is none, or an error (passed on). East and west
// neighbours wrap around the antimeridian (geo::TileId::neighbour). `min_level` is the layer's
// coarsest stored level: above it (id.z < min_level) no neighbour can be stored, and `stored` is
// not called at all (a filler there is flat_tile(id)).
// Requires: no tile of a level z < min_level is stored.
using StoredTileLookup = std::function<Result<std::optional<tile::TinTile>>(const geo::TileId&)>;
Result<tile::TinTile> filler_tile(const geo::TileId& id, std::uint32_t min_level,
                                  const StoredTileLookup& stored);

// The horizon occlusion point (ellipsoid-scaled ECEF) for a set of ECEF points, seen along the
// direction of `direction_point` — Cesium's EllipsoidalOccluder method ("Horizon culling 2",
// cesium.com blog 2013). Returns nullopt when no finite point exists (points more than 90° from
// the direction, e.g. tiles of levels 0–1); encode() then writes NaN coordinates, which CesiumJS
// treats as "never occluded".
struct Vec3 {
  double x = 0, y = 0, z = 0;
};
std::optional<Vec3> horizon_occlusion_point(std::span<const Vec3> ecef_points,
                                            Vec3 direction_point);

// Cesium's oct encoding of a unit vector into two bytes (AttributeCompression.octEncode, 0..255).
std::array<std::uint8_t, 2> oct_encode(Vec3 unit_normal);

}  // namespace tinstream::terrain
