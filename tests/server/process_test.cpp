// The real tinstream-server executable: start on port 0, serve, stop on SIGTERM.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>
#include <utility>

#include "grid_tile.hpp"
#include "qm_decoder.hpp"
#include "test_support.hpp"
#include "tinstream/server/handler.hpp"

namespace tinstream::server {
namespace {

using testing::TempDir;

const std::string kBinary = std::string(TINSTREAM_BINARY_DIR) + "/bin/tinstream-server";

// A child process with its stdout (and, when asked for, the read end of its stderr); killed and
// reaped by the destructor if the test did not wait for it (a failed assertion never leaves a
// server running).
struct Child {
  pid_t pid = -1;
  FILE* out = nullptr;
  int err = -1;
  Child() = default;
  Child(pid_t p, FILE* f, int e = -1) : pid(p), out(f), err(e) {}
  Child(Child&& o) noexcept
      : pid(std::exchange(o.pid, -1)),
        out(std::exchange(o.out, nullptr)),
        err(std::exchange(o.err, -1)) {}
  Child& operator=(Child&&) = delete;
  ~Child() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      int status = 0;
      ::waitpid(pid, &status, 0);
    }
    if (out) std::fclose(out);
    if (err >= 0) ::close(err);
  }
};

Child spawn(const std::vector<std::string>& args, bool capture_stderr = false) {
  int fds[2];
  int err_fds[2] = {-1, -1};
  if (::pipe(fds) != 0) return {};
  if (capture_stderr && ::pipe(err_fds) != 0) return {};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(fds[1], 1);
    ::close(fds[0]);
    ::close(fds[1]);
    if (capture_stderr) {
      ::dup2(err_fds[1], 2);
      ::close(err_fds[0]);
      ::close(err_fds[1]);
    }
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(kBinary.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(kBinary.c_str(), argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  if (capture_stderr) ::close(err_fds[1]);
  return Child{pid, ::fdopen(fds[0], "r"), err_fds[0]};
}

// The port of the child's first line on stdout, "listening on 127.0.0.1:PORT"; 0 (and a test
// failure) when that line does not come.
std::uint16_t listening_port(Child& child) {
  char line[256] = {0};
  if (!std::fgets(line, sizeof line, child.out)) {
    ADD_FAILURE() << "tinstream-server printed no line";
    return 0;
  }
  const std::string text = line;
  if (text.rfind("listening on 127.0.0.1:", 0) != 0) {
    ADD_FAILURE() << "not the \"listening on\" line: " << text;
    return 0;
  }
  return static_cast<std::uint16_t>(std::stoi(text.substr(text.rfind(':') + 1)));
}

int wait_exit(Child& child) {
  int status = 0;
  ::waitpid(child.pid, &status, 0);
  child.pid = -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

TEST(ServerProcess, ServesAndStopsOnSigterm) {
  TempDir dir("process");
  const auto store = dir.path / "store.db";
  testing::write_test_layer(store, "lux");
  const auto config = dir.path / "server.json";
  std::ofstream(config) << R"({"log_level": "warn", "access_log": false})";
  Child c = spawn({"--config", config.string(), "--store", store.string(), "--port", "0",
                   "--address", "127.0.0.1", "--threads", "2"});
  ASSERT_GT(c.pid, 0);
  const std::uint16_t port = listening_port(c);
  ASSERT_NE(port, 0);
  EXPECT_EQ(testing::http_get(port, "/healthz").status, 200);
  const auto tile = *geo::TileId::from_zxy(12, 2121, 1401);
  EXPECT_EQ(testing::http_get(port, "/tiles/lux/" + tile.quadkey()).status, 200);
  // The server runs without an admin token, so the admin API is disabled: a request with any
  // bearer token is refused with 403 (never started, never a crash).
  EXPECT_EQ(
      testing::http_request(port, "POST", "/admin/ingest", {{"Authorization", "Bearer x"}}, "{}")
          .status,
      403);
  testing::HttpConnection idle(port);
  ASSERT_EQ(idle.request("GET", "/healthz").status, 200);
  ::kill(c.pid, SIGTERM);
  EXPECT_EQ(wait_exit(c), 0);
  EXPECT_TRUE(idle.closed_by_peer());
}

// The exit status of `child` once it exits within `limit`; -1 (and the child left to the
// destructor's SIGKILL) when it does not.
int wait_exit_within(Child& child, std::chrono::milliseconds limit) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    int status = 0;
    if (::waitpid(child.pid, &status, WNOHANG) == child.pid) {
      child.pid = -1;
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return -1;
}

// Reads the child's stderr until it contains `text` or `limit` has passed; returns what was read.
std::string read_stderr_until(Child& child, const std::string& text,
                              std::chrono::milliseconds limit) {
  std::string got;
  const auto until = std::chrono::steady_clock::now() + limit;
  while (got.find(text) == std::string::npos) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        until - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    pollfd p{child.err, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
    char buf[4096];
    const ssize_t n = ::read(child.err, buf, sizeof buf);
    if (n <= 0) break;
    got.append(buf, static_cast<std::size_t>(n));
  }
  return got;
}

// SIGINT, like SIGTERM: the server stops accepting, finishes the answers in flight — a pipelined
// burst it is still writing, a request whose header was not complete yet — each connection's
// last one with `Connection: close`, then exits 0. Logs go to stderr; stdout has only the
// "listening on" line.
TEST(ServerProcess, SigintFinishesInFlightResponsesAndExitsZero) {
  TempDir dir("sigint");
  const auto store = dir.path / "store.db";
  testing::write_test_layer(store, "lux", geo::Projection::spherical, 65);  // tens of KiB a tile
  const auto config = dir.path / "server.json";
  std::ofstream(config) << R"({"log_level": "info", "access_log": false})";
  Child c = spawn({"--config", config.string(), "--store", store.string(), "--port", "0",
                   "--address", "127.0.0.1", "--threads", "2"},
                  /*capture_stderr=*/true);
  ASSERT_GT(c.pid, 0);
  const std::uint16_t port = listening_port(c);
  ASSERT_NE(port, 0);
  const auto tile = *geo::TileId::from_zxy(12, 2121, 1401);
  const std::string native = "/tiles/lux/" + tile.quadkey();
  const auto ref = testing::http_get(port, native);
  ASSERT_EQ(ref.status, 200);

  // A burst of answers that the client does not read yet, 8 MiB, more than the socket buffers
  // hold (net.ipv4.tcp_wmem: 4 MiB at most): the server is writing when the signal comes.
  testing::HttpConnection burst(port, /*receive_buffer=*/2048);
  const std::size_t requests = (8u << 20) / ref.body.size() + 1;
  std::string bytes;
  for (std::size_t i = 0; i < requests; ++i)
    bytes += "GET " + native + " HTTP/1.1\r\nHost: x\r\n\r\n";
  ASSERT_TRUE(burst.send_raw(bytes));
  // Half a request header (after a first request, so the connection is surely accepted).
  testing::HttpConnection partial(port);
  ASSERT_EQ(partial.request("GET", "/healthz").status, 200);
  ASSERT_TRUE(partial.send_raw("GET " + native + " HTTP/1.1\r\nHost: x\r\n"));
  testing::HttpConnection idle(port);
  ASSERT_EQ(idle.request("GET", "/healthz").status, 200);

  ::kill(c.pid, SIGINT);
  const std::string log = read_stderr_until(c, "shutting down", std::chrono::seconds(10));
  ASSERT_NE(log.find("shutting down"), std::string::npos) << log;
  EXPECT_TRUE(idle.closed_by_peer());

  ASSERT_TRUE(partial.send_raw("\r\n"));
  const auto late = partial.read_response();
  EXPECT_EQ(late.status, 200);
  EXPECT_EQ(late.header("Connection"), "close");
  EXPECT_TRUE(late.body == ref.body);
  EXPECT_TRUE(partial.closed_by_peer());

  // Every answer of the burst that comes is whole; the last says `Connection: close`.
  std::size_t answers = 0;
  std::string last_connection;
  for (; answers < requests; ++answers) {
    const auto r = burst.read_response();
    if (r.status == 0) break;
    EXPECT_EQ(r.status, 200) << answers;
    EXPECT_TRUE(r.body == ref.body) << answers;
    last_connection = r.header("Connection");
  }
  EXPECT_GT(answers, 0u);
  EXPECT_EQ(last_connection, "close") << answers << " of " << requests << " answers";
  EXPECT_TRUE(burst.closed_by_peer());

  EXPECT_EQ(wait_exit_within(c, std::chrono::seconds(10)), 0);
  EXPECT_EQ(testing::http_get(port, "/healthz").status, 0);
  std::string rest;
  char line[256];
  while (std::fgets(line, sizeof line, c.out)) rest += line;
  EXPECT_EQ(rest, "") << "stdout is for the \"listening on\" line only";
}

TEST(ServerProcess, HelpAndBadConfig) {
  Child help = spawn({"--help"});
  std::string text;
  char buf[512];
  while (std::fgets(buf, sizeof buf, help.out)) text += buf;
  EXPECT_EQ(wait_exit(help), 0);
  for (const char* opt : {"--store", "--port", "--config", "--address", "--threads"}) {
    EXPECT_NE(text.find(opt), std::string::npos) << opt;
  }
  TempDir dir("badcfg");
  std::ofstream(dir.path / "bad.json") << R"({"prot": 80})";
  Child bad = spawn({"--config", (dir.path / "bad.json").string()});
  while (std::fgets(buf, sizeof buf, bad.out)) {
  }
  EXPECT_NE(wait_exit(bad), 0);
}

const std::string kCli = std::string(TINSTREAM_BINARY_DIR) + "/bin/tinstream";

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Decoded terrain tile with its rectangle, for edge comparisons.
struct Terrain {
  geo::TileId id;
  testing::DecodedMesh mesh;
  geo::LonLatRect rect;
  double lon(std::uint32_t i) const {
    return rect.west + (rect.east - rect.west) * mesh.u[i] / 32767.0;
  }
  double lat(std::uint32_t i) const {
    return rect.south + (rect.north - rect.south) * mesh.v[i] / 32767.0;
  }
  double h(std::uint32_t i) const {
    return mesh.min_height +
           (static_cast<double>(mesh.max_height) - mesh.min_height) * mesh.h[i] / 32767.0;
  }
  double step() const { return (static_cast<double>(mesh.max_height) - mesh.min_height) / 32767.0; }
};

// Checks every pair of same-level east/west and north/south neighbours among `tiles`: each edge
// vertex of one has a vertex of the other at the same lon/lat, with heights within both
// quantisation steps. Returns the number of shared borders compared.
int check_shared_edges(const std::map<geo::TileId, Terrain>& tiles) {
  int borders = 0;
  for (const auto& [id, a] : tiles) {
    for (auto dir : {geo::Direction::east, geo::Direction::south}) {
      auto nid = id.neighbour(dir);
      if (!nid) continue;
      auto it = tiles.find(*nid);
      if (it == tiles.end()) continue;
      const Terrain& b = it->second;
      const auto& a_list = dir == geo::Direction::east ? a.mesh.east : a.mesh.south;
      const auto& b_list = dir == geo::Direction::east ? b.mesh.west : b.mesh.north;
      ++borders;
      for (std::uint32_t i : a_list) {
        bool found = false;
        for (std::uint32_t j : b_list) {
          if (std::abs(std::remainder(a.lon(i) - b.lon(j), 360.0)) < 1e-9 &&
              std::abs(a.lat(i) - b.lat(j)) < 1e-9) {  // ±180° is one meridian
            found = true;
            EXPECT_NEAR(a.h(i), b.h(j), a.step() + b.step() + 1e-3)
                << id.to_string() << " vs " << nid->to_string();
          }
        }
        EXPECT_TRUE(found) << id.to_string() << " edge vertex at " << a.lon(i) << "," << a.lat(i)
                           << " missing in " << nid->to_string();
      }
    }
  }
  return borders;
}

TEST(CesiumExport, DirTreeDecodesAndMatchesTheServer) {
  if (!std::filesystem::exists(kCli)) GTEST_SKIP() << "tinstream CLI not built";
  TempDir dir("export");
  const auto store = dir.path / "store.db";
  testing::write_test_layer(store, "lux");
  const auto out = dir.path / "tree";
  Child c = [&] {
    int fds[2];
    EXPECT_EQ(::pipe(fds), 0);
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::dup2(fds[1], 1);
      ::close(fds[0]);
      ::close(fds[1]);
      ::execl(kCli.c_str(), kCli.c_str(), "export", "--store", store.c_str(), "--layer", "lux",
              "--dir", out.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    return Child{pid, ::fdopen(fds[0], "r")};
  }();
  char buf[512];
  while (std::fgets(buf, sizeof buf, c.out)) {
  }
  ASSERT_EQ(wait_exit(c), 0);

  const auto lj = nlohmann::json::parse(read_file(out / "layer.json"));
  EXPECT_EQ(lj["format"], "quantized-mesh-1.0");
  std::size_t listed = 0;
  std::map<geo::TileId, Terrain> level12;
  for (std::uint32_t z = 0; z < lj["available"].size(); ++z) {
    for (const auto& r : lj["available"][z]) {
      for (std::uint32_t x = r["startX"]; x <= r["endX"].get<std::uint32_t>(); ++x) {
        for (std::uint32_t y = r["startY"]; y <= r["endY"].get<std::uint32_t>(); ++y) {
          ++listed;
          const auto path =
              out / std::to_string(z) / std::to_string(x) / (std::to_string(y) + ".terrain");
          ASSERT_TRUE(std::filesystem::exists(path)) << path;
          const auto id = *geo::TileId::from_tms(z, x, y);
          Terrain t{id, testing::decode_quantized_mesh(testing::gunzip(read_file(path))),
                    id.lonlat_bounds(geo::NormalisedMercator())};
          EXPECT_TRUE(t.mesh.oct_normals.has_value());
          if (z == 12) level12.emplace(id, std::move(t));
        }
      }
    }
  }
  // + ancestors at levels 0-9 and the other three level-1 tiles (terrain::kWholeLevels)
  EXPECT_EQ(listed, testing::test_tile_ids().size() + 13);
  EXPECT_EQ(level12.size(), 16u);
  EXPECT_EQ(check_shared_edges(level12), 24);

  // Byte-identical to what the server sends for the same request.
  auto st = store::TileStore::open(store, store::TileStore::Mode::read_only);
  ASSERT_TRUE(st.ok());
  Context ctx;
  ctx.config.store = store;
  ctx.store = [&]() -> Result<store::TileStore*> { return &*st; };
  Request req;
  req.method = "GET";
  const auto id = *geo::TileId::from_zxy(12, 2121, 1401);
  req.target = "/tiles/lux/12/2121/" + std::to_string(id.tms_row()) + ".terrain";
  req.accept_encoding = "gzip";
  req.accept = "application/vnd.quantized-mesh;extensions=octvertexnormals";
  const Response res = handle(req, ctx);
  ASSERT_EQ(res.status, 200);
  EXPECT_EQ(res.payload(),
            read_file(out / "12" / "2121" / (std::to_string(id.tms_row()) + ".terrain")));
}

TEST(ServerProcess, RealIngestThroughTheAdminApiAndWatertightTerrain) {
  const std::filesystem::path data = TINSTREAM_SHARED_DATA;
  if (!std::filesystem::exists(data / "luxembourg_elev.tif")) GTEST_SKIP() << "no shared data";
  TempDir dir("real");
  const auto config = dir.path / "server.json";
  std::ofstream(config) << nlohmann::json{{"log_level", "warn"},
                                          {"access_log", false},
                                          {"data_root", data.string()},
                                          {"admin_token_env", "TINSTREAM_TEST_ADMIN_TOKEN"}}
                               .dump();
  ::setenv("TINSTREAM_TEST_ADMIN_TOKEN", "real-token", 1);
  Child c = spawn({"--config", config.string(), "--store", (dir.path / "store.db").string(),
                   "--port", "0", "--address", "127.0.0.1", "--threads", "2"});
  ::unsetenv("TINSTREAM_TEST_ADMIN_TOKEN");
  const std::uint16_t port = listening_port(c);
  ASSERT_NE(port, 0);
  const std::map<std::string, std::string> admin = {{"Authorization", "Bearer real-token"},
                                                    {"Content-Type", "application/json"}};
  auto r = testing::http_request(port, "POST", "/admin/ingest", admin,
                                 R"({"layer": "lux", "sources": ["luxembourg_elev.tif"],
                                     "options": {"max_points": 300}})");
  ASSERT_EQ(r.status, 202) << r.body;
  const std::string job = nlohmann::json::parse(r.body)["job"];
  nlohmann::json status;
  for (int i = 0; i < 3000; ++i) {
    const auto jr = testing::http_get(port, "/admin/jobs/" + job, admin);
    ASSERT_EQ(jr.status, 200) << "tinstream-server stopped answering during the ingest (crashed?)";
    status = nlohmann::json::parse(jr.body);
    if (status["state"] != "queued" && status["state"] != "running") break;
    ::usleep(10000);
  }
  if (status["state"] == "failed" &&
      status["errors"][0].get<std::string>().find("no ingest pipeline") != std::string::npos) {
    ::kill(c.pid, SIGTERM);
    wait_exit(c);
    GTEST_SKIP() << "tinstream-server built without core/ingest";
  }
  ASSERT_EQ(status["state"], "succeeded") << status.dump();

  auto lj_res = testing::http_get(port, "/tiles/lux/layer.json");
  ASSERT_EQ(lj_res.status, 200);
  const auto lj = nlohmann::json::parse(lj_res.body);
  std::map<std::uint32_t, std::map<geo::TileId, Terrain>> by_level;
  int fetched = 0;
  for (std::uint32_t z = 0; z < lj["available"].size(); ++z) {
    for (const auto& range : lj["available"][z]) {
      for (std::uint32_t x = range["startX"]; x <= range["endX"].get<std::uint32_t>(); ++x) {
        for (std::uint32_t y = range["startY"]; y <= range["endY"].get<std::uint32_t>(); ++y) {
          auto t = testing::http_get(port,
                                     "/tiles/lux/" + std::to_string(z) + "/" + std::to_string(x) +
                                         "/" + std::to_string(y) + ".terrain",
                                     {{"Accept-Encoding", "gzip"}});
          ASSERT_EQ(t.status, 200);
          const auto id = *geo::TileId::from_tms(z, x, y);
          auto mesh = testing::decode_quantized_mesh(testing::gunzip(t.body));
          for (std::size_t k = 0; k < mesh.indices.size(); k += 3) {
            const auto a = mesh.indices[k], b = mesh.indices[k + 1], cc = mesh.indices[k + 2];
            ASSERT_LT(std::max({a, b, cc}), mesh.u.size());
            const double cross = (static_cast<double>(mesh.u[b]) - mesh.u[a]) *
                                     (static_cast<double>(mesh.v[cc]) - mesh.v[a]) -
                                 (static_cast<double>(mesh.v[b]) - mesh.v[a]) *
                                     (static_cast<double>(mesh.u[cc]) - mesh.u[a]);
            EXPECT_GE(cross, 0) << id.to_string();  // CCW (quantisation may flatten slivers)
          }
          by_level[z].emplace(
              id, Terrain{id, std::move(mesh), id.lonlat_bounds(geo::NormalisedMercator())});
          ++fetched;
        }
      }
    }
  }
  EXPECT_GT(fetched, 10);
  int borders = 0;
  for (const auto& [z, tiles] : by_level) borders += check_shared_edges(tiles);
  EXPECT_GT(borders, 5);
  ::kill(c.pid, SIGTERM);
  EXPECT_EQ(wait_exit(c), 0);
}

}  // namespace
}  // namespace tinstream::server
