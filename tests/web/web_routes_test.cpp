// The routes of the imagery and web families, through the request handler against a real store
// (no sockets): raster-DEM tiles against the TIN, imagery tiles, the metadata in /layers, the
// independence of terrain and imagery, the viewer pages and their static files.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "grid_tile.hpp"
#include "test_rasters.hpp"
#include "test_support.hpp"
#include "tinstream/imagery/image.hpp"
#include "tinstream/imagery/ingest_imagery.hpp"
#include "tinstream/kernel/predicates.hpp"
#include "tinstream/server/handler.hpp"
#include "tinstream/server/routes.hpp"
#include "tinstream/terrain/raster_dem.hpp"

namespace tinstream::server {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The web root of these tests, set before any request reads it (the server looks it up once).
const fs::path kWebRoot = fs::path(TINSTREAM_BINARY_DIR) / "tests" / "web" / "routes-test-root";
[[maybe_unused]] const bool kWebRootSet = [] {
  ::setenv("TINSTREAM_WEB_ROOT", kWebRoot.c_str(), 1);
  return true;
}();

const geo::TileId kTile = *geo::TileId::from_zxy(12, 2121, 1401);

// An orthophoto in EPSG:3857 covering exactly tile kTile with 256 × 256 pixels (native level 12).
fs::path write_ortho(const fs::path& dir, const std::string& name) {
  const geo::MercatorRect r = kTile.bounds();
  const double scale = 20037508.342789244;
  return imagery::testing::write_marker_orthophoto(
             dir / name, 3857, r.min_x * scale, r.max_y * scale, r.width() * scale / 256, 256, 256)
      .path;
}

void ingest_ortho(const fs::path& store, const fs::path& source, imagery::ImageFormat format) {
  imagery::ImageryIngestOptions o;
  o.store_path = store;
  o.layer = "lux";
  o.sources = {source};
  o.format = format;
  o.min_level = 10;
  o.threads = 2;
  auto r = imagery::ingest_imagery(o);
  if (!r) throw std::runtime_error(r.error().message);
}

class WebRoutesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_path_ = dir_.path / "store.db";
    testing::write_test_layer(store_path_, "lux");
    testing::write_test_layer(store_path_, "ell", geo::Projection::ellipsoidal, 5);
    ingest_ortho(store_path_, write_ortho(dir_.path, "ortho.tif"), imagery::ImageFormat::png);
    auto st = store::TileStore::open(store_path_, store::TileStore::Mode::read_only);
    ASSERT_TRUE(st.ok());
    store_ = std::make_unique<store::TileStore>(std::move(*st));
    ctx_.config.store = store_path_;
    ctx_.store = [this]() -> Result<store::TileStore*> { return store_.get(); };
    ctx_.metrics = &metrics_;
    ctx_.terrain_cache = cache_.get();
  }

  Response get(const std::string& target, const std::string& accept_encoding = "",
               const std::string& if_none_match = "") {
    Request r;
    r.method = "GET";
    r.target = target;
    r.accept_encoding = accept_encoding;
    r.if_none_match = if_none_match;
    return handle(r, ctx_);
  }

  testing::TempDir dir_{"web-routes"};
  fs::path store_path_;
  std::unique_ptr<store::TileStore> store_;
  Metrics metrics_;
  std::unique_ptr<TerrainCache> cache_ = std::make_unique<TerrainCache>(8 << 20);
  Context ctx_;
};

// The TIN's height at a point by brute force over all triangles (exact containment).
std::optional<double> tin_height(const tile::TinTile& t, double px, double py) {
  const auto vs = t.vertices();
  for (const auto& tri : t.triangles) {
    const auto &a = vs[tri[0]], &b = vs[tri[1]], &c = vs[tri[2]];
    const kernel::XY pa{a.x, a.y}, pb{b.x, b.y}, pc{c.x, c.y}, p{px, py};
    if (kernel::orient2d(pa, pb, p) < 0 || kernel::orient2d(pb, pc, p) < 0 ||
        kernel::orient2d(pc, pa, p) < 0) {
      continue;
    }
    const long double det = (static_cast<long double>(b.x) - a.x) * (c.y - a.y) -
                            (static_cast<long double>(b.y) - a.y) * (c.x - a.x);
    const long double wb = ((static_cast<long double>(px) - a.x) * (c.y - a.y) -
                            (static_cast<long double>(py) - a.y) * (c.x - a.x)) /
                           det;
    const long double wc = ((static_cast<long double>(b.x) - a.x) * (py - a.y) -
                            (static_cast<long double>(b.y) - a.y) * (px - a.x)) /
                           det;
    return static_cast<double>((1 - wb - wc) * a.z + wb * b.z + wc * c.z);
  }
  return std::nullopt;
}

TEST_F(WebRoutesTest, RasterDemTilesDecodeToTheTinAtPixelCentres) {
  auto tin = store_->read_tile("lux", kTile);
  ASSERT_TRUE(tin.ok() && tin->has_value());
  const geo::MercatorRect r = kTile.bounds();
  for (const auto encoding : {terrain::DemEncoding::terrarium, terrain::DemEncoding::mapbox}) {
    const std::string name(terrain::to_string(encoding));
    const Response res = get("/tiles/lux/12/2121/1401.png?encoding=" + name);
    ASSERT_EQ(res.status, 200) << res.payload();
    EXPECT_EQ(*res.header("Content-Type"), "image/png");
    const std::string_view body = res.payload();
    auto image =
        imagery::decode(std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size()));
    ASSERT_TRUE(image.ok()) << image.error().message;
    ASSERT_EQ(image->width, 256u);
    const double step = terrain::dem_step(encoding);
    int checked = 0;
    for (std::uint32_t j = 0; j < 256; j += 3) {
      for (std::uint32_t i = 0; i < 256; i += 3) {
        const double px = r.min_x + (i + 0.5) * r.width() / 256;
        const double py = r.max_y - (j + 0.5) * r.height() / 256;
        const auto expected = tin_height(**tin, px, py);
        ASSERT_TRUE(expected.has_value());
        const std::uint8_t* p = image->at(i, j);
        ASSERT_EQ(p[3], 255);
        const double h = terrain::decode_dem_height(encoding, p[0], p[1], p[2]);
        ASSERT_NEAR(h, *expected, step / 2 + 1e-6) << name << " pixel " << i << "," << j;
        ++checked;
      }
    }
    EXPECT_EQ(checked, 86 * 86);
  }
}

TEST_F(WebRoutesTest, RasterDemTilesRevalidateCacheAndRefuseWhatTheyCannotServe) {
  const Response first = get("/tiles/lux/12/2121/1401.png");  // terrarium by default
  ASSERT_EQ(first.status, 200);
  const std::string etag = *first.header("ETag");
  EXPECT_NE(etag.find("dem-terrarium-"), std::string::npos) << etag;
  const Response again = get("/tiles/lux/12/2121/1401.png?encoding=terrarium");
  EXPECT_EQ(again.payload(), first.payload());
  EXPECT_EQ(get("/tiles/lux/12/2121/1401.png", "", etag).status, 304);
  const Response mapbox = get("/tiles/lux/12/2121/1401.png?encoding=mapbox");
  EXPECT_NE(*mapbox.header("ETag"), etag);
  // NODATA transparent: a tile of its own (this one has no NODATA, so the same pixels).
  const Response transparent = get("/tiles/lux/12/2121/1401.png?nodata=transparent");
  ASSERT_EQ(transparent.status, 200);
  EXPECT_NE(*transparent.header("ETag"), etag);
  EXPECT_EQ(transparent.payload(), first.payload());
  EXPECT_EQ(get("/tiles/lux/12/2121/1401.png?nodata=transparent", "", etag).status, 200);
  EXPECT_EQ(get("/tiles/ell/12/2121/1401.png").status, 409);
  EXPECT_EQ(get("/tiles/lux/12/0/0.png").status, 404);
  EXPECT_EQ(get("/tiles/lux/13/4242/2802.png").status, 404);
  EXPECT_EQ(get("/tiles/nope/12/2121/1401.png").status, 404);
  EXPECT_EQ(get("/tiles/lux/12/2121/1401.png?encoding=mapzen").status, 400);
  EXPECT_EQ(get("/tiles/lux/12/2121/99999.png").status, 400);
}

// A spherical layer "gap" of the one tile kTile whose north-west corner is NODATA.
void write_nodata_layer(const fs::path& path) {
  auto st = store::TileStore::open(path, store::TileStore::Mode::read_write);
  if (!st) throw std::runtime_error("open store: " + st.error().message);
  tile::TinTile t = testing::make_grid_tile(kTile, 9, testing::synthetic_height);
  t.corner_nodata[0] = true;
  store::LayerInfo info;
  info.name = "gap";
  info.projection = geo::Projection::spherical;
  info.min_level = info.max_level = 12;
  info.max_points = 1000;
  info.mercator_bounds = kTile.bounds();
  info.bounds = kTile.lonlat_bounds(geo::NormalisedMercator(geo::Projection::spherical));
  info.level_max_error = std::vector<double>(13, 0.0);
  auto writer = st->begin_layer(info);
  if (!writer) throw std::runtime_error("begin_layer: " + writer.error().message);
  if (Status s = (*writer)->put(t); !s) throw std::runtime_error("put: " + s.error().message);
  info.tile_count = 1;
  info.point_count = 81;
  info.min_z = t.min_z;
  info.max_z = t.max_z;
  if (Status s = (*writer)->publish(info); !s) {
    throw std::runtime_error("publish: " + s.error().message);
  }
}

std::optional<imagery::RgbaImage> decode_png(const Response& res) {
  const std::string_view body = res.payload();
  auto image =
      imagery::decode(std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size()));
  if (!image) return std::nullopt;
  return std::move(*image);
}

// nodata=opaque (the default, what browsers need) and nodata=transparent are two tiles: different
// bytes (alpha 0 in the NODATA triangles or not, the same heights) and different ETags, so a
// cache or a client revalidating one never gets the other.
TEST_F(WebRoutesTest, RasterDemNodataOpaqueAndTransparentAreDifferentTiles) {
  write_nodata_layer(store_path_);
  const Response opaque = get("/tiles/gap/12/2121/1401.png");
  ASSERT_EQ(opaque.status, 200) << opaque.payload();
  const Response transparent = get("/tiles/gap/12/2121/1401.png?nodata=transparent");
  ASSERT_EQ(transparent.status, 200) << transparent.payload();
  EXPECT_EQ(get("/tiles/gap/12/2121/1401.png?nodata=opaque").payload(), opaque.payload());
  EXPECT_NE(opaque.payload(), transparent.payload());
  const std::string opaque_etag = *opaque.header("ETag");
  const std::string transparent_etag = *transparent.header("ETag");
  EXPECT_NE(opaque_etag, transparent_etag);
  EXPECT_EQ(get("/tiles/gap/12/2121/1401.png", "", opaque_etag).status, 304);
  EXPECT_EQ(get("/tiles/gap/12/2121/1401.png?nodata=transparent", "", transparent_etag).status,
            304);
  const Response crossed = get("/tiles/gap/12/2121/1401.png?nodata=transparent", "", opaque_etag);
  EXPECT_EQ(crossed.status, 200);
  EXPECT_EQ(crossed.payload(), transparent.payload());
  EXPECT_EQ(get("/tiles/gap/12/2121/1401.png", "", transparent_etag).status, 200);

  const auto o = decode_png(opaque);
  const auto t = decode_png(transparent);
  ASSERT_TRUE(o && t);
  ASSERT_EQ(o->width, 256u);
  ASSERT_EQ(t->width, 256u);
  std::size_t clear = 0;
  for (std::uint32_t j = 0; j < 256; ++j) {
    for (std::uint32_t i = 0; i < 256; ++i) {
      const std::uint8_t* po = o->at(i, j);
      const std::uint8_t* pt = t->at(i, j);
      ASSERT_EQ(po[3], 255) << i << "," << j;
      ASSERT_TRUE(pt[3] == 0 || pt[3] == 255) << i << "," << j;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(po[c], pt[c]) << i << "," << j;
      clear += pt[3] == 0 ? 1 : 0;
    }
  }
  // Both triangles of the north-west cell of the 8 × 8 grid have the NODATA corner: its 32 × 32
  // pixels (no pixel centre on a cell border) are clear, no other is.
  EXPECT_EQ(clear, std::size_t{1024});  // 32 × 32
  EXPECT_EQ(t->at(0, 0)[3], 0);
  EXPECT_EQ(t->at(255, 255)[3], 255);

  for (const char* bad : {"?nodata=flagged", "?nodata=Opaque", "?nodata=%zz"}) {
    const Response r = get(std::string("/tiles/gap/12/2121/1401.png") + bad);
    EXPECT_EQ(r.status, 400) << bad;
    EXPECT_NE(r.body.find("nodata"), std::string::npos) << bad << ": " << r.body;
  }
}

TEST_F(WebRoutesTest, ImageryTilesByQuadkeyAndByXyzRows) {
  auto stored = store_->imagery_tile("lux", kTile);
  ASSERT_TRUE(stored.ok() && stored->has_value());
  const Response xyz = get("/imagery/lux/12/2121/1401.png");
  ASSERT_EQ(xyz.status, 200) << xyz.payload();
  EXPECT_EQ(*xyz.header("Content-Type"), "image/png");
  EXPECT_EQ(*xyz.header("ETag"), (**stored).etag);
  EXPECT_EQ(xyz.payload(), std::string((**stored).data.begin(), (**stored).data.end()));
  const Response by_quadkey = get("/imagery/lux/" + kTile.quadkey());
  EXPECT_EQ(by_quadkey.status, 200);
  EXPECT_EQ(by_quadkey.payload(), xyz.payload());
  EXPECT_EQ(get("/imagery/lux/12/2121/1401.png", "", (**stored).etag).status, 304);
  // Its pixels are the orthophoto's: a marker (red at 30 % across, 30 % down) where it was drawn.
  const std::string_view body = xyz.payload();
  auto image =
      imagery::decode(std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size()));
  ASSERT_TRUE(image.ok());
  const std::uint8_t* red = image->at(76, 76);
  EXPECT_GT(red[0], 200);
  EXPECT_LT(red[1], 60);
  const Response wrong = get("/imagery/lux/12/2121/1401.jpg");
  EXPECT_EQ(wrong.status, 404);
  EXPECT_NE(wrong.body.find("use /imagery/lux/{z}/{x}/{y}.png"), std::string::npos) << wrong.body;
  EXPECT_EQ(get("/imagery/lux/12/2121/1402.png").status, 404);  // outside the orthophoto
  EXPECT_EQ(get("/imagery/ell/12/2121/1401.png").status, 404);  // no imagery layer "ell"
  EXPECT_EQ(get("/imagery/lux/12/2121/1401.gif").status, 404);
  EXPECT_EQ(get("/imagery/lux/4444").status, 400);
}

TEST_F(WebRoutesTest, LayersCarryTheirImageryAndRasterDemTemplates) {
  const Response res = get("/layers");
  ASSERT_EQ(res.status, 200);
  const json doc = json::parse(res.body);
  ASSERT_EQ(doc["imagery"].size(), 1u);
  EXPECT_EQ(doc["imagery"][0]["name"], "lux");
  EXPECT_EQ(doc["imagery"][0]["format"], "png");
  EXPECT_EQ(doc["imagery"][0]["tiles"], "/imagery/lux/{z}/{x}/{y}.png");
  EXPECT_EQ(doc["imagery"][0]["max_level"], 12);
  EXPECT_EQ(doc["imagery"][0]["min_level"], 10);
  for (const json& layer : doc["layers"]) {
    if (layer["name"] == "lux") {
      EXPECT_EQ(layer["imagery"]["name"], "lux");
      EXPECT_EQ(layer["raster_dem"]["terrarium"], "/tiles/lux/{z}/{x}/{y}.png?encoding=terrarium");
    } else {
      EXPECT_TRUE(layer["imagery"].is_null());
      EXPECT_TRUE(layer["raster_dem"].is_null());  // ellipsoidal: not EPSG:3857 tiles
    }
  }
  const json one = json::parse(get("/layers/lux").body);
  EXPECT_EQ(one["imagery"]["tile_count"], doc["imagery"][0]["tile_count"]);
}

// Every terrain answer of layer "lux" (native tiles, quantized-mesh, layer.json, raster-DEM)
// keeps its ETag when the imagery of the same name is replaced, while the imagery's change.
TEST_F(WebRoutesTest, ReplacingTheImageryLeavesTerrainEtagsUnchanged) {
  const auto terrain_etags = [&] {
    std::map<std::string, std::string> tags;
    std::vector<std::string> targets = {"/tiles/lux/layer.json"};
    for (const auto& id : testing::test_tile_ids()) {
      targets.push_back("/tiles/lux/" + id.quadkey());
      targets.push_back("/tiles/lux/" + std::to_string(id.z) + "/" + std::to_string(id.x) + "/" +
                        std::to_string(id.tms_row()) + ".terrain");
      targets.push_back("/tiles/lux/" + id.to_string() + ".png?encoding=mapbox");
    }
    for (const auto& t : targets) {
      const Response r = get(t, "gzip");
      EXPECT_EQ(r.status, 200) << t;
      tags[t] = r.header("ETag") != nullptr ? *r.header("ETag") : "";
    }
    return tags;
  };
  const auto before = terrain_etags();
  const std::string imagery_before = *get("/imagery/lux/" + kTile.quadkey()).header("ETag");
  const auto version_before = json::parse(get("/layers/lux").body)["version"];

  ingest_ortho(store_path_, write_ortho(dir_.path, "ortho2.tif"), imagery::ImageFormat::webp);
  cache_ = std::make_unique<TerrainCache>(8 << 20);  // nothing answered from before
  ctx_.terrain_cache = cache_.get();

  EXPECT_EQ(terrain_etags(), before);
  EXPECT_EQ(json::parse(get("/layers/lux").body)["version"], version_before);
  const Response now = get("/imagery/lux/" + kTile.quadkey());
  ASSERT_EQ(now.status, 200);
  EXPECT_NE(*now.header("ETag"), imagery_before);
  EXPECT_EQ(*now.header("Content-Type"), "image/webp");
  EXPECT_EQ(get("/imagery/lux/12/2121/1401.webp").status, 200);
  EXPECT_EQ(get("/imagery/lux/12/2121/1401.png").status, 404);
}

class WebPagesTest : public WebRoutesTest {
 protected:
  void SetUp() override {
    WebRoutesTest::SetUp();
    fs::remove_all(kWebRoot);
    fs::create_directories(kWebRoot / "cesium");
    std::ofstream(kWebRoot / "index.html") << "<!doctype html><title>cesium page</title>";
    std::ofstream(kWebRoot / "maplibre.html") << "<!doctype html><title>maplibre page</title>";
    std::ofstream(kWebRoot / "cesium" / "Cesium.js") << "var Cesium = {};";
    std::ofstream(kWebRoot / "cesium" / "Cesium.js.gz") << "pretend gzip";
    std::ofstream(kWebRoot / ".secret") << "hidden";
  }
};

TEST_F(WebPagesTest, PagesAndStaticFilesComeFromTheWebRoot) {
  const Response index = get("/");
  ASSERT_EQ(index.status, 200) << index.body;
  EXPECT_EQ(*index.header("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(index.body.find("cesium page"), std::string::npos);
  EXPECT_NE(get("/maplibre").body.find("maplibre page"), std::string::npos);
  const Response plain = get("/web/cesium/Cesium.js");
  ASSERT_EQ(plain.status, 200);
  EXPECT_EQ(plain.body, "var Cesium = {};");
  EXPECT_EQ(*plain.header("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_EQ(plain.header("Content-Encoding"), nullptr);
  const Response zipped = get("/web/cesium/Cesium.js", "gzip, deflate");
  EXPECT_EQ(zipped.body, "pretend gzip");
  EXPECT_EQ(*zipped.header("Content-Encoding"), "gzip");
  EXPECT_NE(*zipped.header("ETag"), *plain.header("ETag"));
  EXPECT_EQ(get("/web/cesium/Cesium.js", "", *plain.header("ETag")).status, 304);
  EXPECT_EQ(*plain.header("Cache-Control"), "no-cache");
}

TEST_F(WebPagesTest, NothingOutsideTheWebRootOrHiddenIsServed) {
  for (const char* target : {"/web/.secret", "/web/cesium/../index.html", "/web/%2e%2e/etc/passwd",
                             "/web/cesium/%2F..%2Findex.html", "/web", "/web/", "/web/missing.js",
                             "/maplibre/x", "/index.html"}) {
    const Response r = get(target);
    EXPECT_TRUE(r.status == 404 || r.status == 400) << target << " → " << r.status;
    EXPECT_EQ(r.body.find("hidden"), std::string::npos) << target;
  }
  Request post;
  post.method = "POST";
  post.target = "/";
  EXPECT_EQ(handle(post, ctx_).status, 405);
}

TEST(WebRouteParsing, NewRoutesParseToTheirTypes) {
  auto dem = parse_route("GET", "/tiles/a/3/2/1.png?encoding=mapbox");
  ASSERT_TRUE(std::holds_alternative<Route>(dem));
  const auto& d = std::get<DemTileRoute>(std::get<Route>(dem));
  EXPECT_EQ(d.id, (geo::TileId{3, 2, 1}));  // XYZ rows, not TMS
  EXPECT_EQ(d.encoding, "mapbox");
  EXPECT_EQ(d.nodata, "opaque");  // the default: what browsers need
  auto transparent = parse_route("GET", "/tiles/a/3/2/1.png?nodata=transparent");
  ASSERT_TRUE(std::holds_alternative<Route>(transparent));
  EXPECT_EQ(std::get<DemTileRoute>(std::get<Route>(transparent)).nodata, "transparent");
  EXPECT_EQ(std::get<DemTileRoute>(std::get<Route>(transparent)).encoding, "terrarium");
  EXPECT_EQ(std::get<RouteError>(parse_route("GET", "/tiles/a/3/2/1.png?nodata=flagged")).status,
            400);
  auto im = parse_route("HEAD", "/imagery/a/3/2/1.jpg");
  ASSERT_TRUE(std::holds_alternative<Route>(im));
  EXPECT_EQ(std::get<ImageryTileRoute>(std::get<Route>(im)).extension, "jpg");
  auto qk = parse_route("GET", "/imagery/a/0231");
  ASSERT_TRUE(std::holds_alternative<Route>(qk));
  EXPECT_EQ(std::get<ImageryTileRoute>(std::get<Route>(qk)).id, *geo::TileId::from_quadkey("0231"));
  auto page = parse_route("GET", "/");
  ASSERT_TRUE(std::holds_alternative<Route>(page));
  EXPECT_EQ(std::get<WebPageRoute>(std::get<Route>(page)).page, "index.html");
  auto asset = parse_route("GET", "/web/cesium/Workers/a-b_c.js?v=1");
  ASSERT_TRUE(std::holds_alternative<Route>(asset));
  EXPECT_EQ(std::get<WebAssetRoute>(std::get<Route>(asset)).path, "cesium/Workers/a-b_c.js");
  // Still a terrain tile, and the errors of the new forms.
  EXPECT_TRUE(std::holds_alternative<TerrainRoute>(
      std::get<Route>(parse_route("GET", "/tiles/a/3/2/1.terrain"))));
  EXPECT_EQ(std::get<RouteError>(parse_route("GET", "/tiles/a/3/9/1.png")).status, 400);
  EXPECT_EQ(std::get<RouteError>(parse_route("GET", "/tiles/a/x/2/1.png")).status, 400);
  EXPECT_EQ(std::get<RouteError>(parse_route("DELETE", "/imagery/a/1/0/0.png")).status, 405);
  EXPECT_EQ(std::get<RouteError>(parse_route("GET", "/imagery/a/1/0/0.tif")).status, 404);
  EXPECT_EQ(std::get<RouteError>(parse_route("GET", "/imagery/a%20b/1/0/0.png")).status, 400);
  EXPECT_EQ(std::get<RouteError>(parse_route("GET", "/web/a/.hidden")).status, 404);
}

}  // namespace
}  // namespace tinstream::server
