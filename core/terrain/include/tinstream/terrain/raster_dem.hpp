// tinstream/terrain/raster_dem.hpp — raster-DEM tiles (Terrarium, Mapbox Terrain-RGB) rendered
// from a TIN tile, for web maps whose 3D terrain reads heights from image tiles (MapLibre GL JS
// `raster-dem` sources, Mapbox, Tangram…).
//
// Pixel (i, j) of a size × size raster — i to the east, j to the south — samples the TIN at its
// centre: x = west + (i + ½)·w/size, y = north − (j + ½)·h/size in the tile's normalised Mercator
// rectangle (for a spherical layer: the EPSG:3857 tile z/x/y, as web maps expect). The height is
// the TIN's linear interpolation in the triangle containing that point (found with exact
// orientation tests; a centre on a shared edge takes either triangle, which agree there), encoded
// in R, G, B:
//   terrarium  h = R·256 + G + B/256 − 32768          step 1/256 m, range [−32768, 32768)
//   mapbox     h = −10000 + (R·65536 + G·256 + B)·0.1  step 0.1 m,   range [−10000, 1667721.5]
// rounded to the nearest step (so a decoded height is within step/2 of the TIN's) and clamped to
// the range. In NODATA triangles (those with a NODATA corner, TinTile::is_nodata_triangle;
// docs/tile-format.md §2.1) the height is the triangle's plane like anywhere else, the NODATA
// corners carrying heights continued from the data (no wall, and no crease inside the triangle
// for a hillshade to show); a NODATA corner outside the tile's data range (tiles written when
// those sat at height 0) is left out and the other vertices' weights renormalised, so no wall
// comes back there either. Their pixels are, by DemNodata:
//   opaque       alpha 255, like the data. What browsers need: they premultiply alpha when they
//                decode a PNG into a canvas or texture, so a transparent pixel's R, G, B become 0,
//                i.e. −32768 m (Terrarium) or −10000 m (Terrain-RGB) in MapLibre: a wall.
//   transparent  alpha 0, same R, G, B: the footprint, for clients that decode the PNG themselves.
// DemRaster::nodata_pixels counts them either way.
//
// Pure functions, thread-safe.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::terrain {

enum class DemEncoding { terrarium, mapbox };
enum class DemNodata { opaque, transparent };

std::string_view to_string(DemEncoding e);
// "terrarium" or "mapbox" (Mapbox Terrain-RGB).
Result<DemEncoding> parse_dem_encoding(std::string_view text);
std::string_view to_string(DemNodata n);
// "opaque" or "transparent".
Result<DemNodata> parse_dem_nodata(std::string_view text);

// The height step of an encoding in metres (1/256 or 0.1).
double dem_step(DemEncoding e);
std::array<std::uint8_t, 3> encode_dem_height(DemEncoding e, double height);
double decode_dem_height(DemEncoding e, std::uint8_t r, std::uint8_t g, std::uint8_t b);

struct DemRaster {
  std::uint32_t size = 0;
  std::vector<std::uint8_t> rgba;  // size × size × 4, rows north to south
  std::uint64_t nodata_pixels = 0;
};

// Requires: 1 ≤ size ≤ 4096 (else invalid_argument). A malformed tile — an index out of range, a
// non-finite vertex, a pixel centre no triangle covers, triangles overlapping so much that their
// bounding boxes cover the raster more than 256 times (the work is bounded by that) — is a
// corrupt_data error naming the tile, never a crash.
Result<DemRaster> render_raster_dem(const tile::TinTile& tile, DemEncoding encoding,
                                    std::uint32_t size = 256, DemNodata nodata = DemNodata::opaque);

}  // namespace tinstream::terrain
