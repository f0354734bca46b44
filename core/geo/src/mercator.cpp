#include "tinstream/geo/mercator.hpp"

#include <GeographicLib/Math.hpp>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "tinstream/geo/ecef.hpp"

namespace tinstream::geo {
namespace {

constexpr double kPi = std::numbers::pi;

double wgs84_eccentricity() { return std::sqrt(kWgs84F * (2.0 - kWgs84F)); }

}  // namespace

std::string_view to_string(Projection p) {
  return p == Projection::spherical ? "spherical" : "ellipsoidal";
}

Result<Projection> parse_projection(std::string_view text) {
  if (text == "spherical") return Projection::spherical;
  if (text == "ellipsoidal") return Projection::ellipsoidal;
  return invalid_argument("unknown projection '" + std::string(text) +
                          "' (expected 'spherical' or 'ellipsoidal')");
}

NormalisedMercator::NormalisedMercator(Projection projection)
    : projection_(projection),
      e_(projection == Projection::spherical ? 0.0 : wgs84_eccentricity()),
      max_lat_(0) {
  max_lat_ = lat_from_y(1.0);
}

double NormalisedMercator::x_from_lon(double lon_deg) { return lon_deg / 180.0; }
double NormalisedMercator::lon_from_x(double x) { return x * 180.0; }

// y·π = asinh(τ'), τ' = tan χ with χ the conformal latitude; Math::taupf evaluates τ' from
// τ = tan φ without the cancellation of the textbook ln(tan(π/4 + φ/2)…) near the equator.
// This equals the formula of docs/DESIGN.md §2:
// ln(tan(π/4+φ/2)·((1−e sinφ)/(1+e sinφ))^(e/2)) = asinh(τ').
double NormalisedMercator::y_from_lat(double lat_deg) const {
  const double tau = GeographicLib::Math::tand(lat_deg);
  // On the sphere (e = 0) τ' = τ: taupf(τ, 0) = hypot(1, sinh 0)·τ − sinh(0)·hypot(1, τ) is τ to
  // the bit for every finite τ, so its three library calls are skipped (pass 1 calls this for
  // every point).
  const double taup = e_ == 0.0 ? tau : GeographicLib::Math::taupf(tau, e_);
  return std::asinh(taup) / kPi;
}

double NormalisedMercator::lat_from_y(double y) const {
  const double taup = std::sinh(y * kPi);
  const double tau = GeographicLib::Math::tauf(taup, e_);
  return GeographicLib::Math::atand(tau);
}

MercatorXY NormalisedMercator::forward(LonLat p) const {
  return {x_from_lon(p.lon), y_from_lat(p.lat)};
}

Result<MercatorXY> NormalisedMercator::forward_checked(LonLat p) const {
  if (!std::isfinite(p.lon) || !std::isfinite(p.lat)) {
    return invalid_argument("non-finite coordinate (lon " + std::to_string(p.lon) + ", lat " +
                            std::to_string(p.lat) + ")");
  }
  if (p.lon < -180.0 || p.lon > 180.0) {
    return invalid_argument("longitude " + std::to_string(p.lon) + " outside [-180, 180]");
  }
  if (std::abs(p.lat) > max_lat_) {
    return invalid_argument("latitude " + std::to_string(p.lat) + " outside the " +
                            std::string(to_string(projection_)) + " Mercator range ±" +
                            std::to_string(max_lat_));
  }
  MercatorXY m = forward(p);
  // The limit latitude itself may round to |y| a hair above 1; it is on the map's edge.
  m.y = std::clamp(m.y, -1.0, 1.0);
  return m;
}

LonLat NormalisedMercator::inverse(MercatorXY m) const {
  return {lon_from_x(m.x), lat_from_y(m.y)};
}

}  // namespace tinstream::geo
