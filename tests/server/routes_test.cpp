#include "tinstream/server/routes.hpp"

#include <gtest/gtest.h>

#include "tinstream/server/config.hpp"

namespace tinstream::server {
namespace {

// Copies, so that results of temporaries stay valid.
template <typename T>
std::optional<T> as(const RouteResult& r) {
  if (!std::holds_alternative<Route>(r)) return std::nullopt;
  if (const T* t = std::get_if<T>(&std::get<Route>(r))) return *t;
  return std::nullopt;
}

std::optional<RouteError> error_of(const RouteResult& r) {
  if (const auto e = std::get_if<RouteError>(&r)) return *e;
  return std::nullopt;
}

// The answer's status: the error's, or 200 for a parsed route. (Never `error_of(r)->status`:
// on a parsed route that reads an empty optional, which may happen to hold an earlier status.)
int status_of(const RouteResult& r) {
  if (const auto e = std::get_if<RouteError>(&r)) return e->status;
  return 200;
}

TEST(Routes, NativeTileByQuadkey) {
  const auto r = parse_route("GET", "/tiles/lux/0231");
  const auto t = as<NativeTileRoute>(r);
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->layer, "lux");
  EXPECT_EQ(t->id.quadkey(), "0231");
  EXPECT_EQ(route_name(std::get<Route>(r)), "tile");
}

TEST(Routes, MalformedQuadkeyGives400WithTheTileIdMessage) {
  const auto r = parse_route("GET", "/tiles/lux/0241");
  const auto e = error_of(r);
  ASSERT_TRUE(e.has_value());
  EXPECT_EQ(e->status, 400);
  EXPECT_EQ(e->message, geo::TileId::from_quadkey("0241").error().message);
}

TEST(Routes, TerrainTileConvertsTmsRows) {
  const auto t = as<TerrainRoute>(parse_route("GET", "/tiles/lux/12/2120/2695.terrain?v=3"));
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->id.z, 12u);
  EXPECT_EQ(t->id.x, 2120u);
  EXPECT_EQ(t->id.y, 4095u - 2695u);
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/2/4/0.terrain")),
            400);  // x out of range
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/2/1/-1.terrain")), 400);
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/2/1/x.terrain")), 400);
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/2/1/1.gif")), 404);  // .png: raster-DEM
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/99999999999/1/1.terrain")), 400);
}

TEST(Routes, LayerJsonAndMetadata) {
  EXPECT_TRUE(as<LayerJsonRoute>(parse_route("GET", "/tiles/lux/layer.json")).has_value());
  EXPECT_TRUE(as<LayersRoute>(parse_route("GET", "/layers")).has_value());
  const auto l = as<LayerRoute>(parse_route("HEAD", "/layers/my-layer_1.v2"));
  ASSERT_TRUE(l.has_value());
  EXPECT_EQ(l->layer, "my-layer_1.v2");
  EXPECT_TRUE(as<HealthRoute>(parse_route("GET", "/healthz")).has_value());
  EXPECT_TRUE(as<MetricsRoute>(parse_route("GET", "/metrics")).has_value());
}

TEST(Routes, TraversalInLayerNamesIsRejected) {
  for (const std::string& target :
       std::vector<std::string>{"/tiles/../0", "/tiles/%2e%2e/0", "/tiles/%2E%2E/layer.json",
                                "/layers/..", "/layers/.hidden", "/layers/a%2Fb", "/layers/a%5Cb",
                                "/tiles/..%2F..%2Fetc/0", "/admin/layers/%2e%2e", "/layers/a%00b",
                                "/layers/%zz", "/layers/" + std::string(65, 'a') + ""}) {
    const auto r = parse_route(target.substr(0, 7) == "/admin/" ? "DELETE" : "GET", target);
    const auto e = error_of(r);
    ASSERT_TRUE(e.has_value()) << target;
    EXPECT_EQ(e->status, 400) << target;
  }
  // A decoded "/" cannot split a segment into two.
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux%2F0/1")), 400);
  // ".." as a path segment is just an unknown path.
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/../../etc/passwd")), 404);
}

TEST(Routes, QuadkeyTraversalIsRejected) {
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/%2e%2e")), 400);
  EXPECT_EQ(status_of(parse_route("GET", "/tiles/lux/..%2f..%2fetc")), 400);
}

TEST(Routes, WrongMethodIs405WithAllow) {
  const auto e = error_of(parse_route("POST", "/tiles/lux/0"));
  ASSERT_TRUE(e.has_value());
  EXPECT_EQ(e->status, 405);
  EXPECT_NE(e->allow.find("GET"), std::string::npos);
  EXPECT_EQ(status_of(parse_route("GET", "/admin/ingest")), 405);
  EXPECT_EQ(status_of(parse_route("GET", "/admin/layers/lux")), 405);
  EXPECT_EQ(status_of(parse_route("DELETE", "/layers/lux")), 405);
}

TEST(Routes, UnknownPathsAndBadTargets) {
  EXPECT_EQ(status_of(parse_route("GET", "/nope")), 404);
  EXPECT_EQ(status_of(parse_route("GET", "/admin")), 404);
  EXPECT_EQ(status_of(parse_route("GET", "/tiles")), 404);
  EXPECT_EQ(status_of(parse_route("GET", "/maplibre/x")), 404);
  // "/" is the web viewer's page (family "web"), not an unknown path.
  const auto root = as<WebPageRoute>(parse_route("GET", "/"));
  ASSERT_TRUE(root.has_value());
  EXPECT_EQ(root->page, "index.html");
  EXPECT_EQ(status_of(parse_route("GET", "http://example.com/layers")), 400);
  EXPECT_EQ(status_of(parse_route("GET", "*")), 400);
  EXPECT_EQ(status_of(parse_route("GET", "")), 400);
}

TEST(Routes, AdminRoutes) {
  const auto i = as<IngestRoute>(parse_route("POST", "/admin/ingest?layer=lux&filename=a%20b.tif"));
  ASSERT_TRUE(i.has_value());
  EXPECT_EQ(i->query.at("layer"), "lux");
  EXPECT_EQ(i->query.at("filename"), "a b.tif");
  const auto j = as<JobRoute>(parse_route("GET", "/admin/jobs/12"));
  ASSERT_TRUE(j.has_value());
  EXPECT_EQ(j->id, "12");
  EXPECT_EQ(status_of(parse_route("GET", "/admin/jobs/..%2f1")), 400);
  EXPECT_TRUE(as<JobsRoute>(parse_route("GET", "/admin/jobs")).has_value());
  EXPECT_TRUE(as<DeleteLayerRoute>(parse_route("DELETE", "/admin/layers/lux")).has_value());
  EXPECT_TRUE(as<PreflightRoute>(parse_route("OPTIONS", "/tiles/lux/0")).has_value());
}

TEST(Routes, PercentDecoding) {
  EXPECT_EQ(*percent_decode("a%41%62"), "aAb");
  EXPECT_FALSE(percent_decode("a%4").has_value());
  EXPECT_FALSE(percent_decode("a%").has_value());
  EXPECT_FALSE(percent_decode("%g0").has_value());
  EXPECT_FALSE(percent_decode("%00").has_value());
  EXPECT_EQ(*percent_decode("a+b", true), "a b");
  EXPECT_EQ(*percent_decode("a+b", false), "a+b");
  EXPECT_EQ(*percent_decode("plain_segment-1.terrain", true), "plain_segment-1.terrain");
  EXPECT_FALSE(percent_decode(std::string_view("a\0b", 3)).has_value());  // a raw NUL too
}

TEST(Config, ParsesKeysAndRejectsUnknownOnes) {
  auto c = config_from_json(R"({
    // comments are allowed
    "address": "127.0.0.1", "port": 9000, "store": "x.db", "threads": 3,
    "admin_token_env": "MY_TOKEN", "data_root": "/srv/data", "upload_dir": "/tmp/up",
    "max_upload_bytes": 1000, "max_header_bytes": 4096, "max_body_bytes": 2000,
    "max_connections": 10, "read_timeout_ms": 100, "write_timeout_ms": 200,
    "cache_max_age_s": 60, "cors_allow_origin": "", "terrain_cache_bytes": 0,
    "max_queued_jobs": 2, "shutdown_grace_ms": 500, "log_level": "warn", "access_log": false,
    "sendfile": false, "sendfile_min_bytes": 0})");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->port, 9000);
  EXPECT_EQ(c->threads, 3u);
  EXPECT_EQ(c->store, "x.db");
  EXPECT_EQ(c->max_header_bytes, 4096u);
  EXPECT_FALSE(c->access_log);
  EXPECT_FALSE(c->sendfile);
  EXPECT_EQ(c->sendfile_min_bytes, 0u);
  EXPECT_EQ(c->cors_allow_origin, "");

  auto bad = config_from_json(R"({"prot": 1})");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("prot"), std::string::npos);
  EXPECT_FALSE(config_from_json(R"({"port": 70000})").ok());
  EXPECT_FALSE(config_from_json(R"({"port": "80"})").ok());
  EXPECT_FALSE(config_from_json(R"({"log_level": "loud"})").ok());
  EXPECT_FALSE(config_from_json(R"({"sendfile": 1})").ok());
  EXPECT_FALSE(config_from_json("[1,2]").ok());
  EXPECT_FALSE(config_from_json("{").ok());
}

TEST(Config, ShippedConfigFileParses) {
  auto c = load_config(std::filesystem::path(TINSTREAM_SOURCE_DIR) / "config" / "server.json");
  ASSERT_TRUE(c.ok()) << c.error().message;
}

TEST(Config, TokenFromEnvironment) {
  ServerConfig c;
  c.admin_token_env = "TINSTREAM_TEST_TOKEN_XYZ";
  ::setenv("TINSTREAM_TEST_TOKEN_XYZ", "s3cret", 1);
  EXPECT_EQ(resolve_admin_token(c), "s3cret");
  c.admin_token = "literal";
  EXPECT_EQ(resolve_admin_token(c), "literal");
  ::unsetenv("TINSTREAM_TEST_TOKEN_XYZ");
  c.admin_token.clear();
  EXPECT_EQ(resolve_admin_token(c), "");
}

}  // namespace
}  // namespace tinstream::server

namespace tinstream::server {
namespace {

// Found by server/fuzz/route_fuzzer: "/admin" alone read a second path segment that does not
// exist (heap overflow). Every short admin path must be a plain 404.
TEST(Routes, BareAdminPathIsNotFoundInsteadOfReadingPastTheSegments) {
  for (const char* method : {"GET", "POST", "DELETE"}) {
    for (const char* target : {"/admin", "/admin?lay=are&&iy;are&le!2", "/admin/"}) {
      const auto e = error_of(parse_route(method, target));
      ASSERT_TRUE(e.has_value()) << method << " " << target;
      EXPECT_EQ(e->status, 404) << method << " " << target;
    }
  }
}

}  // namespace
}  // namespace tinstream::server
