#include "test_support.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <random>
#include <stdexcept>

#include "grid_tile.hpp"

namespace tinstream::testing {

TempDir::TempDir(const std::string& name) {
  std::random_device rd;
  path = std::filesystem::path(TINSTREAM_BINARY_DIR) / "test-tmp" /
         (name + "-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  std::filesystem::create_directories(path);
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

namespace {
rlimit open_files_now() {
  rlimit now{};
  if (::getrlimit(RLIMIT_NOFILE, &now) != 0) throw std::runtime_error("getrlimit failed");
  return now;
}
}  // namespace

OpenFilesLimit::OpenFilesLimit(std::uint64_t soft, std::uint64_t hard) {
  const rlimit before = open_files_now();
  saved_soft_ = before.rlim_cur;
  saved_hard_ = before.rlim_max;
  const rlimit wanted{soft, hard};
  if (::setrlimit(RLIMIT_NOFILE, &wanted) != 0)
    throw std::runtime_error("setrlimit(RLIMIT_NOFILE, " + std::to_string(soft) + ", " +
                             std::to_string(hard) + ") failed");
}

OpenFilesLimit::~OpenFilesLimit() {
  const rlimit saved{saved_soft_, saved_hard_};
  ::setrlimit(RLIMIT_NOFILE, &saved);
}

std::uint64_t OpenFilesLimit::soft_now() { return open_files_now().rlim_cur; }
std::uint64_t OpenFilesLimit::hard_now() { return open_files_now().rlim_max; }

std::vector<geo::TileId> test_tile_ids() {
  std::vector<geo::TileId> ids;
  for (std::uint32_t x = 2120; x < 2124; ++x)
    for (std::uint32_t y = 1400; y < 1404; ++y) ids.push_back(*geo::TileId::from_zxy(12, x, y));
  for (std::uint32_t x = 1060; x < 1062; ++x)
    for (std::uint32_t y = 700; y < 702; ++y) ids.push_back(*geo::TileId::from_zxy(11, x, y));
  ids.push_back(*geo::TileId::from_zxy(10, 530, 350));
  return ids;
}

void write_test_layer(const std::filesystem::path& path, const std::string& name,
                      geo::Projection projection, int grid) {
  auto st = store::TileStore::open(path, store::TileStore::Mode::read_write);
  if (!st) throw std::runtime_error("open store: " + st.error().message);
  store::LayerInfo info;
  info.name = name;
  info.projection = projection;
  info.min_level = 10;
  info.max_level = 12;
  info.max_points = 1000;
  info.attribution = "synthetic test surface";
  const auto ids = test_tile_ids();
  const geo::NormalisedMercator merc(projection);
  info.mercator_bounds = ids.back().bounds();
  info.bounds = ids.back().lonlat_bounds(merc);
  info.level_max_error = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 4.0, 2.0, 0.0};
  auto writer = st->begin_layer(info);
  if (!writer) throw std::runtime_error("begin_layer: " + writer.error().message);
  double min_z = 1e300, max_z = -1e300;
  for (const auto& id : ids) {
    auto t = make_grid_tile(id, grid, synthetic_height);
    min_z = std::min(min_z, t.min_z);
    max_z = std::max(max_z, t.max_z);
    Status s = (*writer)->put(t);
    if (!s) throw std::runtime_error("put: " + s.error().message);
  }
  info.tile_count = ids.size();
  info.point_count =
      std::uint64_t{16} * static_cast<std::uint64_t>(grid) * static_cast<std::uint64_t>(grid);
  info.min_z = min_z;
  info.max_z = max_z;
  Status s = (*writer)->publish(info);
  if (!s) throw std::runtime_error("publish: " + s.error().message);
}

std::string HttpResponse::header(const std::string& name) const {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  auto it = headers.find(lower);
  return it == headers.end() ? std::string() : it->second;
}

HttpConnection::HttpConnection(std::uint16_t port, int receive_buffer, const std::string& from) {
  fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd_ < 0) return;
  if (!from.empty()) {
    sockaddr_in local{};
    local.sin_family = AF_INET;
    ::inet_pton(AF_INET, from.c_str(), &local.sin_addr);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
      ::close(fd_);
      fd_ = -1;
      return;
    }
  }
  if (receive_buffer > 0)
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  timeval tv{10, 0};
  ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

HttpConnection::~HttpConnection() {
  if (fd_ >= 0) ::close(fd_);
}

bool HttpConnection::send_raw(const std::string& bytes) {
  if (fd_ < 0) return false;
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

HttpResponse HttpConnection::read_response(bool head_request) {
  HttpResponse r;
  if (fd_ < 0) return r;
  auto fill = [&]() {
    char chunk[65536];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n <= 0) return false;
    buffer_.append(chunk, static_cast<std::size_t>(n));
    return true;
  };
  std::size_t end;
  while ((end = buffer_.find("\r\n\r\n")) == std::string::npos) {
    if (!fill()) return r;
  }
  const std::string head = buffer_.substr(0, end);
  buffer_.erase(0, end + 4);
  std::size_t line_end = head.find("\r\n");
  const std::string status_line = head.substr(0, line_end);
  if (status_line.size() < 12) return r;
  const int status = std::stoi(status_line.substr(9, 3));
  std::size_t pos = line_end == std::string::npos ? head.size() : line_end + 2;
  while (pos < head.size()) {
    std::size_t e = head.find("\r\n", pos);
    if (e == std::string::npos) e = head.size();
    const std::string line = head.substr(pos, e - pos);
    const auto colon = line.find(':');
    if (colon != std::string::npos) {
      std::string k = line.substr(0, colon);
      std::transform(k.begin(), k.end(), k.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      std::string v = line.substr(colon + 1);
      while (!v.empty() && v.front() == ' ') v.erase(0, 1);
      r.headers[k] = v;
    }
    pos = e + 2;
  }
  if (status == 100) return read_response(head_request);
  std::size_t length = 0;
  if (auto it = r.headers.find("content-length"); it != r.headers.end())
    length = std::stoul(it->second);
  if (head_request || status == 304 || status == 204) length = 0;
  while (buffer_.size() < length) {
    if (!fill()) return r;
  }
  r.body = buffer_.substr(0, length);
  buffer_.erase(0, length);
  buffer_.shrink_to_fit();  // a connection kept open holds no more than what is left unread
  r.status = status;
  return r;
}

bool HttpConnection::closed_by_peer() {
  if (fd_ < 0) return true;
  char c;
  const ssize_t n = ::recv(fd_, &c, 1, 0);
  return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
}

bool HttpConnection::readable(int timeout_ms) {
  if (!buffer_.empty()) return true;
  if (fd_ < 0) return true;
  pollfd p{fd_, POLLIN, 0};
  return ::poll(&p, 1, timeout_ms) > 0;
}

HttpResponse HttpConnection::request(const std::string& method, const std::string& target,
                                     const std::map<std::string, std::string>& headers,
                                     const std::string& body) {
  std::string req = method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  for (const auto& [k, v] : headers) {
    req += k;
    req += ": ";
    req += v;
    req += "\r\n";
  }
  if (!body.empty() || method == "POST")
    req += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  req += "\r\n" + body;
  if (!send_raw(req)) return {};
  return read_response(method == "HEAD");
}

HttpResponse http_request(std::uint16_t port, const std::string& method, const std::string& target,
                          const std::map<std::string, std::string>& headers,
                          const std::string& body) {
  HttpConnection c(port);
  return c.request(method, target, headers, body);
}

namespace {
std::vector<std::uint8_t> inflate_with(const std::string& in, int window_bits) {
  z_stream zs{};
  if (inflateInit2(&zs, window_bits) != Z_OK) throw std::runtime_error("inflateInit2");
  std::vector<std::uint8_t> out;
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  zs.avail_in = static_cast<uInt>(in.size());
  int rc = Z_OK;
  std::uint8_t chunk[65536];
  while (rc != Z_STREAM_END) {
    zs.next_out = chunk;
    zs.avail_out = sizeof chunk;
    rc = inflate(&zs, Z_NO_FLUSH);
    if (rc != Z_OK && rc != Z_STREAM_END) {
      inflateEnd(&zs);
      throw std::runtime_error("inflate failed");
    }
    out.insert(out.end(), chunk, chunk + (sizeof chunk - zs.avail_out));
    if (rc == Z_OK && zs.avail_in == 0 && zs.avail_out != 0) {
      inflateEnd(&zs);
      throw std::runtime_error("truncated stream");
    }
  }
  inflateEnd(&zs);
  return out;
}
}  // namespace

std::vector<std::uint8_t> gunzip(const std::string& gz) { return inflate_with(gz, 31); }
std::vector<std::uint8_t> inflate_zlib(const std::string& z) { return inflate_with(z, 15); }
std::vector<std::uint8_t> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

}  // namespace tinstream::testing
