// The server as a tile source: Boost.Beast HTTP/1.1 over one keep-alive connection per worker.
// This is the only translation unit of the client that includes Beast/Asio (compile time).
//
// Each connection owns an io_context that only its worker thread runs: an exchange starts the
// asynchronous connect/write/read with a deadline (tcp_stream::expires_after) and runs the
// context in short slices until it completes, so a request can neither hang past its timeout
// nor outlive a cancellation (the slices check the cancel flag and cancel the socket).
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/version.hpp>
#include <chrono>
#include <cmath>
#include <random>
#include <thread>
#include <utility>

#include "tinstream/client/imagery.hpp"
#include "tinstream/client/tile_source.hpp"

namespace tinstream::client {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

namespace {

struct Url {
  std::string host, port, prefix;
  std::string text() const { return "http://" + host + ":" + port + prefix; }
};

Result<Url> parse_url(std::string_view url) {
  constexpr std::string_view kScheme = "http://";
  if (url.substr(0, kScheme.size()) != kScheme)
    return invalid_argument("URL \"" + std::string(url) +
                            "\": only http://HOST[:PORT] is supported");
  std::string_view rest = url.substr(kScheme.size());
  const std::size_t slash = rest.find('/');
  std::string_view authority = rest.substr(0, slash);
  std::string prefix(slash == std::string_view::npos ? std::string_view{} : rest.substr(slash));
  while (!prefix.empty() && prefix.back() == '/') prefix.pop_back();
  Url u;
  u.prefix = prefix;
  if (!authority.empty() && authority.front() == '[') {  // [IPv6]:port
    const std::size_t close = authority.find(']');
    if (close == std::string_view::npos) return invalid_argument("URL: unclosed '[' in the host");
    u.host = std::string(authority.substr(1, close - 1));
    authority.remove_prefix(close + 1);
    if (!authority.empty() && authority.front() != ':')
      return invalid_argument("URL: junk after ']'");
    u.port = authority.empty() ? "80" : std::string(authority.substr(1));
  } else {
    const std::size_t colon = authority.rfind(':');
    u.host = std::string(authority.substr(0, colon));
    u.port = colon == std::string_view::npos ? "80" : std::string(authority.substr(colon + 1));
  }
  if (u.host.empty()) return invalid_argument("URL \"" + std::string(url) + "\" has no host");
  if (u.port.empty() || u.port.size() > 5 ||
      u.port.find_first_not_of("0123456789") != std::string::npos || std::stoi(u.port) == 0 ||
      std::stoi(u.port) > 65535)
    return invalid_argument("URL \"" + std::string(url) + "\": bad port \"" + u.port + "\"");
  return u;
}

// One answer as far as the callers care.
struct Answer {
  unsigned status = 0;
  std::vector<std::uint8_t> body;
  std::string etag, content_encoding;
  bool keep_alive = true;
  std::uint64_t wire_bytes = 0;
  std::chrono::steady_clock::time_point headers_at{};
};

enum class Transport { ok, failed, stale };  // stale: a reused connection the peer had closed

class Client {
 public:
  Client(Url url, HttpOptions options)
      : url_(std::move(url)), options_(options), rng_(std::random_device{}()) {}

  // One request/answer on the connection (opening it first when needed).
  Transport exchange(const std::string& target, const std::optional<std::string>& if_none_match,
                     const char* accept_encoding, const std::atomic<bool>& cancel, Answer& out,
                     std::string& error, std::uint32_t& reconnects) {
    const bool reused = open_;
    if (!open_) {
      if (!connect(cancel, error)) return Transport::failed;
      ++reconnects;
    }
    http::request<http::empty_body> req{http::verb::get, target, 11};
    req.set(http::field::host, url_.host);
    req.set(http::field::user_agent, "tinstream-viewer/0.1");
    req.set(http::field::accept_encoding, accept_encoding);
    if (if_none_match) req.set(http::field::if_none_match, *if_none_match);
    req.keep_alive(true);

    http::response_parser<http::vector_body<std::uint8_t>> parser;
    parser.body_limit(options_.max_body_bytes);
    parser.header_limit(64 * 1024);
    beast::error_code ec;
    bool done = false;
    std::size_t read_bytes = 0;
    stream_.expires_after(std::chrono::milliseconds(options_.request_timeout_ms));
    http::async_write(stream_, req, [&](beast::error_code e, std::size_t) {
      if (e) {
        ec = e;
        done = true;
        return;
      }
      // Headers first, then the body: the time between them is the transfer (timeline.hpp).
      http::async_read_header(stream_, buffer_, parser, [&](beast::error_code e2, std::size_t n) {
        read_bytes = n;
        if (e2) {
          ec = e2;
          done = true;
          return;
        }
        out.headers_at = std::chrono::steady_clock::now();
        http::async_read(stream_, buffer_, parser, [&](beast::error_code e3, std::size_t m) {
          ec = e3;
          read_bytes += m;
          done = true;
        });
      });
    });
    run_until(done, cancel);
    out.wire_bytes += read_bytes;
    if (ec) {
      close();
      const bool nothing_read = read_bytes == 0 && !parser.got_some();
      if (reused && nothing_read &&
          (ec == http::error::end_of_stream || ec == asio::error::eof ||
           ec == asio::error::connection_reset || ec == asio::error::broken_pipe))
        return Transport::stale;
      error = ec == beast::error::timeout
                  ? "timed out after " + std::to_string(options_.request_timeout_ms) + " ms"
                  : ec.message();
      if (cancel.load()) error = "cancelled";
      return Transport::failed;
    }
    auto res = parser.release();
    out.status = res.result_int();
    out.etag = std::string(res[http::field::etag]);
    out.content_encoding = std::string(res[http::field::content_encoding]);
    out.keep_alive = res.keep_alive();
    out.body = std::move(res.body());
    if (!out.keep_alive) close();
    return Transport::ok;
  }

  // Sleeps `ms` in slices, returning early (false) when cancelled.
  bool backoff(int attempt, const std::atomic<bool>& cancel) {
    const double base = options_.backoff_ms * std::pow(2.0, attempt - 2);
    std::uniform_real_distribution<double> jitter(0.75, 1.25);
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::microseconds(static_cast<long>(base * jitter(rng_) * 1000));
    while (std::chrono::steady_clock::now() < until) {
      if (cancel.load()) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return !cancel.load();
  }

  const HttpOptions& options() const { return options_; }
  const Url& url() const { return url_; }

 private:
  bool connect(const std::atomic<bool>& cancel, std::string& error) {
    beast::error_code ec;
    bool done = false;
    tcp::resolver::results_type endpoints;
    resolver_.async_resolve(url_.host, url_.port,
                            [&](beast::error_code e, tcp::resolver::results_type r) {
                              ec = e;
                              endpoints = std::move(r);
                              done = true;
                            });
    run_until(done, cancel, &resolver_);
    if (ec) {
      error = "cannot resolve " + url_.host + ": " + ec.message();
      return false;
    }
    done = false;
    stream_.expires_after(std::chrono::milliseconds(options_.connect_timeout_ms));
    stream_.async_connect(endpoints, [&](beast::error_code e, const tcp::endpoint&) {
      ec = e;
      done = true;
    });
    run_until(done, cancel);
    if (ec) {
      error = "cannot connect to " + url_.host + ":" + url_.port + ": " +
              (ec == beast::error::timeout ? std::string("timed out") : ec.message());
      close();
      return false;
    }
    stream_.socket().set_option(tcp::no_delay(true), ec);
    buffer_.clear();
    open_ = true;
    return true;
  }

  void close() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
    stream_.close();
    buffer_.clear();
    open_ = false;
  }

  // Runs the context until `done`; on cancellation cancels the pending operations (their
  // handlers then complete with operation_aborted, setting `done`).
  void run_until(bool& done, const std::atomic<bool>& cancel, tcp::resolver* resolver = nullptr) {
    ioc_.restart();
    bool cancelled = false;
    while (!done) {
      ioc_.run_one_for(std::chrono::milliseconds(20));
      if (!done && !cancelled && cancel.load()) {
        cancelled = true;
        if (resolver) resolver->cancel();
        stream_.cancel();
      }
    }
  }

  Url url_;
  HttpOptions options_;
  asio::io_context ioc_;
  tcp::resolver resolver_{ioc_};
  beast::tcp_stream stream_{ioc_};
  beast::flat_buffer buffer_;
  bool open_ = false;
  std::mt19937 rng_;
};

ContentEncoding parse_encoding(const std::string& value, bool& known) {
  known = true;
  if (value.empty() || value == "identity") return ContentEncoding::identity;
  if (value == "deflate") return ContentEncoding::deflate;
  if (value == "gzip" || value == "x-gzip") return ContentEncoding::gzip;
  known = false;
  return ContentEncoding::identity;
}

std::string quadkey_path(const TileKey& key, const std::string& layer) {
  return (key.kind == TileKind::imagery ? "/imagery/" : "/tiles/") + layer + "/" +
         key.tile.quadkey();
}

class HttpConnectionImpl final : public TileConnection {
 public:
  HttpConnectionImpl(Url url, HttpOptions options) : client_(std::move(url), options) {}

  FetchResponse fetch(const FetchRequest& request, const std::atomic<bool>& cancel) override {
    FetchResponse r;
    const std::string target =
        client_.url().prefix + quadkey_path(request.key, request.layer->name);
    const std::string what = "GET " + target;
    std::string error;
    const int max_attempts = std::max(client_.options().max_attempts, 1);
    for (int attempt = 1; attempt <= max_attempts; ++attempt) {
      if (attempt > 1 && !client_.backoff(attempt, cancel)) {
        error = "cancelled";
        break;
      }
      Answer a;
      Transport t = Transport::stale;
      for (int stale = 0; t == Transport::stale && stale < 2; ++stale) {
        ++r.attempts;
        t = client_.exchange(target, request.if_none_match, "deflate, gzip", cancel, a, error,
                             r.reconnects);
      }
      r.wire_bytes += a.wire_bytes;
      r.headers_at = a.headers_at;
      if (cancel.load()) {
        error = "cancelled";
        break;
      }
      if (t != Transport::ok) continue;  // connection error or timeout: retry
      if (a.status == 200) {
        bool known = false;
        r.encoding = parse_encoding(a.content_encoding, known);
        if (!known) {
          error = "unknown Content-Encoding \"" + a.content_encoding + "\"";
          break;
        }
        r.status = FetchResponse::Status::ok;
        r.body = std::move(a.body);
        r.etag = std::move(a.etag);
        return r;
      }
      if (a.status == 304) {
        r.status = FetchResponse::Status::not_modified;
        r.etag = std::move(a.etag);
        return r;
      }
      if (a.status == 404) {
        r.status = FetchResponse::Status::not_found;
        return r;
      }
      error = "HTTP " + std::to_string(a.status);
      if (a.status < 500) break;  // other 4xx: asking again will not help
    }
    r.status = FetchResponse::Status::failed;
    r.error = Error(error == "cancelled" ? ErrorCode::cancelled : ErrorCode::io_error,
                    what + " (" + client_.url().text() + "): " + error + " after " +
                        std::to_string(r.attempts) + " attempt(s)");
    return r;
  }

 private:
  Client client_;
};

class HttpSource final : public TileSource {
 public:
  HttpSource(Url url, HttpOptions options) : url_(std::move(url)), options_(options) {}

  std::string describe() const override { return url_.text(); }
  bool remote() const override { return true; }

  Result<std::vector<LayerDescription>> layers(const std::vector<std::string>& names) override {
    Client client(url_, options_);
    std::vector<LayerDescription> out;
    if (names.empty()) {
      auto text = get(client, url_.prefix + "/layers");
      if (!text) return text.error();
      return parse_layers_json(*text);
    }
    for (const std::string& name : names) {
      auto text = get(client, url_.prefix + "/layers/" + name);
      if (!text) return text.error();
      auto layer = parse_layer_json(*text);
      if (!layer) return layer.error();
      out.push_back(std::move(*layer));
    }
    return out;
  }

  Result<std::unique_ptr<TileConnection>> connect() override {
    return std::unique_ptr<TileConnection>(std::make_unique<HttpConnectionImpl>(url_, options_));
  }

 private:
  // A metadata document (JSON), with the same retries as tiles.
  Result<LayerDescription> imagery_layer(const std::string& name) override {
    Client client(url_, options_);
    auto text = get(client, url_.prefix + "/layers");
    if (!text) return text.error();
    auto layer = parse_imagery_json(*text, name);
    if (!layer) return Error(layer.error().code, url_.text() + ": " + layer.error().message);
    return layer;
  }

  Result<std::string> get(Client& client, const std::string& target) {
    const std::atomic<bool> never{false};
    std::string error;
    std::uint32_t reconnects = 0;
    for (int attempt = 1; attempt <= std::max(options_.max_attempts, 1); ++attempt) {
      if (attempt > 1) client.backoff(attempt, never);
      Answer a;
      Transport t = Transport::stale;
      for (int stale = 0; t == Transport::stale && stale < 2; ++stale)
        t = client.exchange(target, std::nullopt, "identity", never, a, error, reconnects);
      if (t != Transport::ok) continue;
      std::string body(a.body.begin(), a.body.end());
      if (a.status == 200) return body;
      if (a.status == 404)
        return not_found(
            std::string("GET ").append(url_.text()).append(target).append(": 404 ").append(body));
      error = "HTTP " + std::to_string(a.status) + " " + body.substr(0, 200);
      if (a.status < 500) break;
    }
    return io_error("GET " + url_.text() + target + ": " + error);
  }

  Url url_;
  HttpOptions options_;
};

}  // namespace

Result<std::shared_ptr<TileSource>> open_http_source(std::string_view url,
                                                     const HttpOptions& options) {
  auto u = parse_url(url);
  if (!u) return u.error();
  return std::shared_ptr<TileSource>(std::make_shared<HttpSource>(std::move(*u), options));
}

}  // namespace tinstream::client
