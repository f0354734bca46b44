// The pure request handler against a real SQLite store, without sockets.
#include "tinstream/server/handler.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "grid_tile.hpp"
#include "qm_decoder.hpp"
#include "test_support.hpp"
#include "tinstream/server/ingest_paths.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;
using testing::TempDir;

class HandlerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_path_ = dir_.path / "store.db";
    testing::write_test_layer(store_path_, "lux");
    testing::write_test_layer(store_path_, "ell", geo::Projection::ellipsoidal, 5);
    auto st = store::TileStore::open(store_path_, store::TileStore::Mode::read_only);
    ASSERT_TRUE(st.ok());
    store_ = std::make_unique<store::TileStore>(std::move(*st));
    ctx_.config.store = store_path_;
    ctx_.admin_token = "tok";
    ctx_.store = [this]() -> Result<store::TileStore*> { return store_.get(); };
    ctx_.metrics = &metrics_;
    ctx_.terrain_cache = &cache_;
  }

  Response get(const std::string& target, const std::string& accept_encoding = "",
               const std::string& if_none_match = "", const std::string& accept = "") {
    Request r;
    r.method = "GET";
    r.target = target;
    r.accept_encoding = accept_encoding;
    r.if_none_match = if_none_match;
    r.accept = accept;
    return handle(r, ctx_);
  }

  TempDir dir_{"handler"};
  std::filesystem::path store_path_;
  std::unique_ptr<store::TileStore> store_;
  Metrics metrics_;
  TerrainCache cache_{1 << 20};
  Context ctx_;
};

using testing::kTile;

TEST_F(HandlerTest, NativeTileIsTheStoredBlobWithDeflate) {
  const Response r = get("/tiles/lux/" + kTile.quadkey(), "gzip, deflate");
  ASSERT_EQ(r.status, 200) << r.body;
  ASSERT_NE(r.header("Content-Encoding"), nullptr);
  EXPECT_EQ(*r.header("Content-Encoding"), "deflate");
  auto stored = store_->tile("lux", kTile);
  ASSERT_TRUE(stored.ok() && stored->has_value());
  EXPECT_EQ(testing::bytes_of(r.body), (**stored).compressed);
  EXPECT_EQ(*r.header("ETag"), (**stored).etag);
  EXPECT_EQ(*r.header("Cache-Control"), "public, max-age=86400");
  EXPECT_EQ(*r.header("Access-Control-Allow-Origin"), "*");
  auto decoded = tile::decode(testing::inflate_zlib(r.body));
  ASSERT_TRUE(decoded.ok());
  EXPECT_EQ(decoded->id, kTile);
}

TEST_F(HandlerTest, NativeTileGzipAndIdentityNegotiation) {
  const Response gz = get("/tiles/lux/" + kTile.quadkey(), "gzip");
  ASSERT_EQ(gz.status, 200);
  EXPECT_EQ(*gz.header("Content-Encoding"), "gzip");
  const auto raw = testing::gunzip(gz.body);
  const Response plain = get("/tiles/lux/" + kTile.quadkey(), "");
  ASSERT_EQ(plain.status, 200);
  EXPECT_EQ(plain.header("Content-Encoding"), nullptr);
  EXPECT_EQ(testing::bytes_of(plain.body), raw);
  const Response refused = get("/tiles/lux/" + kTile.quadkey(), "deflate;q=0, gzip;q=0");
  EXPECT_EQ(refused.header("Content-Encoding"), nullptr);
  EXPECT_TRUE(tile::decode(testing::bytes_of(plain.body)).ok());
}

TEST_F(HandlerTest, ETagGives304) {
  const Response first = get("/tiles/lux/" + kTile.quadkey(), "deflate");
  const std::string etag = *first.header("ETag");
  const Response again = get("/tiles/lux/" + kTile.quadkey(), "deflate", etag);
  EXPECT_EQ(again.status, 304);
  EXPECT_TRUE(again.body.empty());
  EXPECT_EQ(*again.header("ETag"), etag);
  EXPECT_EQ(get("/tiles/lux/" + kTile.quadkey(), "deflate", "\"other\", " + etag).status, 304);
  EXPECT_EQ(get("/tiles/lux/" + kTile.quadkey(), "deflate", "\"other\"").status, 200);
}

// The deflate, gzip and identity bodies of a tile are three representations: three strong tags,
// and a tag revalidates only its own encoding (a cache holding the gzip copy must not get a 304
// for a client that takes no gzip).
TEST_F(HandlerTest, EachContentEncodingHasItsOwnETag) {
  const std::string target = "/tiles/lux/" + kTile.quadkey();
  const Response deflate = get(target, "deflate");
  const Response gzip = get(target, "gzip");
  const Response identity = get(target, "");
  ASSERT_EQ(*gzip.header("Content-Encoding"), "gzip");
  ASSERT_EQ(identity.header("Content-Encoding"), nullptr);
  const std::string tags[3] = {*deflate.header("ETag"), *gzip.header("ETag"),
                               *identity.header("ETag")};
  EXPECT_NE(tags[0], tags[1]);
  EXPECT_NE(tags[0], tags[2]);
  EXPECT_NE(tags[1], tags[2]);
  const char* encodings[3] = {"deflate", "gzip", ""};
  for (int e = 0; e < 3; ++e) {
    for (int t = 0; t < 3; ++t) {
      EXPECT_EQ(get(target, encodings[e], tags[t]).status, e == t ? 304 : 200)
          << "Accept-Encoding '" << encodings[e] << "', If-None-Match " << tags[t];
    }
  }
}

TEST_F(HandlerTest, AbsentTilesAndLayersAre404) {
  const Response r = get("/tiles/lux/" + geo::TileId::from_zxy(12, 0, 0)->quadkey());
  EXPECT_EQ(r.status, 404);
  const json j = json::parse(r.body);
  EXPECT_EQ(j["status"], 404);
  EXPECT_TRUE(j["error"].is_string());
  EXPECT_EQ(get("/tiles/nope/" + kTile.quadkey()).status, 404);
  EXPECT_EQ(get("/layers/nope").status, 404);
  EXPECT_EQ(get("/tiles/nope/layer.json").status, 404);
}

TEST_F(HandlerTest, MalformedQuadkeyIs400WithMessage) {
  const Response r = get("/tiles/lux/01x");
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(json::parse(r.body)["error"], geo::TileId::from_quadkey("01x").error().message);
}

TEST_F(HandlerTest, LayersMetadata) {
  const Response all = get("/layers");
  ASSERT_EQ(all.status, 200);
  const json j = json::parse(all.body);
  ASSERT_EQ(j["layers"].size(), 2u);
  const Response one = get("/layers/lux");
  ASSERT_EQ(one.status, 200);
  const json l = json::parse(one.body);
  EXPECT_EQ(l["name"], "lux");
  EXPECT_EQ(l["projection"], "spherical");
  EXPECT_EQ(l["min_level"], 10);
  EXPECT_EQ(l["max_level"], 12);
  EXPECT_EQ(l["tile_count"], testing::test_tile_ids().size());
  EXPECT_EQ(l["attribution"], "synthetic test surface");
  EXPECT_EQ(l["level_max_error"][10], 4.0);
  EXPECT_TRUE(l["bounds"]["west"].is_number());
  EXPECT_EQ(l["terrain"], "/tiles/lux/layer.json");
  EXPECT_TRUE(json::parse(get("/layers/ell").body)["terrain"].is_null());
}

TEST_F(HandlerTest, LayerJsonListsAvailability) {
  const Response r = get("/tiles/lux/layer.json", "gzip");
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(*r.header("Content-Encoding"), "gzip");
  const auto raw = testing::gunzip(std::string(r.payload()));
  const json j = json::parse(std::string(raw.begin(), raw.end()));
  EXPECT_EQ(j["format"], "quantized-mesh-1.0");
  EXPECT_EQ(j["scheme"], "tms");
  ASSERT_EQ(j["available"].size(), 13u);
  EXPECT_EQ(j["available"][12].size(), 1u);
  EXPECT_EQ(j["available"][12][0]["startX"], 2120);
  EXPECT_EQ(j["available"][12][0]["endX"], 2123);
  EXPECT_EQ(j["available"][12][0]["startY"], 4095 - 1403);
  EXPECT_EQ(j["available"][12][0]["endY"], 4095 - 1400);
  EXPECT_EQ(j["available"][0][0]["endX"], 0);
  // Without gzip in Accept-Encoding, plain JSON.
  const Response plain = get("/tiles/lux/layer.json");
  EXPECT_EQ(json::parse(plain.body)["name"], "lux");
  // The plain body is another representation: its own strong tag; the gzip tag does not match it.
  ASSERT_NE(plain.header("ETag"), nullptr);
  EXPECT_NE(*plain.header("ETag"), *r.header("ETag"));
  EXPECT_EQ(get("/tiles/lux/layer.json", "", *r.header("ETag")).status, 200);
  EXPECT_EQ(get("/tiles/lux/layer.json", "", *plain.header("ETag")).status, 304);
  EXPECT_EQ(get("/tiles/lux/layer.json", "gzip", *r.header("ETag")).status, 304);
}

// Two stores each holding a layer "lux" at version 1, with different tiles (a store rebuilt from
// scratch): their layer.json differ, so must their ETags — a revalidating client of the first
// gets the second's document, not a 304.
TEST_F(HandlerTest, LayerJsonETagFollowsTheDocumentNotTheVersion) {
  const auto other = dir_.path / "other.db";
  {
    auto st = store::TileStore::open(other, store::TileStore::Mode::read_write);
    ASSERT_TRUE(st.ok());
    store::LayerInfo info;
    info.name = "lux";
    info.min_level = 12;
    info.max_level = 12;
    info.max_points = 1000;
    info.mercator_bounds = kTile.bounds();
    info.bounds = kTile.lonlat_bounds(geo::NormalisedMercator());
    info.level_max_error = std::vector<double>(13, 0.0);
    auto writer = st->begin_layer(info);
    ASSERT_TRUE(writer.ok());
    const auto t = testing::make_grid_tile(kTile, 9, testing::synthetic_height);
    ASSERT_TRUE((*writer)->put(t).ok());
    info.tile_count = 1;
    info.min_z = t.min_z;
    info.max_z = t.max_z;
    ASSERT_TRUE((*writer)->publish(info).ok());
  }
  auto st = store::TileStore::open(other, store::TileStore::Mode::read_only);
  ASSERT_TRUE(st.ok());
  auto a = store_->layer("lux");
  auto b = st->layer("lux");
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->version, b->version);  // the case the old version-only tag got wrong

  const Response first = get("/tiles/lux/layer.json", "gzip");
  ASSERT_EQ(first.status, 200);
  const std::string tag = *first.header("ETag");
  EXPECT_EQ(get("/tiles/lux/layer.json", "gzip", tag).status, 304);

  Context other_ctx = ctx_;
  store::TileStore other_store = std::move(*st);
  other_ctx.store = [&]() -> Result<store::TileStore*> { return &other_store; };
  TerrainCache other_cache{1 << 20};
  other_ctx.terrain_cache = &other_cache;
  Request r;
  r.method = "GET";
  r.target = "/tiles/lux/layer.json";
  r.accept_encoding = "gzip";
  r.if_none_match = tag;
  const Response second = handle(r, other_ctx);
  ASSERT_EQ(second.status, 200) << "a 304 for another store's layer.json";
  EXPECT_NE(*second.header("ETag"), tag);
  const auto raw = testing::gunzip(std::string(second.payload()));
  EXPECT_EQ(json::parse(std::string(raw.begin(), raw.end()))["available"].size(), 13u);
}

TEST_F(HandlerTest, TerrainTileDecodesAndNormalsFollowAccept) {
  const std::string target = "/tiles/lux/12/2121/" + std::to_string(kTile.tms_row()) + ".terrain";
  const Response plain = get(target, "gzip");
  ASSERT_EQ(plain.status, 200) << plain.body;
  EXPECT_EQ(*plain.header("Content-Encoding"), "gzip");
  EXPECT_EQ(*plain.header("Content-Type"), "application/vnd.quantized-mesh");
  const auto mesh = testing::decode_quantized_mesh(testing::gunzip(std::string(plain.payload())));
  EXPECT_EQ(mesh.u.size(), 17u * 17u);
  EXPECT_FALSE(mesh.oct_normals.has_value());

  const Response lit = get(target, "gzip", "",
                           "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask,"
                           "application/octet-stream;q=0.9,*/*;q=0.01");
  ASSERT_EQ(lit.status, 200);
  const auto mesh_n = testing::decode_quantized_mesh(testing::gunzip(std::string(lit.payload())));
  EXPECT_TRUE(mesh_n.oct_normals.has_value());
  EXPECT_NE(*lit.header("ETag"), *plain.header("ETag"));
  EXPECT_EQ(get(target, "gzip", *plain.header("ETag")).status, 304);
  // Cached: the same bytes again.
  EXPECT_EQ(get(target, "gzip").payload(), plain.payload());
  EXPECT_GT(cache_.bytes(), 0u);
}

TEST_F(HandlerTest, TerrainAboveTheCoarsestLevelIsFlatAndBelowAbsentIs404) {
  const Response root = get("/tiles/lux/0/0/0.terrain", "gzip");
  ASSERT_EQ(root.status, 200) << root.body;
  const auto mesh = testing::decode_quantized_mesh(testing::gunzip(std::string(root.payload())));
  EXPECT_EQ(mesh.u.size(), 4u);
  // Every level-1 tile, the three away from Luxembourg's data included: CesiumJS cannot upsample
  // a 180° tile (terrain::kWholeLevels).
  for (const char* t : {"0/0", "0/1", "1/0", "1/1"}) {
    const Response r = get(std::string("/tiles/lux/1/") + t + ".terrain", "gzip");
    ASSERT_EQ(r.status, 200) << t << ": " << r.body;
    EXPECT_EQ(testing::decode_quantized_mesh(testing::gunzip(std::string(r.payload()))).u.size(),
              4u)
        << t;
  }
  EXPECT_EQ(get("/tiles/lux/2/0/0.terrain", "gzip").status, 404);  // level 2, away from the data
  EXPECT_EQ(get("/tiles/lux/12/0/0.terrain", "gzip").status, 404);
}

TEST_F(HandlerTest, EllipsoidalLayersRefuseTerrainWith409) {
  const Response r = get("/tiles/ell/12/2121/2694.terrain", "gzip");
  EXPECT_EQ(r.status, 409);
  EXPECT_NE(json::parse(r.body)["error"].get<std::string>().find("ellipsoidal"), std::string::npos);
  EXPECT_EQ(get("/tiles/ell/layer.json").status, 409);
  EXPECT_EQ(get("/tiles/ell/" + kTile.quadkey(), "deflate").status, 200);
}

TEST_F(HandlerTest, AdminNeedsTheToken) {
  Request r;
  r.method = "GET";
  r.target = "/admin/jobs";
  EXPECT_EQ(handle(r, ctx_).status, 401);
  EXPECT_NE(handle(r, ctx_).header("WWW-Authenticate"), nullptr);
  r.authorization = "Bearer wrong";
  EXPECT_EQ(handle(r, ctx_).status, 403);
  r.authorization = "Bearer to";
  EXPECT_EQ(handle(r, ctx_).status, 403);
  r.authorization = "Bearer tokk";
  EXPECT_EQ(handle(r, ctx_).status, 403);
  r.authorization = "Basic dG9r";
  EXPECT_EQ(handle(r, ctx_).status, 401);
  r.authorization = "Bearer tok";
  EXPECT_EQ(handle(r, ctx_).status, 200);
  ctx_.admin_token.clear();
  EXPECT_EQ(handle(r, ctx_).status, 403);  // admin disabled
}

TEST_F(HandlerTest, PreflightAndCors) {
  Request r;
  r.method = "OPTIONS";
  r.target = "/tiles/lux/0";
  const Response res = handle(r, ctx_);
  EXPECT_EQ(res.status, 204);
  EXPECT_EQ(*res.header("Access-Control-Allow-Origin"), "*");
  EXPECT_NE(res.header("Access-Control-Allow-Methods")->find("GET"), std::string::npos);
  ctx_.config.cors_allow_origin = "https://viewer.example";
  EXPECT_EQ(*get("/healthz").header("Access-Control-Allow-Origin"), "https://viewer.example");
  ctx_.config.cors_allow_origin.clear();
  EXPECT_EQ(get("/healthz").header("Access-Control-Allow-Origin"), nullptr);
}

TEST_F(HandlerTest, HealthAndMetrics) {
  const Response h = get("/healthz");
  EXPECT_EQ(h.status, 200);
  EXPECT_EQ(json::parse(h.body)["status"], "ok");
  metrics_.record("tile", 200, 123, 0.0004);
  const Response m = get("/metrics");
  EXPECT_EQ(m.status, 200);
  EXPECT_NE(m.body.find("tinstream_http_requests_total{route=\"tile\",status=\"200\"} 1"),
            std::string::npos);
  EXPECT_NE(m.body.find("tinstream_http_request_duration_seconds_bucket{le=\"0.0005\"} 1"),
            std::string::npos);
  EXPECT_NE(m.body.find("tinstream_http_response_bytes_total 123"), std::string::npos);
  EXPECT_NE(m.body.find("tinstream_ingest_jobs{state=\"running\"} 0"), std::string::npos);
}

TEST_F(HandlerTest, IngestValidatesTheBodyBeforeQueueing) {
  Request r;
  r.method = "POST";
  r.target = "/admin/ingest";
  r.content_type = "application/json";
  r.authorization = "Bearer tok";
  JobManager jobs([](const IngestJobSpec&, const ProgressSink&) { return Status{}; }, 4);
  ctx_.jobs = &jobs;
  ctx_.config.data_root = dir_.path;
  r.body = "not json";
  EXPECT_EQ(handle(r, ctx_).status, 400);
  r.body = R"({"layer": "../x", "sources": ["a"]})";
  EXPECT_EQ(handle(r, ctx_).status, 400);
  r.body = R"({"layer": "x", "sources": []})";
  EXPECT_EQ(handle(r, ctx_).status, 400);
  r.body = R"({"layer": "x", "sources": ["../store.db"]})";
  EXPECT_EQ(handle(r, ctx_).status, 400);
  r.body = R"({"layer": "x", "sources": ["/etc/passwd"]})";
  EXPECT_EQ(handle(r, ctx_).status, 403);
  r.body = R"({"layer": "x", "sources": ["missing.tif"]})";
  EXPECT_EQ(handle(r, ctx_).status, 404);
  r.body = R"({"layer": "x", "sources": ["store.db"]})";
  const Response ok = handle(r, ctx_);
  EXPECT_EQ(ok.status, 202) << ok.body;
  EXPECT_TRUE(json::parse(ok.body)["job"].is_string());
  ctx_.config.data_root.clear();
  EXPECT_EQ(handle(r, ctx_).status, 403);
  jobs.shutdown();
  ctx_.jobs = nullptr;
}

TEST(IngestPaths, CanonicalisesAndStaysInsideTheRoot) {
  TempDir dir("paths");
  const auto root = dir.path / "root";
  std::filesystem::create_directories(root / "sub");
  std::filesystem::create_directories(dir.path / "root-other");
  { std::ofstream(root / "sub" / "a.tif") << "x"; }
  { std::ofstream(dir.path / "outside.tif") << "x"; }
  { std::ofstream(dir.path / "root-other" / "b.tif") << "x"; }
  std::filesystem::create_symlink(dir.path / "outside.tif", root / "escape.tif");
  std::filesystem::create_directory_symlink(dir.path, root / "updir");
  std::filesystem::create_symlink(root / "sub" / "a.tif", root / "inside-link.tif");

  auto ok = resolve_source(root, "sub/a.tif");
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(*ok, std::filesystem::canonical(root / "sub" / "a.tif"));
  EXPECT_TRUE(resolve_source(root, (root / "sub" / "a.tif").string()).ok());
  EXPECT_TRUE(resolve_source(root, "inside-link.tif").ok());
  EXPECT_TRUE(resolve_source(root, "sub").ok());

  EXPECT_EQ(resolve_source(root, "../outside.tif").error().code, ErrorCode::invalid_argument);
  EXPECT_EQ(resolve_source(root, "sub/../../outside.tif").error().code,
            ErrorCode::invalid_argument);
  EXPECT_EQ(resolve_source(root, (dir.path / "outside.tif").string()).error().code,
            ErrorCode::unsupported);
  EXPECT_EQ(resolve_source(root, (dir.path / "root-other" / "b.tif").string()).error().code,
            ErrorCode::unsupported);
  EXPECT_EQ(resolve_source(root, "escape.tif").error().code, ErrorCode::unsupported);
  EXPECT_EQ(resolve_source(root, "updir/outside.tif").error().code, ErrorCode::unsupported);
  EXPECT_EQ(resolve_source(root, "/etc/passwd").error().code, ErrorCode::unsupported);
  EXPECT_EQ(resolve_source(root, "nope.tif").error().code, ErrorCode::not_found);
  EXPECT_FALSE(resolve_source(root, "").ok());
  EXPECT_FALSE(sanitize_filename("../x").ok());
  EXPECT_FALSE(sanitize_filename("a/b").ok());
  EXPECT_FALSE(sanitize_filename(".hidden").ok());
  EXPECT_EQ(*sanitize_filename("dem_1.tif"), "dem_1.tif");
}

}  // namespace
}  // namespace tinstream::server
