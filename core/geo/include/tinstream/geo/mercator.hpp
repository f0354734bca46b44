// tinstream/geo/mercator.hpp — the internal planar frame: normalised Mercator (docs/DESIGN.md §2).
//
//   x = λ / π                        ∈ [-1, 1]
//   y = (1/π) · ln( tan(π/4 + φ/2) · ((1 − e sinφ)/(1 + e sinφ))^(e/2) )   ∈ [-1, 1]
//
// This is the paper's Listing 1 with the 1/π factor restored in the spherical branch (e = 0).
// `spherical` (default) tiles coincide with EPSG:3857 / Bing / Cesium Web Mercator tiles and
// reach ±85.0511°; `ellipsoidal` uses the WGS84 eccentricity (i3D's choice) and reaches ±85.0841°.
// Geodetic coordinates are always on the WGS84 ellipsoid; only the Mercator formula differs.
//
// Accuracy: the forward map is computed through the conformal-latitude form of GeographicLib
// (Math::taupf), the inverse with Math::tauf (Newton on tan φ), < 1e-9° round trip everywhere.
// All functions are pure and thread-safe.
#pragma once

#include <optional>
#include <string_view>

#include "tinstream/base/result.hpp"

namespace tinstream::geo {

// Geodetic position: degrees, WGS84.
struct LonLat {
  double lon = 0;  // east positive, [-180, 180]
  double lat = 0;  // north positive
};

// A point in normalised Mercator, both coordinates in [-1, 1] inside the map.
struct MercatorXY {
  double x = 0;
  double y = 0;
};

enum class Projection { spherical, ellipsoidal };

std::string_view to_string(Projection p);
Result<Projection> parse_projection(std::string_view text);

class NormalisedMercator {
 public:
  explicit NormalisedMercator(Projection projection = Projection::spherical);

  Projection projection() const { return projection_; }
  // The first eccentricity used in the formula (0 for spherical, WGS84's e for ellipsoidal).
  double eccentricity() const { return e_; }
  // Latitude (degrees) where y = 1: 85.05112878° spherical, 85.08405905° ellipsoidal.
  double max_latitude() const { return max_lat_; }

  // Unchecked forward map; any finite latitude in (-90, 90) gives a finite y (|y| may exceed 1).
  MercatorXY forward(LonLat p) const;
  // Forward map that rejects non-finite values and points outside the square [-1, 1]².
  Result<MercatorXY> forward_checked(LonLat p) const;
  // Inverse map; defined for all finite x, y (|x| > 1 gives |lon| > 180).
  LonLat inverse(MercatorXY m) const;

  // Pieces of the above, for code that needs just one axis.
  double y_from_lat(double lat_deg) const;
  double lat_from_y(double y) const;
  static double x_from_lon(double lon_deg);
  static double lon_from_x(double x);

 private:
  Projection projection_;
  double e_;
  double max_lat_;
};

}  // namespace tinstream::geo
