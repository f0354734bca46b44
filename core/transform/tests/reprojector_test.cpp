#include "tinstream/transform/reprojector.hpp"

#include <gdal.h>
#include <gtest/gtest.h>
#include <proj.h>

#include <GeographicLib/UTMUPS.hpp>
#include <cmath>

namespace tinstream::transform {
namespace {

using sources::SourceInfo;
using sources::SourcePoint;

const std::filesystem::path kReprojectorData = TINSTREAM_SHARED_DATA;

Result<std::vector<SourcePoint>> read_all(sources::PointSource& src) {
  std::vector<SourcePoint> all;
  while (true) {
    auto n = src.read(all, 50000);
    if (!n.ok()) return n.error();
    if (*n == 0) break;
  }
  return all;
}

SourceInfo info_with(const std::string& crs, const std::string& path = "test-input") {
  SourceInfo info;
  info.path = path;
  info.crs = crs;
  return info;
}

TEST(Reprojector, AutzenLandsInEugeneWithFeetConvertedToMetres) {
  const auto path = kReprojectorData / "autzen_trim.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = sources::open_source(path);
  ASSERT_TRUE(src.ok()) << src.error().message;
  auto pts = read_all(**src);
  ASSERT_TRUE(pts.ok());
  ASSERT_EQ(pts->size(), 26107u);
  auto rp = Reprojector::create((*src)->info(), {});
  ASSERT_TRUE(rp.ok()) << rp.error().message;
  EXPECT_EQ(rp->plan().z_unit.to_metre, 0.3048);
  EXPECT_NE(rp->plan().z_unit_rule.find("horizontal"), std::string::npos);
  std::vector<GeoPoint> out;
  ASSERT_TRUE(rp->transform(*pts, out).ok());
  ASSERT_EQ(out.size(), pts->size());
  double lon0 = 1e9, lon1 = -1e9, lat0 = 1e9, lat1 = -1e9, h0 = 1e9, h1 = -1e9;
  for (const auto& g : out) {
    lon0 = std::min(lon0, g.lon), lon1 = std::max(lon1, g.lon);
    lat0 = std::min(lat0, g.lat), lat1 = std::max(lat1, g.lat);
    h0 = std::min(h0, g.h), h1 = std::max(h1, g.h);
  }
  // SOURCES.md: about -123.0734, 44.0499 to -123.0690, 44.0516 (4 decimals ≈ 10 m).
  EXPECT_NEAR(lon0, -123.0734, 2e-4);
  EXPECT_NEAR(lon1, -123.0690, 2e-4);
  EXPECT_NEAR(lat0, 44.0499, 2e-4);
  EXPECT_NEAR(lat1, 44.0516, 2e-4);
  // Ground z 406.26 – 434.06 international feet.
  EXPECT_NEAR(h0, 406.26 * 0.3048, 0.005);
  EXPECT_NEAR(h1, 434.06 * 0.3048, 0.005);
}

TEST(Reprojector, AutzenWktMatchesEpsg2994) {
  // SOURCES.md: the WKT's parameters are those of EPSG:2994; both must give the same places.
  const auto path = kReprojectorData / "autzen_trim.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = sources::open_source(path);
  ASSERT_TRUE(src.ok());
  std::vector<SourcePoint> pts;
  ASSERT_TRUE((*src)->read(pts, 100).ok());
  auto a = Reprojector::create((*src)->info(), {});
  ReprojectOptions epsg;
  epsg.crs = "EPSG:2994";
  auto b = Reprojector::create((*src)->info(), epsg);
  ASSERT_TRUE(a.ok() && b.ok());
  std::vector<GeoPoint> ga, gb;
  ASSERT_TRUE(a->transform(pts, ga).ok());
  ASSERT_TRUE(b->transform(pts, gb).ok());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR(ga[i].lon, gb[i].lon, 1e-7);  // ≈ 1 cm
    EXPECT_NEAR(ga[i].lat, gb[i].lat, 1e-7);
  }
}

TEST(Reprojector, NewMexicoUsSurveyFeet) {
  const auto path = kReprojectorData / "nm_4_6_crop.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = sources::open_source(path);
  ASSERT_TRUE(src.ok());
  auto pts = read_all(**src);
  ASSERT_TRUE(pts.ok());
  auto rp = Reprojector::create((*src)->info(), {});
  ASSERT_TRUE(rp.ok()) << rp.error().message;
  EXPECT_EQ(rp->plan().z_unit.name, "US survey foot");
  std::vector<GeoPoint> out;
  ASSERT_TRUE(rp->transform(*pts, out).ok());
  double h0 = 1e9, h1 = -1e9;
  for (const auto& g : out) {
    ASSERT_NEAR(g.lon, -106.252, 0.005);
    ASSERT_NEAR(g.lat, 34.998, 0.005);
    h0 = std::min(h0, g.h), h1 = std::max(h1, g.h);
  }
  // Ground 7077.92 – 7093.86 ftUS; a US survey foot is 1200/3937 m.
  EXPECT_NEAR(h0, 7077.92 * 1200.0 / 3937.0, 0.005);
  EXPECT_NEAR(h1, 7093.86 * 1200.0 / 3937.0, 0.005);
  // International feet would be off by 2 ppm: 4 mm here. Make sure we did not use them.
  EXPECT_GT(std::abs(h0 - 7077.92 * 0.3048), 0.003);
}

TEST(Reprojector, UtmRoundTripAgreesWithGeographicLib) {
  for (int zone : {33, 10}) {
    for (bool north : {true, false}) {
      const std::string crs = "EPSG:" + std::to_string((north ? 32600 : 32700) + zone);
      SCOPED_TRACE(crs);
      const double lon_c = -183.0 + 6.0 * zone;
      std::vector<SourcePoint> in;
      std::vector<std::pair<double, double>> truth;
      for (int i = 0; i < 9; ++i) {
        for (int j = 0; j < 9; ++j) {
          const double lat = (north ? 1 : -1) * (1.0 + 9.5 * i);
          const double lon = lon_c - 2.9 + 0.725 * j;
          int z = 0;
          bool n = false;
          double x = 0, y = 0;
          GeographicLib::UTMUPS::Forward(lat, lon, z, n, x, y, zone);
          in.push_back(SourcePoint{x, y, 10.0 * i, static_cast<std::uint64_t>(in.size() + 1), 0});
          truth.emplace_back(lon, lat);
        }
      }
      auto rp = Reprojector::create(info_with(crs), {});
      ASSERT_TRUE(rp.ok()) << rp.error().message;
      std::vector<GeoPoint> out;
      ASSERT_TRUE(rp->transform(in, out).ok());
      for (std::size_t k = 0; k < in.size(); ++k) {
        EXPECT_NEAR(out[k].lon, truth[k].first, 1e-9);
        EXPECT_NEAR(out[k].lat, truth[k].second, 1e-9);
        EXPECT_DOUBLE_EQ(out[k].h, in[k].z);  // metres, ellipsoidal: unchanged
      }
    }
  }
}

TEST(Reprojector, GeographicInputKeepsLonLatOrder) {
  // EPSG:4326's official axis order is lat, lon; sources give x = lon. Must stay lon/lat.
  auto rp = Reprojector::create(info_with("EPSG:4326"), {});
  ASSERT_TRUE(rp.ok());
  std::vector<SourcePoint> in = {{10.5, 0.25, 100, 1, 0}};
  std::vector<GeoPoint> out;
  ASSERT_TRUE(rp->transform(in, out).ok());
  EXPECT_NEAR(out[0].lon, 10.5, 1e-12);
  EXPECT_NEAR(out[0].lat, 0.25, 1e-12);
  EXPECT_EQ(out[0].h, 100);
  EXPECT_EQ(rp->plan().z_unit.to_metre, 1.0);
}

TEST(Reprojector, CompoundCrsTakesTheVerticalAxisUnit) {
  // NAD83 / UTM 10N + NAVD88 height (ftUS).
  auto rp = Reprojector::create(info_with("EPSG:26910+6360"), {});
  ASSERT_TRUE(rp.ok()) << rp.error().message;
  EXPECT_NEAR(rp->plan().z_unit.to_metre, 1200.0 / 3937.0, 1e-12);
  EXPECT_EQ(rp->plan().z_unit_rule, "the CRS's vertical axis");
}

TEST(Reprojector, ZUnitOptionOverrides) {
  ReprojectOptions o;
  o.z_unit = sources::LinearUnit{"metre", 1.0};
  auto rp = Reprojector::create(info_with("EPSG:2994"), o);  // a feet CRS
  ASSERT_TRUE(rp.ok());
  EXPECT_EQ(rp->plan().z_unit.to_metre, 1.0);
  EXPECT_EQ(rp->plan().z_unit_rule, "given by the user");
}

TEST(Reprojector, UnknownCrsIsAClearErrorNamingTheFile) {
  for (const std::string bad :
       {"EPSG:999999", "PROJCS[\"broken\",", "+proj=nonsense", "not a crs at all"}) {
    auto rp = Reprojector::create(info_with(bad, "/data/in.las"), {});
    ASSERT_FALSE(rp.ok()) << bad;
    EXPECT_EQ(rp.error().code, ErrorCode::unsupported);
    EXPECT_NE(rp.error().message.find("/data/in.las"), std::string::npos) << rp.error().message;
    EXPECT_NE(rp.error().message.find("CRS"), std::string::npos) << rp.error().message;
  }
}

TEST(Reprojector, MissingCrsAsksForCrsOption) {
  const auto path = kReprojectorData / "boulder_srtmgl3.asc";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = sources::open_source(path);
  ASSERT_TRUE(src.ok());
  auto rp = Reprojector::create((*src)->info(), {});
  ASSERT_FALSE(rp.ok());
  EXPECT_NE(rp.error().message.find("--crs"), std::string::npos) << rp.error().message;
  EXPECT_NE(rp.error().message.find("boulder_srtmgl3.asc"), std::string::npos);
  ReprojectOptions o;
  o.crs = "EPSG:4326";
  auto ok = Reprojector::create((*src)->info(), o);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  std::vector<SourcePoint> pts;
  ASSERT_TRUE((*src)->read(pts, 10).ok());
  std::vector<GeoPoint> out;
  ASSERT_TRUE(ok->transform(pts, out).ok());
  EXPECT_NEAR(out[0].lon, -105.55, 0.001);
  EXPECT_NEAR(out[0].lat, 40.21, 0.001);
}

TEST(Reprojector, GeocentricCrsIsRefused) {
  auto rp = Reprojector::create(info_with("EPSG:4978"), {});
  ASSERT_FALSE(rp.ok());
  EXPECT_EQ(rp.error().code, ErrorCode::unsupported);
}

TEST(Reprojector, MissingGeoidGridNamesTheGridAndHowToGetIt) {
  ReprojectOptions o;
  o.vertical_datum = "tinstream_no_such_geoid.tif";
  auto rp = Reprojector::create(info_with("EPSG:4326", "/data/x.xyz"), o);
  ASSERT_FALSE(rp.ok());
  EXPECT_EQ(rp.error().code, ErrorCode::not_found);
  const std::string& m = rp.error().message;
  EXPECT_NE(m.find("tinstream_no_such_geoid.tif"), std::string::npos) << m;
  EXPECT_NE(m.find("projsync"), std::string::npos) << m;
  EXPECT_NE(m.find("PROJ_DATA"), std::string::npos) << m;
  EXPECT_NE(m.find("/data/x.xyz"), std::string::npos) << m;
}

TEST(Reprojector, Egm2008MissingOrWorking) {
  ReprojectOptions o;
  o.vertical_datum = "egm2008";
  auto rp = Reprojector::create(info_with("EPSG:4326"), o);
  if (rp.ok()) GTEST_SKIP() << "EGM2008 grid installed here: " << rp->plan().geoid_grid;
  EXPECT_EQ(rp.error().code, ErrorCode::not_found);
  EXPECT_NE(rp.error().message.find("us_nga_egm08_25.tif"), std::string::npos);
}

TEST(Reprojector, UnknownVerticalDatumIsInvalid) {
  ReprojectOptions o;
  o.vertical_datum = "navd88-please";
  auto rp = Reprojector::create(info_with("EPSG:4326"), o);
  ASSERT_FALSE(rp.ok());
  EXPECT_EQ(rp.error().code, ErrorCode::invalid_argument);
}

TEST(Reprojector, Egm96AddsTheGeoidUndulationReadIndependentlyWithGdal) {
  ReprojectOptions o;
  o.vertical_datum = "egm96";
  auto rp = Reprojector::create(info_with("EPSG:4326"), o);
  if (!rp.ok()) GTEST_SKIP() << "EGM96 grid not installed: " << rp.error().message;
  // Independent reference: sample the installed grid file itself with GDAL (nearest cell;
  // the 15' grid varies by well under a metre between cells here).
  const char* gtx = nullptr;
  for (const char* c : {"/usr/share/proj/egm96_15.gtx", "/usr/share/proj/us_nga_egm96_15.tif"}) {
    if (std::filesystem::exists(c)) gtx = c;
  }
  if (gtx == nullptr) GTEST_SKIP() << "grid file not at a known path for the GDAL reference";
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(gtx, GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  double gt[6];
  GDALGetGeoTransform(ds, gt);
  const std::vector<std::pair<double, double>> places = {
      {-123.071, 44.0507}, {10.5, 0.5}, {-105.45, 40.15}, {6.1, 49.8}};
  std::vector<SourcePoint> in;
  in.reserve(places.size());
  for (const auto& [lon, lat] : places)
    in.push_back(SourcePoint{lon, lat, 100.0, in.size() + 1, 0});
  std::vector<GeoPoint> out;
  ASSERT_TRUE(rp->transform(in, out).ok());
  for (std::size_t k = 0; k < places.size(); ++k) {
    double lon = places[k].first;
    if (lon < gt[0]) lon += 360;  // .gtx grids run 0…360
    const int col = static_cast<int>((lon - gt[0]) / gt[1]);
    const int row = static_cast<int>((places[k].second - gt[3]) / gt[5]);
    float n = 0;
    ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, col, row, 1, 1, &n, 1, 1, GDT_Float32,
                           0, 0),
              CE_None);
    EXPECT_NEAR(out[k].h, 100.0 + n, 1.0) << places[k].first << ", " << places[k].second;
  }
  GDALClose(ds);
  // Eugene, Oregon: EGM96 N ≈ -22.5 m.
  EXPECT_NEAR(out[0].h - 100.0, -22.47, 0.5);
}

TEST(Reprojector, VerticalCrsModeUsesProjsGeoidForEgm96Heights) {
  ReprojectOptions crs_mode;
  crs_mode.vertical_datum = "crs";
  auto rp = Reprojector::create(info_with("EPSG:4326+5773"), crs_mode);  // WGS 84 + EGM96 height
  ReprojectOptions egm;
  egm.vertical_datum = "egm96";
  auto ref = Reprojector::create(info_with("EPSG:4326"), egm);
  if (!ref.ok()) {
    // Without the grid, both must say so.
    ASSERT_FALSE(rp.ok());
    EXPECT_EQ(rp.error().code, ErrorCode::not_found);
    GTEST_SKIP() << "EGM96 grid not installed";
  }
  ASSERT_TRUE(rp.ok()) << rp.error().message;
  EXPECT_FALSE(rp->plan().geoid_grid.empty());
  std::vector<SourcePoint> in = {{-123.071, 44.0507, 100.0, 1, 0}, {6.1, 49.8, 300.0, 2, 0}};
  std::vector<GeoPoint> a, b;
  ASSERT_TRUE(rp->transform(in, a).ok());
  ASSERT_TRUE(ref->transform(in, b).ok());
  for (std::size_t i = 0; i < in.size(); ++i) {
    EXPECT_NEAR(a[i].lon, in[i].x, 1e-9);
    EXPECT_NEAR(a[i].lat, in[i].y, 1e-9);
    EXPECT_NEAR(a[i].h, b[i].h, 0.01);
  }
  EXPECT_NEAR(a[0].h - 100.0, -22.47, 0.5);
}

TEST(Reprojector, VerticalCrsModeNamesMissingGeoidGrids) {
  ReprojectOptions o;
  o.vertical_datum = "crs";
  SourceInfo info = info_with("EPSG:26910+5703", "/data/oregon.las");  // NAD83 UTM 10N + NAVD88
  info.bounds = sources::SourceBounds{493000, 4877000, 0, 494000, 4878000, 0};
  auto rp = Reprojector::create(info, o);
  if (rp.ok()) GTEST_SKIP() << "NAVD88 geoid grid installed here: " << rp->plan().geoid_grid;
  EXPECT_EQ(rp.error().code, ErrorCode::not_found) << rp.error().message;
  EXPECT_NE(rp.error().message.find("/data/oregon.las"), std::string::npos);
  EXPECT_NE(rp.error().message.find("projsync --file"), std::string::npos) << rp.error().message;
  EXPECT_NE(rp.error().message.find("NAVD88"), std::string::npos) << rp.error().message;
}

TEST(Reprojector, VerticalCrsModeRejectsADatumCodeStoredAsVerticalCrs) {
  const auto path = kReprojectorData / "nm_4_6_crop.las";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "missing " << path;
  auto src = sources::open_source(path);
  ASSERT_TRUE(src.ok());
  ReprojectOptions o;
  o.vertical_datum = "crs";
  auto rp = Reprojector::create((*src)->info(), o);
  ASSERT_FALSE(rp.ok());
  EXPECT_NE(rp.error().message.find("EPSG:5103"), std::string::npos) << rp.error().message;
  EXPECT_NE(rp.error().message.find("--crs"), std::string::npos);
}

TEST(Reprojector, VerticalCrsModeRefusesAZUnitAndNeedsAVerticalCrs) {
  ReprojectOptions o;
  o.vertical_datum = "crs";
  o.z_unit = sources::LinearUnit{"foot", 0.3048};
  auto a = Reprojector::create(info_with("EPSG:4326+5773"), o);
  ASSERT_FALSE(a.ok());
  EXPECT_EQ(a.error().code, ErrorCode::invalid_argument);
  o.z_unit.reset();
  auto b = Reprojector::create(info_with("EPSG:32633"), o);
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.error().code, ErrorCode::invalid_argument);
  EXPECT_NE(b.error().message.find("compound"), std::string::npos);
  auto c = Reprojector::create(info_with("EPSG:4979"), o);  // 3D geographic: already ellipsoidal
  ASSERT_TRUE(c.ok()) << c.error().message;
  std::vector<SourcePoint> in = {{10, 20, 123.25, 1, 0}};
  std::vector<GeoPoint> out;
  ASSERT_TRUE(c->transform(in, out).ok());
  EXPECT_NEAR(out[0].lon, 10, 1e-12);
  EXPECT_NEAR(out[0].lat, 20, 1e-12);
  EXPECT_NEAR(out[0].h, 123.25, 1e-9);
}

TEST(Reprojector, ProjectedCoordinatesLabelledGeographicAreAClearError) {
  // lone_star_tls.laz's GeoKeys say EPSG:4326 for UTM metres (SOURCES.md); same numbers here.
  auto rp = Reprojector::create(info_with("EPSG:4326", "/data/lone_star.las"), {});
  ASSERT_TRUE(rp.ok());
  std::vector<SourcePoint> in = {{10.0, 20.0, 1, 1, 0}, {515368.602, 4918340.364, 2330, 2, 0}};
  std::vector<GeoPoint> out;
  auto st = rp->transform(in, out);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("/data/lone_star.las: record 2"), std::string::npos)
      << st.error().message;
  EXPECT_NE(st.error().message.find("wrong CRS"), std::string::npos);
  // Read as UTM 12N they fall on Lone Star Geyser, Yellowstone (-110.807, 44.418).
  auto utm = Reprojector::create(info_with("EPSG:32612"), {});
  ASSERT_TRUE(utm.ok());
  ASSERT_TRUE(utm->transform(std::span(in).subspan(1), out).ok());
  EXPECT_NEAR(out[0].lon, -110.807, 0.001);
  EXPECT_NEAR(out[0].lat, 44.418, 0.001);
}

TEST(Reprojector, PointOutsideTheProjectionDomainNamesTheRecord) {
  auto rp = Reprojector::create(info_with("EPSG:32633", "/data/far.xyz"), {});
  ASSERT_TRUE(rp.ok());
  std::vector<SourcePoint> in = {{500000, 4000000, 0, 7, 0}, {1e12, 1e12, 0, 8, 0}};
  std::vector<GeoPoint> out;
  auto st = rp->transform(in, out);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("/data/far.xyz: record 8"), std::string::npos)
      << st.error().message;
}

}  // namespace
}  // namespace tinstream::transform

namespace tinstream::transform {
namespace {

// #22: the vertical option went into a PROJ pipeline as text, so it could add steps or read a grid
// at any absolute path. Now only the closed list and bare grid file names pass.
TEST(Reprojector, VerticalDatumCannotInjectPipelineStepsOrAbsoluteGrids) {
  for (const std::string& hostile : {
           // egm96_15.gtx is in Debian's proj-data: before the fix this built a pipeline that
           // added 5 km to every height.
           std::string("egm96_15.gtx +multiplier=1 +step +proj=affine +zoff=5000 "
                       "+step +proj=noop +x=a.tif"),
           std::string("/usr/share/proj/egm96_15.gtx"),
           std::string("../proj/egm96_15.gtx"),
           std::string("@egm96_15.gtx"),
           std::string("egm96_15.gtx\n"),
           std::string("egm96 15.gtx"),
           std::string(200, 'a') + ".tif",
       }) {
    SCOPED_TRACE(hostile);
    EXPECT_FALSE(is_grid_file_name(hostile));
    ReprojectOptions o;
    o.vertical_datum = hostile;
    auto rp = Reprojector::create(info_with("EPSG:4326"), o);
    ASSERT_FALSE(rp.ok());
    EXPECT_EQ(rp.error().code, ErrorCode::invalid_argument) << rp.error().message;
    EXPECT_NE(rp.error().message.find("unknown vertical datum"), std::string::npos);
  }
  for (const char* fine :
       {"egm96_15.gtx", "us_nga_egm08_25.tif", "AUSGeoid2020_20180201.gtx", "nzgeoid2016.gtg"}) {
    EXPECT_TRUE(is_grid_file_name(fine)) << fine;
  }
}

TEST(Reprojector, ConfinedOptionsTakeOnlyAuthorityCodesAndNoFileNamingCrs) {
  EXPECT_TRUE(is_authority_code("EPSG:4326"));
  EXPECT_TRUE(is_authority_code("EPSG:2903+6360"));
  EXPECT_TRUE(is_authority_code("ESRI:102100"));
  for (const char* bad : {"EPSG:", "epsg:4326", "EPSG:43a", "EPSG:4326+", "+proj=longlat",
                          "EPSG:4326 +init=/etc/passwd", ":4326", "EPSG:+4326"}) {
    EXPECT_FALSE(is_authority_code(bad)) << bad;
  }
  ReprojectOptions o;
  o.confined = true;
  o.crs = "+proj=longlat +datum=WGS84 +nadgrids=/etc/passwd +type=crs";
  auto rp = Reprojector::create(info_with(""), o);
  ASSERT_FALSE(rp.ok());
  EXPECT_EQ(rp.error().code, ErrorCode::invalid_argument);
  EXPECT_NE(rp.error().message.find("authority code"), std::string::npos) << rp.error().message;
  o.crs = "EPSG:32632";
  EXPECT_TRUE(Reprojector::create(info_with(""), o).ok());
  // A file's own CRS that can name files (a LAS WKT VLR is the file writer's text) is refused
  // too; a plain WKT passes.
  o.crs.clear();
  for (const char* file_crs :
       {"+proj=longlat +datum=WGS84 +no_defs +type=crs",
        R"(GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],)"
        R"(PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],)"
        R"(EXTENSION["PROJ4_GRIDS","/etc/passwd"]])"}) {
    auto from_file = Reprojector::create(info_with(file_crs), o);
    ASSERT_FALSE(from_file.ok()) << file_crs;
    EXPECT_EQ(from_file.error().code, ErrorCode::unsupported);
  }
  auto plain = Reprojector::create(
      info_with(R"(GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],)"
                R"(PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]])"),
      o);
  EXPECT_TRUE(plain.ok()) << plain.error().message;
  // Unconfined (the CLI, the user's own machine): a PROJ string is the user's choice.
  ReprojectOptions local;
  local.crs = "+proj=longlat +datum=WGS84 +no_defs +type=crs";
  EXPECT_TRUE(Reprojector::create(info_with(""), local).ok());
}

}  // namespace
}  // namespace tinstream::transform
