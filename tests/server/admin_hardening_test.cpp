// The request logic as an attacker reads it (issue #22, findings 3, 4, 6 and 7): no server path
// in any answer, ingest options validated before a job is queued, admin and metrics kept apart
// from the public routes (CORS, an address allow-list), the job list evicted oldest first, and
// terrain tiles for clients without gzip answered from the cache. Pure handler, real store.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "default_ingest_runner.hpp"
#include "test_support.hpp"
#include "tinstream/server/handler.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;
using testing::TempDir;

using testing::kTile;

void sql(const std::filesystem::path& store, const std::string& statement) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(store.c_str(), &db), SQLITE_OK);
  char* message = nullptr;
  EXPECT_EQ(sqlite3_exec(db, statement.c_str(), nullptr, nullptr, &message), SQLITE_OK)
      << (message ? message : "");
  sqlite3_free(message);
  sqlite3_close(db);
}

class AdminHardeningTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_path_ = dir_.path / "store.db";
    testing::write_test_layer(store_path_, "lux");
    data_root_ = dir_.path / "data";
    std::filesystem::create_directories(data_root_ / "sub");
    std::ofstream(data_root_ / "sub" / "points.xyz") << "6.1 49.6 300\n";
    open_store();
    ctx_.config.store = store_path_;
    ctx_.config.data_root = data_root_;
    ctx_.config.upload_dir = dir_.path / "uploads";
    ctx_.admin_token = "tok";
    ctx_.store = [this]() -> Result<store::TileStore*> { return store_.get(); };
    ctx_.metrics = &metrics_;
    ctx_.terrain_cache = &cache_;
    ctx_.jobs = &jobs_;
  }
  void TearDown() override { jobs_.shutdown(); }

  void open_store() {
    store_.reset();
    auto st = store::TileStore::open(store_path_, store::TileStore::Mode::read_only);
    ASSERT_TRUE(st.ok());
    store_ = std::make_unique<store::TileStore>(std::move(*st));
  }

  Response request(const std::string& method, const std::string& target,
                   const std::string& body = {}, bool token = false) {
    Request r;
    r.method = method;
    r.target = target;
    r.body = body;
    r.content_type = body.empty() ? "" : "application/json";
    if (token) r.authorization = "Bearer tok";
    r.remote = "127.0.0.1";
    Response res = handle(r, ctx_);
    if (res.deferred) res = res.deferred();
    return res;
  }

  Response ingest(const json& options) {
    return request(
        "POST", "/admin/ingest",
        json{{"layer", "x"}, {"sources", {"sub/points.xyz"}}, {"options", options}}.dump(), true);
  }

  TempDir dir_{"admin-hardening"};
  std::filesystem::path store_path_, data_root_;
  std::unique_ptr<store::TileStore> store_;
  Metrics metrics_;
  TerrainCache cache_{4 << 20};
  JobManager jobs_{[](const IngestJobSpec&, const ProgressSink&) { return Status{}; }, 1000};
  Context ctx_;
};

// Finding 3: the layer metadata anyone can read lists each input by its file name, never by the
// server path it was read from; and no error answer names the store file, the data root or the
// upload directory.
TEST_F(AdminHardeningTest, NoServerPathInPublicMetadataOrErrors) {
  const std::string root = std::filesystem::absolute(data_root_).string();
  sql(store_path_, "UPDATE layer_versions SET options = '{\"inputs\": [{\"path\": \"" + root +
                       "/sub/points.xyz\", \"crs\": \"\"}, {\"path\": \"" +
                       (dir_.path / "uploads" / "upload-0123456789abcdef-pts.xyz").string() +
                       "\"}], \"max_points\": 1000}'");
  open_store();
  std::vector<std::string> bodies;
  const Response layers = request("GET", "/layers");
  ASSERT_EQ(layers.status, 200);
  const json inputs = json::parse(layers.body)["layers"][0]["options"]["inputs"];
  ASSERT_EQ(inputs.size(), 2u);
  EXPECT_EQ(inputs[0]["path"], "points.xyz");
  EXPECT_EQ(inputs[1]["path"], "pts.xyz");
  bodies.push_back(layers.body);
  bodies.push_back(request("GET", "/layers/lux").body);
  for (const auto& [method, target] :
       std::vector<std::pair<std::string, std::string>>{{"GET", "/layers/nope"},
                                                        {"GET", "/tiles/nope/layer.json"},
                                                        {"GET", "/tiles/nope/0/0/0.terrain"},
                                                        {"GET", "/tiles/nope/" + kTile.quadkey()},
                                                        {"DELETE", "/admin/layers/nope"}}) {
    const Response r = request(method, target, {}, true);
    EXPECT_GE(r.status, 400) << target;
    bodies.push_back(r.body);
  }
  bodies.push_back(
      request("POST", "/admin/ingest", json{{"layer", "x"}, {"sources", {"nope.xyz"}}}.dump(), true)
          .body);
  for (const auto& body : bodies) {
    for (const std::string& secret : {store_path_.string(), dir_.path.string(), root}) {
      EXPECT_EQ(body.find(secret), std::string::npos) << secret << " in " << body;
    }
  }
}

// Finding 4: every ingest option is checked when the job is submitted (400 naming the option):
// negative numbers that would wrap, thread counts that build a context per thread, memory sizes
// that overflow when shifted, levels the wrong way round, unknown keys, PROJ strings.
TEST_F(AdminHardeningTest, IngestOptionsOutOfRangeAre400BeforeQueueing) {
  const std::vector<std::pair<json, std::string>> bad = {
      {{{"threads", -1}}, "threads"},
      {{{"threads", 100000}}, "threads"},
      {{{"threads", 2.5}}, "threads"},
      {{{"memory_mb", -5}}, "memory_mb"},
      {{{"memory_mb", 1ull << 44}}, "memory_mb"},
      {{{"memory_mb", 1}}, "memory_mb"},
      {{{"max_points", 70000}}, "max_points"},
      {{{"max_points", 2}}, "max_points"},
      {{{"max_level", 31}}, "max_level"},
      {{{"min_level", 20}, {"max_level", 10}}, "min_level"},
      {{{"epsilon", -1}}, "epsilon"},
      {{{"epsilon", "1"}}, "epsilon"},
      {{{"epsilon", 1e300}}, "epsilon"},
      {{{"pyramid", "yes"}}, "pyramid"},
      {{{"projection", "bogus"}}, "projection"},
      {{{"vertical", "+proj=vgridshift +grids=/etc/passwd"}}, "vertical"},
      {{{"vertical", "../../geoid.tif"}}, "vertical"},
      {{{"crs", "+proj=longlat +init=/etc/passwd"}}, "crs"},
      {{{"attribution", std::string(5000, 'a')}}, "attribution"},
      {{{"z_units", 3}}, "z_units"},
      {{{"unknown_key", 1}}, "unknown_key"},
  };
  for (const auto& [options, name] : bad) {
    const Response r = ingest(options);
    EXPECT_EQ(r.status, 400) << options.dump() << ": " << r.body;
    EXPECT_NE(r.body.find(name), std::string::npos) << options.dump() << ": " << r.body;
  }
  EXPECT_TRUE(jobs_.list().empty());
  const Response good = ingest({{"threads", 2},
                                {"memory_mb", 64},
                                {"max_points", 300},
                                {"min_level", 3},
                                {"max_level", 20},
                                {"epsilon", 0.5},
                                {"pyramid", true},
                                {"projection", "ellipsoidal"},
                                {"vertical", "egm96"},
                                {"crs", "EPSG:2169"},
                                {"z_units", "metre"}});
  EXPECT_EQ(good.status, 202) << good.body;
}

// Finding 7: a browser on another origin may read tiles (CORS), never drive the admin API: the
// preflight of a public route offers GET/HEAD only, that of an admin route no CORS at all, and
// admin answers carry no Access-Control-Allow-Origin.
TEST_F(AdminHardeningTest, CorsNeverOpensTheAdminApi) {
  const Response tiles = request("OPTIONS", "/tiles/lux/layer.json");
  EXPECT_EQ(tiles.status, 204);
  ASSERT_NE(tiles.header("Access-Control-Allow-Methods"), nullptr);
  EXPECT_EQ(*tiles.header("Access-Control-Allow-Methods"), "GET, HEAD, OPTIONS");
  ASSERT_NE(tiles.header("Access-Control-Allow-Origin"), nullptr);
  for (const std::string target : {"/admin/ingest", "/admin/jobs", "/admin/layers/lux"}) {
    const Response pre = request("OPTIONS", target);
    EXPECT_EQ(pre.header("Access-Control-Allow-Origin"), nullptr) << target;
    EXPECT_EQ(pre.header("Access-Control-Allow-Methods"), nullptr) << target;
  }
  const Response jobs = request("GET", "/admin/jobs", {}, true);
  EXPECT_EQ(jobs.status, 200);
  EXPECT_EQ(jobs.header("Access-Control-Allow-Origin"), nullptr);
}

// Finding 7: with an allow-list, admin routes and metrics answer 403 to other addresses (before
// the token is looked at); tiles are for everyone.
TEST_F(AdminHardeningTest, AdminAllowListKeepsOtherAddressesOut) {
  ctx_.config.admin_allow = {"10.0.0.0/8", "::1"};
  const auto from = [&](const std::string& address, const std::string& target) {
    Request r;
    r.method = "GET";
    r.target = target;
    r.authorization = "Bearer tok";
    r.remote = address;
    return handle(r, ctx_).status;
  };
  EXPECT_EQ(from("127.0.0.1", "/admin/jobs"), 403);
  EXPECT_EQ(from("127.0.0.1", "/metrics"), 403);
  EXPECT_EQ(from("10.1.2.3", "/admin/jobs"), 200);
  EXPECT_EQ(from("10.1.2.3", "/metrics"), 200);
  EXPECT_EQ(from("::1", "/admin/jobs"), 200);
  EXPECT_EQ(from("11.0.0.1", "/admin/jobs"), 403);
  EXPECT_EQ(from("127.0.0.1", "/tiles/lux/layer.json"), 200);
  EXPECT_EQ(from("127.0.0.1", "/healthz"), 200);
}

// Finding 7: the job list keeps the newest 1000 jobs. Ids are numbers: job 2 is older than job
// 10 (the list was keyed by text, so "10" went before "2").
TEST_F(AdminHardeningTest, JobListEvictsTheOldestJobsByNumber) {
  for (int i = 1; i <= 1002; ++i) {
    auto id = jobs_.submit(IngestJobSpec{});
    ASSERT_TRUE(id.ok());
    for (int wait = 0; wait < 10000; ++wait) {
      const auto st = jobs_.get(*id);
      if (st && st->state != JobState::queued && st->state != JobState::running) break;
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
  }
  EXPECT_FALSE(jobs_.get("1").has_value());
  EXPECT_FALSE(jobs_.get("2").has_value());
  for (const std::string id : {"3", "10", "100", "1000", "1002"})
    EXPECT_TRUE(jobs_.get(id).has_value()) << id;
  const auto list = jobs_.list();
  ASSERT_EQ(list.size(), 1000u);
  EXPECT_EQ(list.front().id, "3");  // oldest first
  EXPECT_EQ(list.back().id, "1002");
}

// Finding 6: a terrain tile for a client without gzip is inflated once and cached as its own
// representation (shared bytes, a prebuilt head), not inflated again on every request.
TEST_F(AdminHardeningTest, IdentityTerrainIsCachedLikeGzip) {
  const std::string target = "/tiles/lux/12/2121/" + std::to_string(kTile.tms_row()) + ".terrain";
  Request gz;
  gz.method = "GET";
  gz.target = target;
  gz.accept_encoding = "gzip";
  ASSERT_EQ(handle(gz, ctx_).status, 200);
  const auto with_gzip = cache_.bytes();
  Request id = gz;
  id.accept_encoding.clear();
  const Response first = handle(id, ctx_);
  ASSERT_EQ(first.status, 200);
  EXPECT_GT(cache_.bytes(), with_gzip);  // the inflated body joined the cache
  const Response second = handle(id, ctx_);
  ASSERT_EQ(second.status, 200);
  EXPECT_NE(second.shared_body, nullptr);
  EXPECT_NE(second.prebuilt, nullptr);
  EXPECT_EQ(second.payload(), first.payload());
  EXPECT_EQ(*second.header("ETag"), *first.header("ETag"));
  EXPECT_EQ(second.header("Content-Encoding"), nullptr);
}

// Finding 7: the admin token is compared in constant time, whatever its length: every token but
// the right one is refused, those that share its prefix or extend it included.
TEST_F(AdminHardeningTest, OnlyTheExactTokenIsAccepted) {
  ctx_.admin_token = "s3cret-token-0123456789";
  const std::string& want = ctx_.admin_token;
  std::vector<std::string> wrong = {"",
                                    "s",
                                    want.substr(0, want.size() - 1),
                                    want + "x",
                                    want + std::string(500, 'x'),
                                    std::string(want.size(), 'a')};
  for (std::size_t i = 0; i < want.size(); ++i) {
    std::string near = want;
    near[i] ^= 1;
    wrong.push_back(near);
  }
  for (const auto& token : wrong) {
    Request r;
    r.method = "GET";
    r.target = "/admin/jobs";
    r.authorization = "Bearer " + token;
    const int status = handle(r, ctx_).status;
    EXPECT_TRUE(status == 401 || status == 403) << token << ": " << status;
  }
  Request ok;
  ok.method = "GET";
  ok.target = "/admin/jobs";
  ok.authorization = "Bearer " + want;
  EXPECT_EQ(handle(ok, ctx_).status, 200);
}

#ifdef TINSTREAM_SERVER_WITH_INGEST
// The job's `threads` bounds the ingest's pool and the LAZ chunk decoding of every source, as
// `tinstream ingest --threads` does; absent, both are 0 (one per core).
TEST(DefaultIngestRunner, ThreadsAlsoBoundLazDecoding) {
  IngestJobSpec job;
  job.layer = "lux";
  job.sources = {"/data/a.laz", "/data/b.laz"};
  job.root = "/data";
  job.options = json{{"threads", 3}};
  auto options = ingest_options_for(job);
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->threads, 3u);
  ASSERT_EQ(options->inputs.size(), 2u);
  for (const auto& in : options->inputs) EXPECT_EQ(in.source.decode_threads, 3u);

  job.options = json::object();
  options = ingest_options_for(job);
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->threads, 0u);
  for (const auto& in : options->inputs) EXPECT_EQ(in.source.decode_threads, 0u);
}

// Every source of an admin job is confined to the job's root (finding 2): GDAL's policy has the
// root, and a VRT is refused when the job says so (uploads: a VRT's sources were not uploaded).
TEST(DefaultIngestRunner, SourcesAreConfinedToTheJobsRoot) {
  IngestJobSpec job;
  job.layer = "lux";
  job.sources = {"/up/upload-0123456789abcdef-a.tif"};
  job.root = "/up";
  job.allow_vrt = false;
  auto options = ingest_options_for(job);
  ASSERT_TRUE(options.ok()) << options.error().message;
  ASSERT_EQ(options->inputs.size(), 1u);
  const auto& raster = options->inputs[0].source.raster;
  EXPECT_EQ(raster.root, std::filesystem::path("/up"));
  EXPECT_EQ(std::count(raster.drivers.begin(), raster.drivers.end(), "VRT"), 0);
  EXPECT_EQ(std::count(raster.drivers.begin(), raster.drivers.end(), "GTiff"), 1);
  EXPECT_TRUE(options->inputs[0].reproject.confined);
  job.allow_vrt = true;
  options = ingest_options_for(job);
  ASSERT_TRUE(options.ok()) << options.error().message;
  const auto& drivers = options->inputs[0].source.raster.drivers;
  EXPECT_EQ(std::count(drivers.begin(), drivers.end(), "VRT"), 1);
}
#endif

}  // namespace
}  // namespace tinstream::server
