// tinstream/client/render_mesh.hpp — a native tile turned into what the GPU draws.
//
// Runs on the loader's worker threads (never on the render thread): inflate the payload, decode
// it with core's tile::decode (docs/tile-format.md), then for the layer's projection convert every
// vertex normalised Mercator → geodetic terms → double ECEF (GeodeticTerms, below) and store it as
// float relative to the tile's centre (millimetres survive even at level 30). Each vertex gets an
// area-weighted normal, its height (for the colour ramp) and its position in the tile (for the
// quadrant masks that stand in for absent children). Only the tile's data footprint is drawn:
// NODATA triangles are left out (TinTile::footprint_mask, docs/tile-format.md §2.1).
//
// Skirts: every border segment of a drawn triangle gets a skirt quad, grouped by side (north,
// east, south, west, each in edge order), each quad with its extent along the side
// (TileMesh::skirt_spans), so that the renderer draws only the quads that need one in a frame
// (skirts.hpp decides: beside the data of a drawn neighbour of another level across the side).
// Cut skirts: the tile's drawn surface is also cut along its two mid lines (where a quadrant
// mask's discard cuts it when a child is drawn in one quadrant and the tile in the other) and
// gets skirt quads under that cross-section, in four groups (TileMesh::cut_index_count): nothing
// else closes the opening between the tile's cut edge and a lower child. A
// vertex sits *at* its border vertex, flagged; the vertex shader lowers it along the ellipsoid
// normal by the frame's depth, never below the frame's floor (how deep depends on the neighbours,
// known only when drawing). The bounding box holds the deepest a skirt may hang: down to the
// layer's lowest height less the margin (no neighbour surface lies lower).
//
//   surface vertices (tile numbering)  skirt vertices (one per border vertex that is drawn)
//   indices: surface triangles, then skirt quads (triangle pairs): north, east, south, west,
//            then cut quads: x = mid north half, x = mid south half, y = mid west half, east half
//   cut vertices: four per cut quad (two on the cross-section, two lowered)
//
// The result owns plain vectors; it is immutable once built and shared between the RAM tier and
// the upload queue (std::shared_ptr<const TileMesh>).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/bounds.hpp"
#include "tinstream/client/layer.hpp"
#include "tinstream/client/tile_key.hpp"
#include "tinstream/client/vec.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::client {

// std::lround for |v| < 2^31, inline (the normal and uv packing's rounding): halves away from
// zero; NaN gives 0.
std::int32_t round_half_away(double v);

// 24 bytes, the vertex buffer's layout (renderer.cpp binds these offsets).
struct MeshVertex {
  float position[3];     // metres, ECEF relative to TileMesh::centre
  float height;          // metres above the ellipsoid (colour ramp)
  std::uint32_t normal;  // GL_INT_2_10_10_10_REV: x, y, z signed normalised; w: 1 = skirt
                         // (then position = the border vertex's; the shader lowers it)
  std::uint16_t u, v;    // unorm16 position in the tile: u west → east, v north → south
};
static_assert(sizeof(MeshVertex) == 24);

enum class ContentEncoding : std::uint8_t { identity, deflate, gzip };
std::string_view to_string(ContentEncoding e);

// The bytes as sent or stored, inflated (deflate = zlib stream, RFC 1950; gzip, RFC 1952).
// Refuses to produce more than max_output bytes.
Result<std::vector<std::uint8_t>> inflate_payload(std::span<const std::uint8_t> bytes,
                                                  ContentEncoding encoding,
                                                  std::size_t max_output = 64u << 20);

// Where one skirt quad lies along its line, normalised Mercator: x for a north or south side and
// a cut along y = mid, y for an east or west side and a cut along x = mid. lo < hi.
struct SkirtSpan {
  double lo = 0, hi = 0;
};

// The cut groups, in index order after the four sides: the half-lines between two quadrants.
enum class Cut : std::uint8_t { north = 0, south = 1, west = 2, east = 3 };

struct TileMesh {
  TileKey key;
  Vec3 centre;                  // ECEF origin of the float positions
  std::array<Vec3, 3> frame{};  // east, north, up at the centre (lighting)
  std::vector<MeshVertex> vertices;
  std::vector<std::uint16_t> indices16;   // used when vertices.size() ≤ 65536
  std::vector<std::uint32_t> indices32;   // otherwise
  std::uint32_t surface_index_count = 0;  // the first indices; skirts follow
  // Indices of each side's skirt quads (0 north, 1 east, 2 south, 3 west), in that order after
  // the surface: side s starts at surface_index_count + the counts of the sides before it.
  std::array<std::uint32_t, 4> skirt_index_count{};
  // Indices of the cut quads after the sides' (Cut order): north = x = mid between NW and NE,
  // south = x = mid between SW and SE, west = y = mid between NW and SW, east = between NE, SE.
  std::array<std::uint32_t, 4> cut_index_count{};
  std::vector<SkirtSpan> skirt_spans;  // one per skirt quad (sides, then cuts), in index order
  Obb bounds;                          // every drawn vertex, skirts at their deepest included
  // The tile's own (header), metres; when no triangle is drawn (data_triangles = 0), at least
  // the largest |height| of its data vertices: the globe shows through there.
  double geometric_error = 0;
  double min_z = 0, max_z = 0;  // of the drawn vertices
  double skirt_margin = 0;      // metres added to a skirt's depth against rounding
  double skirt_lowest = 0;      // the lowest height a skirt may reach (the box holds it)
  std::uint32_t data_triangles = 0, nodata_triangles = 0;
  std::uint8_t quadrant_data = 0;  // bit q (quadkey digit): a drawn triangle reaches quadrant q

  std::size_t index_count() const {
    return indices16.empty() ? indices32.size() : indices16.size();
  }
  // What the mesh costs in RAM and on the GPU (vertex + index bytes).
  std::size_t byte_size() const;
};

// cos λ and sin λ (λ = πx) of the x near one longitude, a tile's centre: by the angle-addition
// formulas from the centre's cos and sin (computed once) and Taylor series of the difference d
// (to d⁸; what is left out is below 6e-18) — a few multiplications instead of a sincos per
// vertex. Within 4 ulps of 1 of std::cos / std::sin (RenderMesh.LongitudeNear…). Farther than
// kReach radians from the centre (only in tiles of level < 6) it calls std::cos and std::sin.
struct LongitudeNear {
  static constexpr double kReach = 0.05;
  explicit LongitudeNear(double centre_x);
  std::pair<double, double> cos_sin(double x) const;
  double centre_x, cos_centre, sin_centre;
};

// A vertex's place on the WGS84 ellipsoid from normalised Mercator, without degrees: the decode's
// hot loop. geo::to_ecef(projection.inverse(p)) goes through latitude and longitude in degrees
// (GeographicLib's atand, then sincosd with its exact degree reduction, per vertex); here, on a
// spherical layer, cos φ = sech πy and sin φ = tanh πy come from one expm1 and one sqrt; on an
// ellipsoidal one τ = tan φ from sinh(πy) and GeographicLib's Math::tauf, cos φ and sin φ from τ by
// one hypot; λ = πx by one sincos, or near a tile's centre by LongitudeNear. The terms give the
// ECEF point at any height by a few multiplications (a skirt vertex reuses its border vertex's).
// Agrees with the GeographicLib path within 1e-8 m anywhere on the map
// (RenderMesh.FastEcefAgreesWith…; 2.8e-9 m measured), far below what the mesh's float positions
// keep at any level it draws.
struct GeodeticTerms {
  double cos_lat_cos_lon = 0, cos_lat_sin_lon = 0, sin_lat = 0;
  double prime_vertical = 0;  // N(φ) = a / sqrt(1 − e² sin² φ), metres

  static GeodeticTerms from_mercator(const geo::NormalisedMercator& projection, double x, double y);
  // The same with λ's terms from `near` (the decode's loop: near its tile's centre).
  static GeodeticTerms from_mercator(const geo::NormalisedMercator& projection,
                                     const LongitudeNear& near, double x, double y);
  Vec3 ecef(double height) const;
};

// What a skirt hangs deeper than the crack it hides, against float rounding: 1e-5 of the
// tile's width (float positions relative to the tile's centre round at ~1e-7 of it), at least
// 5 cm. (1e-3 made a level-6 tile's skirt 500 m deeper than any crack.)
double skirt_margin(const tile::TinTile& tile, const LayerDescription& layer);

// Builds the mesh of a decoded tile. Requires: tile.id == key.tile and the indices are in range
// (tile::decode checks them).
TileMesh build_render_mesh(const tile::TinTile& tile, const LayerDescription& layer, TileKey key);

// What a worker does with a payload: inflate, tile::decode, check that it is tile key.tile, build.
// Errors name the tile.
Result<TileMesh> decode_render_mesh(std::span<const std::uint8_t> payload, ContentEncoding encoding,
                                    const LayerDescription& layer, TileKey key);

}  // namespace tinstream::client
