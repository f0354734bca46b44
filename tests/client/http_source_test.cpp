// The HTTP tile source against the real tinstream-server on 127.0.0.1 (tiles, 304, 404, idle
// keep-alive connections) and against a scripted peer for what a healthy server never does
// (5xx, silence, refused connections).
#include <gtest/gtest.h>

#include <cstring>
#include <thread>

#include "process.hpp"
#include "synthetic_store.hpp"
#include "tinstream/client/loader.hpp"
#include "tinstream/client/streamer.hpp"
#include "tinstream/client/tile_source.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::client {
namespace {

using testing::TempDir;

constexpr geo::TileId kTile{12, 2121, 1401};  // in the synthetic layer
constexpr geo::TileId kAbsent{12, 2200, 1401};

struct ServedStore {
  explicit ServedStore(const std::string& name, const std::string& config = "")
      : dir(name), store(dir.path / "s.db") {
    testing::write_layer(store, testing::default_layer());
    server = std::make_unique<testing::Server>(store, config);
  }
  TempDir dir;
  std::filesystem::path store;
  std::unique_ptr<testing::Server> server;
};

std::shared_ptr<TileSource> http(const std::string& url, HttpOptions options = {}) {
  auto s = open_http_source(url, options);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  return s.ok() ? *s : nullptr;
}

FetchResponse fetch(TileConnection& c, const LayerDescription& layer, const geo::TileId& id,
                    std::optional<std::string> etag = std::nullopt) {
  const std::atomic<bool> never{false};
  return c.fetch(FetchRequest{{TileKind::terrain, 0, id}, &layer, std::move(etag)}, never);
}

TEST(HttpSource, FetchesRevalidatesAndReportsAbsentTiles) {
  ServedStore served("http_fetch");
  auto source = http(served.server->url());
  auto layers = source->layers({});
  ASSERT_TRUE(layers.ok()) << layers.error().message;
  ASSERT_EQ(layers->size(), 1u);
  const LayerDescription& layer = layers->front();
  EXPECT_EQ(layer.name, "synth");
  EXPECT_EQ(layer.min_level, 10u);
  EXPECT_EQ(layer.max_level, 12u);
  auto named = source->layers({"synth"});
  ASSERT_TRUE(named.ok());
  EXPECT_EQ(named->front().version, layer.version);
  // The helper's server configuration is gone once the server serves: none piles up beside the
  // stores (they did, one per run).
  EXPECT_EQ(served.server->config().parent_path(), served.dir.path);
  for (const auto& entry : std::filesystem::directory_iterator(served.dir.path))
    EXPECT_NE(entry.path().filename().string().rfind("server-", 0), 0u) << entry.path();
  auto missing = source->layers({"nope"});
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::not_found);

  auto connection = source->connect();
  ASSERT_TRUE(connection.ok());
  const FetchResponse ok = fetch(**connection, layer, kTile);
  ASSERT_EQ(ok.status, FetchResponse::Status::ok) << ok.error.message;
  EXPECT_EQ(ok.encoding, ContentEncoding::deflate);  // the stored zlib bytes, as they are
  EXPECT_FALSE(ok.etag.empty());
  EXPECT_GT(ok.wire_bytes, ok.body.size());
  // The very bytes in the store.
  auto st = store::TileStore::open(served.store, store::TileStore::Mode::read_only);
  ASSERT_TRUE(st.ok());
  auto stored = st->tile("synth", kTile);
  ASSERT_TRUE(stored.ok() && stored->has_value());
  EXPECT_EQ(ok.body, (*stored)->compressed);
  EXPECT_EQ(ok.etag, (*stored)->etag);

  const FetchResponse same = fetch(**connection, layer, kTile, ok.etag);
  EXPECT_EQ(same.status, FetchResponse::Status::not_modified);
  EXPECT_TRUE(same.body.empty());
  const FetchResponse absent = fetch(**connection, layer, kAbsent);
  EXPECT_EQ(absent.status, FetchResponse::Status::not_found);
  // One connection served all three (keep-alive).
  EXPECT_EQ(ok.reconnects + same.reconnects + absent.reconnects, 1u);
}

// tinstream_http_open_connections from the server's /metrics (the probe's own connection
// included), or -1 when it cannot be read.
std::int64_t open_connections(std::uint16_t port) {
  const std::string body = testing::http_get(port, "/metrics");
  const std::string name = "\ntinstream_http_open_connections ";
  const auto at = body.find(name);
  if (at == std::string::npos) return -1;
  return std::strtoll(body.c_str() + at + name.size(), nullptr, 10);
}

TEST(HttpSource, ReopensAKeepAliveConnectionTheServerClosed) {
  ServedStore served("http_idle", R"("read_timeout_ms": 200)");
  auto source = http(served.server->url());
  auto layers = source->layers({});
  ASSERT_TRUE(layers.ok());
  auto connection = source->connect();
  ASSERT_TRUE(connection.ok());
  ASSERT_EQ(fetch(**connection, layers->front(), kTile).status, FetchResponse::Status::ok);
  // The server drops idle connections after 200 ms (its sweep runs every 25 ms): wait until its
  // metrics count no connection but the probe's own, however long a loaded machine takes.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  std::int64_t open = -1;
  while ((open = open_connections(served.server->port())) != 1 &&
         std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_EQ(open, 1) << "the server kept the idle connection open";
  const FetchResponse again = fetch(**connection, layers->front(), kTile);
  EXPECT_EQ(again.status, FetchResponse::Status::ok) << again.error.message;
  EXPECT_EQ(again.reconnects, 1u);
}

TEST(HttpSource, RetriesServerErrorsThenSucceeds) {
  const std::string tile_bytes = "not really a tile";
  testing::ScriptedPeer peer([&](int i, const std::string&) {
    return i < 2 ? testing::http_response(503, "{\"error\":\"busy\"}")
                 : testing::http_response(200, tile_bytes, {"ETag: \"t1\""});
  });
  HttpOptions options;
  options.backoff_ms = 20;
  auto source = http("http://127.0.0.1:" + std::to_string(peer.port()), options);
  auto connection = source->connect();
  ASSERT_TRUE(connection.ok());
  LayerDescription layer;
  layer.name = "synth";
  const auto start = std::chrono::steady_clock::now();
  const FetchResponse r = fetch(**connection, layer, kTile);
  EXPECT_EQ(r.status, FetchResponse::Status::ok) << r.error.message;
  EXPECT_EQ(r.attempts, 3u);
  EXPECT_EQ(std::string(r.body.begin(), r.body.end()), tile_bytes);
  EXPECT_EQ(r.etag, "\"t1\"");
  // Two backoffs: 20 ms and 40 ms, each at least 75 %.
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(45));
}

TEST(HttpSource, GivesUpAfterItsAttemptsNamingTheRequest) {
  testing::ScriptedPeer peer(
      [](int, const std::string&) { return testing::http_response(500, "no"); });
  HttpOptions options;
  options.backoff_ms = 5;
  options.max_attempts = 3;
  auto source = http("http://127.0.0.1:" + std::to_string(peer.port()), options);
  auto connection = source->connect();
  LayerDescription layer;
  layer.name = "synth";
  const FetchResponse r = fetch(**connection, layer, kTile);
  EXPECT_EQ(r.status, FetchResponse::Status::failed);
  EXPECT_EQ(r.attempts, 3u);
  EXPECT_EQ(peer.requests(), 3);
  EXPECT_NE(r.error.message.find("GET /tiles/synth/" + kTile.quadkey()), std::string::npos);
  EXPECT_NE(r.error.message.find("HTTP 500"), std::string::npos);
  // A 4xx other than 404 is not retried.
  testing::ScriptedPeer forbidden(
      [](int, const std::string&) { return testing::http_response(403, "no"); });
  auto source2 = http("http://127.0.0.1:" + std::to_string(forbidden.port()), options);
  const FetchResponse f = fetch(**source2->connect(), layer, kTile);
  EXPECT_EQ(f.status, FetchResponse::Status::failed);
  EXPECT_EQ(forbidden.requests(), 1);
}

TEST(HttpSource, TimesOutOnASilentServerAndCancelsPromptly) {
  testing::ScriptedPeer silent([](int, const std::string&) { return std::string(); });
  HttpOptions options;
  options.request_timeout_ms = 300;
  options.max_attempts = 2;
  options.backoff_ms = 10;
  auto source = http("http://127.0.0.1:" + std::to_string(silent.port()), options);
  LayerDescription layer;
  layer.name = "synth";
  const FetchResponse r = fetch(**source->connect(), layer, kTile);
  EXPECT_EQ(r.status, FetchResponse::Status::failed);
  EXPECT_NE(r.error.message.find("timed out"), std::string::npos) << r.error.message;
  EXPECT_EQ(r.attempts, 2u);

  options.request_timeout_ms = 60000;
  auto patient = http("http://127.0.0.1:" + std::to_string(silent.port()), options);
  auto connection = patient->connect();
  std::atomic<bool> cancel{false};
  std::thread canceller([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    cancel.store(true);
  });
  const auto start = std::chrono::steady_clock::now();
  const FetchResponse c =
      (*connection)
          ->fetch(FetchRequest{{TileKind::terrain, 0, kTile}, &layer, std::nullopt}, cancel);
  canceller.join();
  EXPECT_EQ(c.status, FetchResponse::Status::failed);
  EXPECT_EQ(c.error.code, ErrorCode::cancelled);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
}

TEST(HttpSource, RefusedConnectionsAndBadUrls) {
  HttpOptions options;
  options.backoff_ms = 5;
  options.max_attempts = 2;
  auto source = http("http://127.0.0.1:" + std::to_string(testing::closed_port()), options);
  LayerDescription layer;
  layer.name = "synth";
  const FetchResponse r = fetch(**source->connect(), layer, kTile);
  EXPECT_EQ(r.status, FetchResponse::Status::failed);
  EXPECT_NE(r.error.message.find("cannot connect"), std::string::npos) << r.error.message;
  EXPECT_FALSE(source->layers({}).ok());
  for (const char* bad :
       {"https://example.org", "http://", "http://host:99999", "ftp://x", "http://h:p"})
    EXPECT_FALSE(open_http_source(bad).ok()) << bad;
  EXPECT_TRUE(open_http_source("http://[::1]:8080/prefix/").ok());
}

// Loads every tile of the layer through a loader and returns the results.
std::vector<LoadResult> load_all(TileLoader& loader, const std::vector<geo::TileId>& ids) {
  std::vector<TileRequest> wanted;
  wanted.reserve(ids.size());
  for (const geo::TileId& id : ids) wanted.push_back({{TileKind::terrain, 0, id}, 1.0, 0.0});
  std::vector<LoadResult> results;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (results.size() < ids.size() && std::chrono::steady_clock::now() < until) {
    loader.submit(wanted);  // what is still missing, as the render thread would
    loader.wait_for_results(std::chrono::milliseconds(100));
    for (LoadResult& r : loader.take_results()) {
      std::erase_if(wanted, [&](const TileRequest& w) { return w.key == r.key; });
      results.push_back(std::move(r));
    }
  }
  return results;
}

TEST(Loader, ASecondRunWithAWarmDiskCacheDownloadsNothingNew) {
  ServedStore served("loader_disk");
  const std::vector<geo::TileId> ids = [] {
    std::vector<geo::TileId> all;
    for (std::uint32_t y = 1400; y < 1404; ++y)
      for (std::uint32_t x = 2120; x < 2124; ++x) all.push_back({12, x, y});
    return all;
  }();
  const auto disk_dir = served.dir.path / "disk";
  std::uint64_t first_bytes = 0;
  {
    auto source = http(served.server->url());
    auto disk = DiskCache::open(disk_dir, 64 << 20);
    ASSERT_TRUE(disk.ok());
    TileLoader loader(source, *source->layers({}), std::move(*disk), LoaderOptions{4});
    const auto results = load_all(loader, ids);
    ASSERT_EQ(results.size(), ids.size());
    for (const LoadResult& r : results) {
      EXPECT_EQ(r.status, LoadStatus::loaded) << r.error;
      EXPECT_EQ(r.origin, LoadOrigin::network);
    }
    const LoaderCounters c = loader.counters();
    EXPECT_EQ(c.ok, ids.size());
    EXPECT_EQ(c.failed, 0u);
    first_bytes = c.downloaded_bytes;
    EXPECT_GT(first_bytes, 0u);
  }
  // A restart: a new loader and a new index over the same directory.
  auto source = http(served.server->url());
  auto disk = DiskCache::open(disk_dir, 64 << 20);
  ASSERT_TRUE(disk.ok());
  std::shared_ptr<DiskCache> shared_disk = std::move(*disk);
  TileLoader loader(source, *source->layers({}), shared_disk, LoaderOptions{4});
  const auto results = load_all(loader, ids);
  ASSERT_EQ(results.size(), ids.size());
  for (const LoadResult& r : results) {
    EXPECT_EQ(r.status, LoadStatus::loaded) << r.error;
    EXPECT_EQ(r.origin, LoadOrigin::revalidated);
  }
  const LoaderCounters c = loader.counters();
  EXPECT_EQ(c.downloaded_bytes, 0u);
  EXPECT_EQ(c.not_modified, ids.size());
  EXPECT_EQ(c.ok, 0u);
  EXPECT_EQ(shared_disk->counters().hits, ids.size());
}

TEST(Loader, StoreAndHttpSourcesGiveTheSameMeshes) {
  ServedStore served("loader_same");
  auto store_source = open_store_source(served.store);
  ASSERT_TRUE(store_source.ok());
  auto http_source = http(served.server->url());
  const std::vector<geo::TileId> ids{{10, 530, 350}, {11, 1061, 700}, kTile};
  TileLoader a(*store_source, *(*store_source)->layers({}), nullptr, LoaderOptions{2});
  TileLoader b(http_source, *http_source->layers({}), nullptr, LoaderOptions{2});
  auto ra = load_all(a, ids), rb = load_all(b, ids);
  ASSERT_EQ(ra.size(), ids.size());
  ASSERT_EQ(rb.size(), ids.size());
  const auto by_key = [](std::vector<LoadResult>& v) {
    std::sort(v.begin(), v.end(),
              [](const LoadResult& x, const LoadResult& y) { return x.key < y.key; });
  };
  by_key(ra);
  by_key(rb);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    ASSERT_EQ(ra[i].status, LoadStatus::loaded);
    ASSERT_EQ(rb[i].status, LoadStatus::loaded);
    EXPECT_EQ(ra[i].origin, LoadOrigin::store);
    const TileMesh& x = *ra[i].mesh;
    const TileMesh& y = *rb[i].mesh;
    ASSERT_EQ(x.vertices.size(), y.vertices.size());
    EXPECT_EQ(0, std::memcmp(x.vertices.data(), y.vertices.data(),
                             x.vertices.size() * sizeof(MeshVertex)));
    EXPECT_EQ(x.indices16, y.indices16);
  }
}

class NoGpu final : public GpuUploader {
 public:
  GpuMesh upload(const TileMesh& m) override {
    GpuMesh g;
    g.vao = 1;
    g.bytes = m.byte_size();
    return g;
  }
  void release(GpuMesh&) override {}
};

TEST(Streaming, MovingTheCameraDropsTheOldViewsQueuedRequestsOverHttp) {
  ServedStore served("stream_drop");
  auto source = http(served.server->url());
  TileLoader loader(source, *source->layers({}), nullptr, LoaderOptions{1});
  TileStreamer streamer(loader, StreamerOptions{});
  NoGpu gpu;
  // The root, then the close view's tiles queued while the worker is held.
  const geo::MercatorRect r = geo::TileId{10, 530, 350}.bounds();
  const geo::LonLat c =
      geo::NormalisedMercator().inverse({(r.min_x + r.max_x) / 2, (r.min_y + r.max_y) / 2});
  Camera camera(1280, 720, 60);
  camera.set_pose({c.lon, c.lat, 400000, 0, -90});
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  while (!streamer.update(camera, gpu).complete && std::chrono::steady_clock::now() < until)
    loader.wait_for_results(std::chrono::milliseconds(20));
  ASSERT_TRUE(streamer.last_frame().complete);
  loader.set_paused(true);
  const LoaderCounters before = loader.counters();
  camera.set_pose({c.lon, c.lat, 1500, 0, -90});
  const std::size_t queued = streamer.update(camera, gpu).wanted;
  ASSERT_GT(queued, 0u);
  camera.set_pose({c.lon + 90, c.lat, 1500, 0, -90});  // far away: nothing of the layer in view
  EXPECT_EQ(streamer.update(camera, gpu).wanted, 0u);
  loader.set_paused(false);
  for (int i = 0; i < 10; ++i) {
    streamer.update(camera, gpu);
    loader.wait_for_results(std::chrono::milliseconds(20));
  }
  const LoaderCounters after = loader.counters();
  EXPECT_EQ(after.dropped - before.dropped, queued);
  EXPECT_EQ(after.requests, before.requests) << "a dropped request reached the server";
}

}  // namespace
}  // namespace tinstream::client
