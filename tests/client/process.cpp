#include "process.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <stdexcept>

namespace tinstream::client::testing {

std::string binary(const std::string& name) {
  return std::string(TINSTREAM_BINARY_DIR) + "/bin/" + name;
}

Child::Child(const std::string& program, const std::vector<std::string>& args, bool capture_stderr,
             const std::vector<std::string>& env) {
  int out[2], err[2] = {-1, -1};
  if (::pipe(out) != 0 || (capture_stderr && ::pipe(err) != 0)) throw std::runtime_error("pipe");
  pid_ = ::fork();
  if (pid_ == 0) {
    ::dup2(out[1], 1);
    if (capture_stderr) ::dup2(err[1], 2);
    ::close(out[0]);
    ::close(out[1]);
    if (capture_stderr) {
      ::close(err[0]);
      ::close(err[1]);
    }
    for (const std::string& e : env) ::putenv(const_cast<char*>(e.c_str()));
    std::vector<char*> argv{const_cast<char*>(program.c_str())};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(program.c_str(), argv.data());
    ::_exit(127);
  }
  ::close(out[1]);
  out_fd_ = out[0];
  if (capture_stderr) {
    ::close(err[1]);
    err_fd_ = err[0];
  }
}

Child::~Child() {
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
  }
  if (out_fd_ >= 0) ::close(out_fd_);
  if (err_fd_ >= 0) ::close(err_fd_);
}

void Child::drain(bool block_until_eof, std::chrono::steady_clock::time_point until) {
  while (out_fd_ >= 0 || err_fd_ >= 0) {
    pollfd fds[2];
    int n = 0;
    if (out_fd_ >= 0) fds[n++] = {out_fd_, POLLIN, 0};
    if (err_fd_ >= 0) fds[n++] = {err_fd_, POLLIN, 0};
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        until - std::chrono::steady_clock::now());
    const int timeout = block_until_eof ? static_cast<int>(std::max<long>(left.count(), 0)) : 0;
    if (::poll(fds, static_cast<nfds_t>(n), timeout) <= 0) return;
    for (int i = 0; i < n; ++i) {
      if (!(fds[i].revents & (POLLIN | POLLHUP))) continue;
      char buf[8192];
      const ssize_t got = ::read(fds[i].fd, buf, sizeof buf);
      const bool is_out = fds[i].fd == out_fd_;
      if (got <= 0) {
        ::close(fds[i].fd);
        (is_out ? out_fd_ : err_fd_) = -1;
        continue;
      }
      (is_out ? pending_ : err_).append(buf, static_cast<std::size_t>(got));
    }
  }
}

std::string Child::read_line(std::chrono::milliseconds limit) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (pending_.find('\n') == std::string::npos && out_fd_ >= 0 &&
         std::chrono::steady_clock::now() < until) {
    pollfd p{out_fd_, POLLIN, 0};
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        until - std::chrono::steady_clock::now());
    if (::poll(&p, 1, static_cast<int>(std::max<long>(left.count(), 0))) <= 0) break;
    char buf[4096];
    const ssize_t got = ::read(out_fd_, buf, sizeof buf);
    if (got <= 0) {
      ::close(out_fd_);
      out_fd_ = -1;
      break;
    }
    pending_.append(buf, static_cast<std::size_t>(got));
  }
  const std::size_t nl = pending_.find('\n');
  if (nl == std::string::npos) return {};
  std::string line = pending_.substr(0, nl);
  out_ += pending_.substr(0, nl + 1);
  pending_.erase(0, nl + 1);
  return line;
}

int Child::wait(std::chrono::milliseconds limit) {
  const auto until = std::chrono::steady_clock::now() + limit;
  int status = 0;
  while (true) {
    drain(false, until);
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) break;
    if (std::chrono::steady_clock::now() >= until) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
      pid_ = -1;
      return -1;
    }
    drain(true, std::min(until, std::chrono::steady_clock::now() + std::chrono::milliseconds(20)));
  }
  pid_ = -1;
  drain(true, std::chrono::steady_clock::now() + std::chrono::seconds(5));
  out_ += pending_;
  pending_.clear();
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

Server::Server(const std::filesystem::path& store, const std::string& extra_config) {
  config_ =
      store.parent_path() / ("server-" + std::to_string(::getpid()) + "-" +
                             std::to_string(reinterpret_cast<std::uintptr_t>(this)) + ".json");
  std::ofstream(config_) << R"({"log_level": "warn", "access_log": false)"
                         << (extra_config.empty() ? "" : ", " + extra_config) << "}";
  child_ = std::make_unique<Child>(
      binary("tinstream-server"),
      std::vector<std::string>{"--config", config_.string(), "--store", store.string(), "--address",
                               "127.0.0.1", "--port", "0", "--threads", "2"});
  const std::string line = child_->read_line(std::chrono::seconds(60));
  // The server has read its configuration once it listens (or it has given up): the file goes,
  // so no run leaves one beside the store.
  std::error_code ignored;
  std::filesystem::remove(config_, ignored);
  const std::string prefix = "listening on 127.0.0.1:";
  if (line.rfind(prefix, 0) != 0)
    throw std::runtime_error("tinstream-server said: \"" + line + "\"");
  port_ = static_cast<std::uint16_t>(std::stoi(line.substr(prefix.size())));
}

ScriptedPeer::ScriptedPeer(Respond respond) : respond_(std::move(respond)) {
  listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(listen_fd_, 16) != 0)
    throw std::runtime_error("ScriptedPeer: bind/listen");
  socklen_t len = sizeof addr;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  thread_ = std::thread([this] { serve(); });
}

ScriptedPeer::~ScriptedPeer() {
  stop_.store(true);
  thread_.join();
  ::close(listen_fd_);
}

void ScriptedPeer::serve() {
  std::vector<int> clients;
  std::vector<std::string> buffers;
  while (!stop_.load()) {
    std::vector<pollfd> fds{{listen_fd_, POLLIN, 0}};
    for (int c : clients) fds.push_back({c, POLLIN, 0});
    if (::poll(fds.data(), static_cast<nfds_t>(fds.size()), 20) <= 0) continue;
    if (fds[0].revents & POLLIN) {
      const int c = ::accept(listen_fd_, nullptr, nullptr);
      if (c >= 0) {
        clients.push_back(c);
        buffers.emplace_back();
      }
    }
    for (std::size_t i = 1; i < fds.size(); ++i) {
      if (!(fds[i].revents & (POLLIN | POLLHUP))) continue;
      char buf[4096];
      const ssize_t got = ::read(fds[i].fd, buf, sizeof buf);
      if (got <= 0) continue;  // closed by the client: left until the end
      std::string& b = buffers[i - 1];
      b.append(buf, static_cast<std::size_t>(got));
      for (std::size_t end; (end = b.find("\r\n\r\n")) != std::string::npos;) {
        const std::string request = b.substr(0, end + 4);
        b.erase(0, end + 4);
        const std::string answer = respond_(requests_++, request);
        if (!answer.empty()) (void)!::write(fds[i].fd, answer.data(), answer.size());
      }
    }
  }
  for (int c : clients) ::close(c);
}

std::string http_response(int status, const std::string& body,
                          const std::vector<std::string>& headers) {
  std::string r = "HTTP/1.1 " + std::to_string(status) +
                  " X\r\nContent-Length: " + std::to_string(body.size()) + "\r\n";
  for (const std::string& h : headers) r += h + "\r\n";
  return r + "\r\n" + body;
}

std::string http_get(std::uint16_t port, const std::string& path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return {};
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(port);
  std::string response;
  const std::string request =
      "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
      ::write(fd, request.data(), request.size()) == static_cast<ssize_t>(request.size())) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          until - std::chrono::steady_clock::now());
      pollfd p{fd, POLLIN, 0};
      if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) {
        response.clear();  // timed out: no half answer
        break;
      }
      char buf[4096];
      const ssize_t got = ::read(fd, buf, sizeof buf);
      if (got <= 0) break;  // the server closed: the response is complete
      response.append(buf, static_cast<std::size_t>(got));
    }
  }
  ::close(fd);
  return response;
}

std::uint16_t closed_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  (void)::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ::close(fd);
  return ntohs(addr.sin_port);
}

}  // namespace tinstream::client::testing
