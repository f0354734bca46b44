// Shared helpers for the server tests: a test store with real tiles, and a tiny blocking HTTP/1.1
// client over POSIX sockets (so tests can also send malformed bytes). 127.0.0.1 only; every read
// has a timeout so a broken server fails a test instead of hanging it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "tinstream/geo/tile_id.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::testing {

// The tile the server suites store and request.
inline const geo::TileId kTile = *geo::TileId::from_zxy(12, 2121, 1401);

// A fresh directory under the build tree, removed by the destructor.
struct TempDir {
  explicit TempDir(const std::string& name);
  ~TempDir();
  std::filesystem::path path;
};

// Sets the process's open-files limit (RLIMIT_NOFILE) to soft/hard for one test and puts back the
// limit it found when it goes out of scope, so a failed assertion cannot leave a lowered limit
// behind for the next test of the same process (ctest runs each binary's tests in one process).
class OpenFilesLimit {
 public:
  OpenFilesLimit(std::uint64_t soft, std::uint64_t hard);
  ~OpenFilesLimit();
  OpenFilesLimit(const OpenFilesLimit&) = delete;
  OpenFilesLimit& operator=(const OpenFilesLimit&) = delete;
  // The soft and hard limits now (the server under test may have raised the soft one).
  static std::uint64_t soft_now();
  static std::uint64_t hard_now();

 private:
  std::uint64_t saved_soft_ = 0;
  std::uint64_t saved_hard_ = 0;
};

// The tiles of the test layer: a 4×4 block at level 12 (near Luxembourg) and their ancestors up to
// level 10, built from the synthetic surface (grid_tile.hpp).
std::vector<geo::TileId> test_tile_ids();
// Writes layer `name` with those tiles through LayerWriter (n×n vertex grids) and publishes it.
void write_test_layer(const std::filesystem::path& store, const std::string& name,
                      geo::Projection projection = geo::Projection::spherical, int grid = 17);

struct HttpResponse {
  int status = 0;
  std::map<std::string, std::string> headers;  // lower-case names
  std::string body;
  std::string header(const std::string& name) const;
};

class HttpConnection {
 public:
  // receive_buffer > 0: the socket's SO_RCVBUF, set before connecting (the kernel's minimum for
  // small values), so that answers the client leaves unread back up into the server's buffers.
  // from: the local address to connect from (any 127.x.y.z is loopback).
  explicit HttpConnection(std::uint16_t port, int receive_buffer = 0, const std::string& from = {});
  ~HttpConnection();
  HttpConnection(const HttpConnection&) = delete;
  HttpConnection& operator=(const HttpConnection&) = delete;

  bool send_raw(const std::string& bytes);  // false when the peer is gone
  // Reads one response; status 0 when the connection closed or timed out first.
  HttpResponse read_response(bool head_request = false);
  // True when the server closed the connection (EOF within the timeout).
  bool closed_by_peer();
  // True when bytes (or the end of the stream) can be read within `timeout_ms`.
  bool readable(int timeout_ms);
  HttpResponse request(const std::string& method, const std::string& target,
                       const std::map<std::string, std::string>& headers = {},
                       const std::string& body = {});

 private:
  int fd_ = -1;
  std::string buffer_;
};

HttpResponse http_request(std::uint16_t port, const std::string& method, const std::string& target,
                          const std::map<std::string, std::string>& headers = {},
                          const std::string& body = {});
inline HttpResponse http_get(std::uint16_t port, const std::string& target,
                             const std::map<std::string, std::string>& headers = {}) {
  return http_request(port, "GET", target, headers);
}

std::vector<std::uint8_t> gunzip(const std::string& gz);
std::vector<std::uint8_t> inflate_zlib(const std::string& z);
std::vector<std::uint8_t> bytes_of(const std::string& s);

}  // namespace tinstream::testing
