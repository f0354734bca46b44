// tinstream/geo/ecef.hpp — geodetic ↔ Earth-centred Earth-fixed (WGS84), via GeographicLib.
//
// Used by the client (double-precision ECEF vertices) and the quantized-mesh encoder (bounding
// spheres, horizon occlusion points). Pure and thread-safe.
#pragma once

namespace tinstream::geo {

struct Ecef {
  double x = 0, y = 0, z = 0;  // metres
};

struct Geodetic {
  double lon = 0;     // degrees
  double lat = 0;     // degrees
  double height = 0;  // metres above the WGS84 ellipsoid
};

Ecef to_ecef(const Geodetic& g);
Geodetic from_ecef(const Ecef& e);

// WGS84 constants.
inline constexpr double kWgs84A = 6378137.0;
inline constexpr double kWgs84F = 1.0 / 298.257223563;

}  // namespace tinstream::geo
