// tinstream/client/render_mesh.hpp — a native tile turned into what the GPU draws.
//
// Runs on the loader's worker threads (never on the render thread): inflate the payload, decode
// it with core's tile::decode (docs/tile-format.md), then for the layer's projection convert every
// vertex normalised Mercator → lon/lat → double ECEF (GeographicLib) and store it as float
// relative to the tile's centre (millimetres survive even at level 30). Each vertex gets an
// area-weighted normal, its height (for the colour ramp) and its position in the tile (for the
// quadrant masks that stand in for absent children). Only the tile's data footprint is drawn:
// NODATA triangles are left out (TinTile::footprint_mask, docs/tile-format.md §2.1); skirts hang
// from every border segment of a drawn triangle.
//
//   surface vertices (tile numbering)  skirt vertices (one per border vertex that is drawn)
//   indices: surface triangles, then skirt quads as triangle pairs
//
// The result owns plain vectors; it is immutable once built and shared between the RAM tier and
// the upload queue (std::shared_ptr<const TileMesh>).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/bounds.hpp"
#include "tinstream/client/layer.hpp"
#include "tinstream/client/tile_key.hpp"
#include "tinstream/client/vec.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::client {

// 24 bytes, the vertex buffer's layout (renderer.cpp binds these offsets).
struct MeshVertex {
  float position[3];     // metres, ECEF relative to TileMesh::centre
  float height;          // metres above the ellipsoid (colour ramp)
  std::uint32_t normal;  // GL_INT_2_10_10_10_REV: x, y, z signed normalised; w: 1 = skirt
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

struct TileMesh {
  TileKey key;
  Vec3 centre;                  // ECEF origin of the float positions
  std::array<Vec3, 3> frame{};  // east, north, up at the centre (lighting)
  std::vector<MeshVertex> vertices;
  std::vector<std::uint16_t> indices16;   // used when vertices.size() ≤ 65536
  std::vector<std::uint32_t> indices32;   // otherwise
  std::uint32_t surface_index_count = 0;  // the first indices; skirts follow
  Obb bounds;                             // every drawn vertex, skirts included
  double geometric_error = 0;             // the tile's own (header), metres
  double min_z = 0, max_z = 0;            // of the drawn vertices
  double skirt_depth = 0;
  std::uint32_t data_triangles = 0, nodata_triangles = 0;
  std::uint8_t quadrant_data = 0;  // bit q (quadkey digit): a drawn triangle reaches quadrant q

  std::size_t index_count() const {
    return indices16.empty() ? indices32.size() : indices16.size();
  }
  // What the mesh costs in RAM and on the GPU (vertex + index bytes).
  std::size_t byte_size() const;
};

// How far the skirts hang below the border: the tile's own error plus the largest error of the
// level above (the gap to a coarser neighbour, the usual case of a crack), plus 1e-3 of the
// tile's width against float rounding.
double skirt_depth(const tile::TinTile& tile, const LayerDescription& layer);

// Builds the mesh of a decoded tile. Requires: tile.id == key.tile and the indices are in range
// (tile::decode checks them).
TileMesh build_render_mesh(const tile::TinTile& tile, const LayerDescription& layer, TileKey key);

// What a worker does with a payload: inflate, tile::decode, check that it is tile key.tile, build.
// Errors name the tile.
Result<TileMesh> decode_render_mesh(std::span<const std::uint8_t> payload, ContentEncoding encoding,
                                    const LayerDescription& layer, TileKey key);

}  // namespace tinstream::client
