// Test helpers for the client's integration tests: child processes (the real tinstream-server,
// tinstream, tinstream-viewer) and a scripted HTTP peer on 127.0.0.1 for the failure cases a real
// server does not produce on demand (5xx, silence). Every wait is bounded.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace tinstream::client::testing {

std::string binary(const std::string& name);  // build/bin/<name>

// A child process; killed and reaped by the destructor unless waited for.
class Child {
 public:
  // stdout (and stderr when capture_stderr) go to pipes read by read_line / output().
  Child(const std::string& program, const std::vector<std::string>& args,
        bool capture_stderr = false, const std::vector<std::string>& env = {});
  ~Child();
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  pid_t pid() const { return pid_; }
  // The next line of stdout within `limit` ("" on EOF or timeout).
  std::string read_line(std::chrono::milliseconds limit);
  // Waits for the exit (up to `limit`); the exit status, 128 + signal, or -1 on timeout
  // (the child is then killed). Collects the rest of stdout/stderr.
  int wait(std::chrono::milliseconds limit);
  const std::string& out() const { return out_; }
  const std::string& err() const { return err_; }

 private:
  void drain(bool block_until_eof, std::chrono::steady_clock::time_point until);
  pid_t pid_ = -1;
  int out_fd_ = -1, err_fd_ = -1;
  std::string out_, err_, pending_;
};

// tinstream-server on 127.0.0.1, any free port, over `store`; stopped by the destructor. Its
// configuration file (server-*.json beside the store) is removed once the server listens.
class Server {
 public:
  explicit Server(const std::filesystem::path& store, const std::string& extra_config = "");
  std::uint16_t port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  const std::filesystem::path& config() const { return config_; }

 private:
  std::filesystem::path config_;
  std::unique_ptr<Child> child_;
  std::uint16_t port_ = 0;
};

// A listening socket on 127.0.0.1 that answers each request (index counted over all
// connections) with what `respond` returns: the raw bytes of a response, or "" to stay silent
// (the connection is held open until the peer is destroyed).
class ScriptedPeer {
 public:
  using Respond = std::function<std::string(int request_index, const std::string& request)>;
  explicit ScriptedPeer(Respond respond);
  ~ScriptedPeer();
  std::uint16_t port() const { return port_; }
  int requests() const { return requests_.load(); }

 private:
  void serve();
  Respond respond_;
  int listen_fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> requests_{0};
  std::thread thread_;
};

// An HTTP response with a body.
std::string http_response(int status, const std::string& body,
                          const std::vector<std::string>& headers = {});

// GET `path` from 127.0.0.1:port on a connection of its own (Connection: close): the whole
// response, headers included, or "" when it fails or takes more than 30 s.
std::string http_get(std::uint16_t port, const std::string& path);

// A port on 127.0.0.1 with no listener (bound, then closed).
std::uint16_t closed_port();

}  // namespace tinstream::client::testing
