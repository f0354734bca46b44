// The real tinstream-server executable: start on port 0, serve, stop on SIGTERM.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

namespace tinstream::server {
namespace {

using testing::TempDir;

const std::string kBinary = std::string(TINSTREAM_BINARY_DIR) + "/bin/tinstream-server";

struct Child {
  pid_t pid = -1;
  FILE* out = nullptr;
};

Child spawn(const std::vector<std::string>& args) {
  int fds[2];
  if (::pipe(fds) != 0) return {};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(fds[1], 1);
    ::close(fds[0]);
    ::close(fds[1]);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(kBinary.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(kBinary.c_str(), argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  return {pid, ::fdopen(fds[0], "r")};
}

int wait_exit(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
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
  char line[256] = {0};
  ASSERT_NE(std::fgets(line, sizeof line, c.out), nullptr);
  const std::string text = line;
  ASSERT_EQ(text.rfind("listening on 127.0.0.1:", 0), 0u) << text;
  const auto port = static_cast<std::uint16_t>(std::stoi(text.substr(text.rfind(':') + 1)));
  EXPECT_EQ(testing::http_get(port, "/healthz").status, 200);
  const auto tile = *geo::TileId::from_zxy(12, 2121, 1401);
  EXPECT_EQ(testing::http_get(port, "/tiles/lux/" + tile.quadkey()).status, 200);
  // The stock executable has no ingest pipeline linked in unless the lead plugs it in; either
  // way the job is accepted or refused cleanly, never a crash. Admin is disabled without token.
  EXPECT_EQ(testing::http_request(port, "POST", "/admin/ingest", {{"Authorization", "Bearer x"}}, "{}").status, 403);
  testing::HttpConnection idle(port);
  ASSERT_EQ(idle.request("GET", "/healthz").status, 200);
  ::kill(c.pid, SIGTERM);
  EXPECT_EQ(wait_exit(c.pid), 0);
  EXPECT_TRUE(idle.closed_by_peer());
  std::fclose(c.out);
}

TEST(ServerProcess, HelpAndBadConfig) {
  Child help = spawn({"--help"});
  std::string text;
  char buf[512];
  while (std::fgets(buf, sizeof buf, help.out)) text += buf;
  std::fclose(help.out);
  EXPECT_EQ(wait_exit(help.pid), 0);
  for (const char* opt : {"--store", "--port", "--config", "--address", "--threads"}) {
    EXPECT_NE(text.find(opt), std::string::npos) << opt;
  }
  TempDir dir("badcfg");
  std::ofstream(dir.path / "bad.json") << R"({"prot": 80})";
  Child bad = spawn({"--config", (dir.path / "bad.json").string()});
  while (std::fgets(buf, sizeof buf, bad.out)) {
  }
  std::fclose(bad.out);
  EXPECT_NE(wait_exit(bad.pid), 0);
}

}  // namespace
}  // namespace tinstream::server
