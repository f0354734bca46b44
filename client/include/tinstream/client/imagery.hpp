// tinstream/client/imagery.hpp — imagery tiles in the client (issue #19, the paper's §7.3): colour
// tiles of the terrain's own quadtree, stored apart from it (docs/store-format.md "Imagery"),
// fetched through the same download pool, disk and RAM tiers as terrain tiles (TileKind::imagery
// keys, the imagery layer appended to the loader's layer table) and draped as textures.
//
// Which imagery tile drapes a terrain tile T (drape.cpp): the imagery tile of T's quadkey when
// the imagery has it; T deeper than the imagery's finest level, or that tile absent (404) or
// broken: the nearest ancestor the imagery has, through the sub-rectangle that T covers in it
// (ancestor_uv). Texture coordinates are each vertex's Mercator position in T (MeshVertex::u, v),
// exact because both tile sets share the quadtree. T is never held back for its imagery: until a
// texture is resident it is drawn with the nearest resident ancestor's, else the colour ramp.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>

#include "tinstream/base/result.hpp"
#include "tinstream/client/layer.hpp"
#include "tinstream/client/render_mesh.hpp"
#include "tinstream/client/tile_key.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/imagery/image.hpp"

namespace tinstream::store {
struct ImageryInfo;
}

namespace tinstream::client {

// The largest imagery tile side the client accepts (the store writes 256).
inline constexpr std::uint32_t kMaxImageryTileSize = 4096;

LayerDescription from_imagery_info(const store::ImageryInfo& info);
// The imagery layer `name` from the server's GET /layers answer ({"imagery": [...]}). Errors: the
// answer is malformed, or the server has no imagery layer of that name (not_found, naming the
// layers it has).
Result<LayerDescription> parse_imagery_json(std::string_view layers_json, std::string_view name);

// What a download worker does with an imagery payload: inflate (a proxy may have compressed it),
// decode PNG / JPEG / WebP, check that the image is square and at most kMaxImageryTileSize.
// Errors name the tile and the layer.
Result<imagery::RgbaImage> decode_imagery_tile(std::span<const std::uint8_t> payload,
                                               ContentEncoding encoding,
                                               const LayerDescription& layer, const TileKey& key);

// The texture transform of tile `tile` inside its ancestor (or itself) `ancestor`: a point at
// (u, v) in `tile` (0…1, west → east, north → south) lies at (u·s + du, v·s + dv) in
// `ancestor`'s image; returns {s, s, du, dv}. Requires: ancestor is tile or one of its ancestors.
std::array<float, 4> ancestor_uv(const geo::TileId& tile, const geo::TileId& ancestor);

}  // namespace tinstream::client
