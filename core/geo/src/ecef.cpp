#include "tinstream/geo/ecef.hpp"

#include <GeographicLib/Geocentric.hpp>

namespace tinstream::geo {

Ecef to_ecef(const Geodetic& g) {
  Ecef e;
  GeographicLib::Geocentric::WGS84().Forward(g.lat, g.lon, g.height, e.x, e.y, e.z);
  return e;
}

Geodetic from_ecef(const Ecef& e) {
  Geodetic g;
  GeographicLib::Geocentric::WGS84().Reverse(e.x, e.y, e.z, g.lat, g.lon, g.height);
  return g;
}

}  // namespace tinstream::geo
