// Test helper: geodetic → ECEF through GeographicLib (geo::to_ecef), as a client Vec3.
#pragma once

#include "tinstream/client/vec.hpp"
#include "tinstream/geo/ecef.hpp"

namespace tinstream::client::testing {

inline Vec3 ecef(double lon, double lat, double h) {
  const geo::Ecef e = geo::to_ecef({lon, lat, h});
  return {e.x, e.y, e.z};
}

}  // namespace tinstream::client::testing
