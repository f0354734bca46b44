#include "tinstream/geo/mercator.hpp"

#include <gtest/gtest.h>
#include <proj.h>

#include <GeographicLib/Math.hpp>
#include <bit>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <random>

#include "tinstream/geo/ecef.hpp"

namespace tinstream::geo {
namespace {

constexpr double kPi = std::numbers::pi;

// The textbook formula of docs/DESIGN.md §2 in long double, written independently of the library's
// conformal-latitude form, as a reference.
long double textbook_y(long double lat_deg, long double e) {
  const long double phi = lat_deg * std::numbers::pi_v<long double> / 180.0L;
  const long double s = std::sin(phi);
  const long double t = std::tan(std::numbers::pi_v<long double> / 4.0L + phi / 2.0L);
  return std::log(t * std::pow((1.0L - e * s) / (1.0L + e * s), e / 2.0L)) /
         std::numbers::pi_v<long double>;
}

// Snyder (1987) eq. 7-9 fixed-point iteration for the ellipsoidal inverse, in long double.
long double snyder_lat(long double y, long double e) {
  const long double t = std::exp(-y * std::numbers::pi_v<long double>);
  long double phi = std::numbers::pi_v<long double> / 2.0L - 2.0L * std::atan(t);
  for (int i = 0; i < 100; ++i) {
    const long double s = e * std::sin(phi);
    const long double next = std::numbers::pi_v<long double> / 2.0L -
                             2.0L * std::atan(t * std::pow((1.0L - s) / (1.0L + s), e / 2.0L));
    if (next == phi) break;
    phi = next;
  }
  return phi * 180.0L / std::numbers::pi_v<long double>;
}

TEST(Mercator, SphericalLimitLatitudeMapsToOne) {
  const NormalisedMercator m(Projection::spherical);
  EXPECT_NEAR(m.max_latitude(), 85.0511287798066, 1e-12);
  EXPECT_NEAR(m.y_from_lat(85.0511287798066), 1.0, 1e-13);
  EXPECT_NEAR(m.y_from_lat(-85.0511287798066), -1.0, 1e-13);
}

TEST(Mercator, EllipsoidalLimitLatitudeMapsToOne) {
  const NormalisedMercator m(Projection::ellipsoidal);
  EXPECT_NEAR(m.max_latitude(), 85.0840590501, 1e-9);
  EXPECT_NEAR(m.y_from_lat(m.max_latitude()), 1.0, 1e-14);
  EXPECT_NEAR(m.y_from_lat(-85.0840590501), -1.0, 1e-10);
}

TEST(Mercator, LongitudeIsLinear) {
  const NormalisedMercator m;
  EXPECT_EQ(m.forward({180, 0}).x, 1.0);
  EXPECT_EQ(m.forward({-180, 0}).x, -1.0);
  EXPECT_EQ(m.forward({90, 0}).x, 0.5);
  EXPECT_EQ(m.forward({0, 0}).y, 0.0);
}

TEST(Mercator, MatchesTextbookFormulaBothProjections) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> lat(-85.0, 85.0);
  for (Projection p : {Projection::spherical, Projection::ellipsoidal}) {
    const NormalisedMercator m(p);
    for (int i = 0; i < 10000; ++i) {
      const double phi = lat(rng);
      const long double ref = textbook_y(phi, m.eccentricity());
      EXPECT_NEAR(m.y_from_lat(phi), static_cast<double>(ref), 2e-15) << phi;
    }
  }
}

TEST(Mercator, SphericalInverseIsGudermannian) {
  const NormalisedMercator m(Projection::spherical);
  for (double y = -1.0; y <= 1.0; y += 1.0 / 1024) {
    const double ref = (2.0 * std::atan(std::exp(kPi * y)) - kPi / 2) * 180.0 / kPi;
    EXPECT_NEAR(m.lat_from_y(y), ref, 1e-12) << y;
  }
}

TEST(Mercator, EllipsoidalInverseMatchesSnyderIteration) {
  const NormalisedMercator m(Projection::ellipsoidal);
  for (double y = -1.0; y <= 1.0; y += 1.0 / 1024) {
    EXPECT_NEAR(m.lat_from_y(y), static_cast<double>(snyder_lat(y, m.eccentricity())), 1e-11) << y;
  }
}

TEST(Mercator, SphericalForwardIsGeographicLibsConformalFormToTheBit) {
  // The spherical forward skips Math::taupf (τ' = τ when e = 0): every y must equal the general
  // form asinh(taupf(tand(φ), 0)) / π bit for bit — random latitudes, ±0, subnormal and tiny
  // ones, and the limits.
  const NormalisedMercator m(Projection::spherical);
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> lat(-m.max_latitude(), m.max_latitude());
  std::vector<double> lats{0.0,   -0.0, 5e-324, -5e-324,          1e-300,           -1e-170,
                           1e-10, 45.0, -45.0,  m.max_latitude(), -m.max_latitude()};
  for (int i = 0; i < 1000000; ++i) lats.push_back(lat(rng));
  for (const double phi : lats) {
    const double general =
        std::asinh(GeographicLib::Math::taupf(GeographicLib::Math::tand(phi), 0.0)) / kPi;
    const double y = m.forward({0.0, phi}).y;
    ASSERT_EQ(std::bit_cast<std::uint64_t>(y), std::bit_cast<std::uint64_t>(general)) << phi;
  }
}

TEST(Mercator, RoundTripMillionRandomPointsBothProjections) {
  std::mt19937_64 rng(7);
  for (Projection p : {Projection::spherical, Projection::ellipsoidal}) {
    const NormalisedMercator m(p);
    std::uniform_real_distribution<double> lon(-180.0, 180.0);
    std::uniform_real_distribution<double> lat(-m.max_latitude(), m.max_latitude());
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    double worst_geo = 0, worst_xy = 0;
    for (int i = 0; i < 1000000; ++i) {
      const LonLat g{lon(rng), lat(rng)};
      const LonLat back = m.inverse(m.forward(g));
      worst_geo = std::max({worst_geo, std::abs(back.lat - g.lat), std::abs(back.lon - g.lon)});
      const MercatorXY xy{unit(rng), unit(rng)};
      const MercatorXY again = m.forward(m.inverse(xy));
      worst_xy = std::max({worst_xy, std::abs(again.x - xy.x), std::abs(again.y - xy.y)});
    }
    EXPECT_LT(worst_geo, 1e-9) << to_string(p);
    EXPECT_LT(worst_xy, 1e-13) << to_string(p);
  }
}

TEST(Mercator, ForwardCheckedRejectsBadInput) {
  const NormalisedMercator m;
  EXPECT_FALSE(m.forward_checked({NAN, 0}).ok());
  EXPECT_FALSE(m.forward_checked({0, INFINITY}).ok());
  EXPECT_FALSE(m.forward_checked({181, 0}).ok());
  const auto polar = m.forward_checked({0, 86});
  ASSERT_FALSE(polar.ok());
  EXPECT_NE(polar.error().message.find("latitude 86"), std::string::npos) << polar.error().message;
  EXPECT_TRUE(m.forward_checked({0, 85.0}).ok());
  EXPECT_TRUE(NormalisedMercator(Projection::ellipsoidal).forward_checked({0, 85.07}).ok());
}

TEST(Mercator, ParseProjection) {
  EXPECT_EQ(*parse_projection("spherical"), Projection::spherical);
  EXPECT_EQ(*parse_projection("ellipsoidal"), Projection::ellipsoidal);
  EXPECT_FALSE(parse_projection("utm").ok());
}

// PROJ as an independent peer: EPSG:3857 is a·π·(spherical y), EPSG:3395 (World Mercator) is
// a·π·(ellipsoidal y), both with x = a·λ.
struct ProjDeleter {
  void operator()(PJ* p) const { proj_destroy(p); }
  void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
};

void compare_with_proj(Projection projection, const char* target_crs) {
  std::unique_ptr<PJ_CONTEXT, ProjDeleter> ctx(proj_context_create());
  std::unique_ptr<PJ, ProjDeleter> raw(
      proj_create_crs_to_crs(ctx.get(), "EPSG:4326", target_crs, nullptr));
  ASSERT_TRUE(raw) << "PROJ could not build EPSG:4326 -> " << target_crs;
  std::unique_ptr<PJ, ProjDeleter> pj(proj_normalize_for_visualization(ctx.get(), raw.get()));
  ASSERT_TRUE(pj);
  const NormalisedMercator m(projection);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> lon(-179.9, 179.9), lat(-85.0, 85.0);
  for (int i = 0; i < 2000; ++i) {
    const LonLat g{lon(rng), lat(rng)};
    const PJ_COORD out = proj_trans(pj.get(), PJ_FWD, proj_coord(g.lon, g.lat, 0, 0));
    const MercatorXY xy = m.forward(g);
    EXPECT_NEAR(xy.x * kPi * kWgs84A, out.xy.x, 1e-6);  // metres: micrometre agreement
    EXPECT_NEAR(xy.y * kPi * kWgs84A, out.xy.y, 1e-6);
  }
}

TEST(Mercator, SphericalAgreesWithProjWebMercator) {
  compare_with_proj(Projection::spherical, "EPSG:3857");
}

TEST(Mercator, EllipsoidalAgreesWithProjWorldMercator) {
  compare_with_proj(Projection::ellipsoidal, "EPSG:3395");
}

}  // namespace
}  // namespace tinstream::geo
