// Rasters for the imagery tests, written with GDAL: a generated orthophoto with coloured
// ground-control markers, an orthophoto made from a real DEM, and helpers that locate pixels in
// lon/lat and decode tiles through GDAL (independently of the code under test).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "tinstream/geo/mercator.hpp"
#include "tinstream/geo/tile_id.hpp"

namespace tinstream::imagery::testing {

// A marker: a square of one colour centred on a source pixel centre.
struct Marker {
  double column = 0, row = 0;  // the pixel centre of the marker's centre, in source pixels
  std::array<std::uint8_t, 3> rgb{};
};

struct Orthophoto {
  std::filesystem::path path;
  int epsg = 32611;
  double origin_x = 0, origin_y = 0;  // north-west corner, CRS units
  double pixel = 1;                   // CRS units per pixel (square)
  int width = 0, height = 0;
  std::vector<Marker> markers;
  int marker_half = 0;  // markers span 2·half + 1 pixels

  // The CRS coordinates of a point given in source pixels (0,0 = north-west corner).
  std::array<double, 2> crs_of(double column, double row) const {
    return {origin_x + column * pixel, origin_y - row * pixel};
  }
};

// An RGB GeoTIFF (EPSG:`epsg`, north-up) of a smooth colour gradient with five markers of
// saturated colours (red, green, blue, yellow, magenta) well inside it, and an optional alpha
// band that makes the west tenth of the image transparent.
Orthophoto write_marker_orthophoto(const std::filesystem::path& path, int epsg, double origin_x,
                                   double origin_y, double pixel, int width, int height,
                                   bool alpha = false);

// An RGB GeoTIFF in the DEM's CRS and grid: a hypsometric colour ramp shaded by a hillshade
// (GDALDEMProcessing), i.e. what an orthophoto of steep terrain looks like to a tiler.
bool write_orthophoto_from_dem(const std::filesystem::path& dem, const std::filesystem::path& out);

// EPSG:`epsg` coordinates → WGS84 lon/lat through OGR (traditional x/y order).
std::array<double, 2> to_lonlat(int epsg, double x, double y);
// WGS84 lon/lat → EPSG:`epsg` coordinates.
std::array<double, 2> from_lonlat(int epsg, double lon, double lat);

// The fractional pixel position (x right, y down, 0..size) of a lon/lat in tile `id` of a layer
// in `projection`, from the quadtree's tile bounds.
std::array<double, 2> pixel_in_tile(const geo::TileId& id, geo::Projection projection, double lon,
                                    double lat, std::uint32_t size = 256);

// Decodes an encoded image with GDAL (PNG, JPEG, WebP drivers) into RGBA rows; empty on failure.
struct DecodedImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
  const std::uint8_t* at(int x, int y) const {
    return rgba.data() + static_cast<std::size_t>(y * width + x) * 4;
  }
};
DecodedImage gdal_decode(const std::vector<std::uint8_t>& bytes);

// Reads band values of a raster at integer pixel (column, row); bands 1..n.
std::vector<std::uint8_t> read_pixel(const std::filesystem::path& raster, int column, int row);

}  // namespace tinstream::imagery::testing
