// The socket side of the server: Boost.Beast sessions over one io_context and N threads.
// All request logic is in handler.cpp; this file only moves bytes, enforces limits and timeouts,
// and shuts down gracefully.
//
// Session states (each on the session's strand; shared_from_this keeps it alive while an
// operation is pending):
//
//   read header ──▶ read body (string, or file for uploads) ──▶ handle() ──▶ write ──┐
//        ▲                                                                         │
//        └──────────────────────── keep-alive and not stopping ◀───────────────────┘
//   any error / Connection: close / stopping ──▶ lingering close (drain, bounded) ──▶ closed
#include "tinstream/server/server.hpp"

#include <spdlog/spdlog.h>

#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include "tinstream/server/handler.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::server {

namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;

class Session;

struct Server::Impl {
  ~Impl();
  explicit Impl(const ServerConfig& c)
      : serial(next_serial.fetch_add(1)),
        config(c),
        acceptor(net::make_strand(ioc)),
        signals(ioc, SIGINT, SIGTERM),
        grace(ioc) {}

  static inline std::atomic<std::uint64_t> next_serial{1};
  std::uint64_t serial;
  ServerConfig config;
  net::io_context ioc;
  tcp::acceptor acceptor;
  net::signal_set signals;
  net::steady_timer grace;
  Metrics metrics;
  std::unique_ptr<JobManager> jobs;
  std::unique_ptr<TerrainCache> cache;
  LayerCache layers{1000};
  Context ctx;
  std::atomic<bool> stopping{false};
  std::chrono::steady_clock::time_point stop_deadline;

  std::mutex sessions_mutex;  // guards sessions
  std::map<Session*, std::weak_ptr<Session>> sessions;

  void do_accept();
  void stop();
  void watch_drain();
};

namespace {

std::string random_hex(std::size_t n) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  static constexpr char kHex[] = "0123456789abcdef";
  std::string s;
  for (std::size_t i = 0; i < n; ++i) s.push_back(kHex[rng() % 16]);
  return s;
}

// Each io thread's own read-only store, opened on first use, keyed by the server's serial number
// (unique per process, unlike its address) and released when the thread leaves run().
std::map<std::uint64_t, std::unique_ptr<store::TileStore>>& thread_stores() {
  thread_local std::map<std::uint64_t, std::unique_ptr<store::TileStore>> stores;
  return stores;
}

Result<store::TileStore*> thread_store(std::uint64_t serial, const std::filesystem::path& path) {
  auto& slot = thread_stores()[serial];
  if (!slot) {
    auto opened = store::TileStore::open(path, store::TileStore::Mode::read_only);
    if (!opened) return opened.error();
    slot = std::make_unique<store::TileStore>(std::move(*opened));
  }
  return slot.get();
}

}  // namespace

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket&& socket, Server::Impl& server)
      : stream_(std::move(socket)), server_(server) {
    server_.metrics.connection_opened();
  }
  ~Session() {
    server_.metrics.connection_closed();
    if (!upload_path_.empty()) {
      std::error_code ec;
      std::filesystem::remove(upload_path_, ec);
    }
    std::lock_guard lock(server_.sessions_mutex);
    server_.sessions.erase(this);
  }

  void start() {
    {
      std::lock_guard lock(server_.sessions_mutex);
      server_.sessions[this] = weak_from_this();
    }
    net::dispatch(stream_.get_executor(),
                  beast::bind_front_handler(&Session::do_read, shared_from_this()));
  }

  void reject() {
    net::dispatch(stream_.get_executor(), [self = shared_from_this()] {
      self->start_ = std::chrono::steady_clock::now();
      self->req_ = Request{};
      self->req_.method = "-";
      self->req_.target = "-";
      self->send(json_error(503, "too many connections"), true);
    });
  }

  // Called (posted to the strand) when the server stops: idle connections close now, busy ones
  // after their response.
  void shutdown() {
    if (reading_header_ && idle()) close_now();
    // Otherwise a request is in flight (bytes received or being handled): it is answered with
    // `Connection: close`, bounded by the read/write timeouts and shutdown_grace_ms.
  }
  // Only when no thread runs the io_context (Server::Impl's destructor).
  void force_close() { close_now(); }
  void shutdown_posted() {
    net::post(stream_.get_executor(), [self = shared_from_this()] { self->shutdown(); });
  }

 private:
  const ServerConfig& cfg() const { return server_.config; }

  // No bytes of a next request received, neither buffered nor waiting in the socket.
  bool idle() {
    beast::error_code ec;
    return buffer_.size() == 0 && stream_.socket().available(ec) == 0;
  }

  void do_read() {
    if (server_.stopping && idle()) return close_now();
    header_parser_.emplace();
    header_parser_->header_limit(cfg().max_header_bytes);
    // Body limits depend on the route (uploads vs. the rest): checked once the header is known.
    header_parser_->body_limit(std::numeric_limits<std::uint64_t>::max());
    reading_header_ = true;
    stream_.expires_after(std::chrono::milliseconds(cfg().read_timeout_ms));
    http::async_read_header(stream_, buffer_, *header_parser_,
                            beast::bind_front_handler(&Session::on_header, shared_from_this()));
  }

  void on_header(beast::error_code ec, std::size_t) {
    reading_header_ = false;
    start_ = std::chrono::steady_clock::now();
    req_ = Request{};
    req_.method = "-";
    req_.target = "-";
    if (ec == http::error::end_of_stream || ec == net::error::eof || ec == beast::error::timeout ||
        ec == net::error::operation_aborted || ec == net::error::connection_reset ||
        ec == net::error::bad_descriptor) {
      return close_now();
    }
    if (ec == http::error::header_limit) {
      return send(json_error(431, "request header fields too large (max_header_bytes = " +
                                      std::to_string(cfg().max_header_bytes) + ")"),
                  true);
    }
    if (ec == http::error::body_limit) return send(json_error(413, "request body too large"), true);
    if (ec) return send(json_error(400, "malformed request: " + ec.message()), true);

    const auto& h = header_parser_->get();
    req_.method = std::string(h.method_string());
    req_.target = std::string(h.target());
    auto field = [&](http::field f) { return std::string(h[f]); };
    req_.accept = field(http::field::accept);
    req_.accept_encoding = field(http::field::accept_encoding);
    req_.if_none_match = field(http::field::if_none_match);
    req_.authorization = field(http::field::authorization);
    req_.content_type = field(http::field::content_type);
    keep_alive_ = h.keep_alive();
    version_ = h.version();
    const bool expect_continue = beast::iequals(h[http::field::expect], "100-continue");
    const auto length = header_parser_->content_length();

    if (is_upload(req_)) {
      if (auto denied = check_admin(req_, server_.ctx)) return send(std::move(*denied), true);
      if (cfg().upload_dir.empty()) {
        return send(json_error(403, "uploads are disabled (no upload_dir configured)"), true);
      }
      if (!length && !header_parser_->chunked()) {
        return send(json_error(411, "upload: Content-Length or chunked encoding required"), true);
      }
      if (length && *length > cfg().max_upload_bytes) {
        return send(json_error(413, "upload larger than max_upload_bytes = " +
                                        std::to_string(cfg().max_upload_bytes)),
                    true);
      }
      std::error_code fs_ec;
      std::filesystem::create_directories(cfg().upload_dir, fs_ec);
      upload_path_ = cfg().upload_dir / ("upload-" + random_hex(16));
      file_parser_.emplace(std::move(*header_parser_));
      file_parser_->body_limit(cfg().max_upload_bytes);
      beast::error_code open_ec;
      file_parser_->get().body().open(upload_path_.c_str(), beast::file_mode::write_new, open_ec);
      if (open_ec) {
        upload_path_.clear();
        return send(
            json_error(500, "upload: cannot create a file in upload_dir: " + open_ec.message()),
            true);
      }
      return continue_then(
          [self = shared_from_this()] {
            self->stream_.expires_after(std::chrono::milliseconds(self->cfg().read_timeout_ms));
            http::async_read(self->stream_, self->buffer_, *self->file_parser_,
                             beast::bind_front_handler(&Session::on_file_body, self));
          },
          expect_continue);
    }
    if (length && *length > cfg().max_body_bytes) {
      return send(json_error(413, "request body larger than max_body_bytes = " +
                                      std::to_string(cfg().max_body_bytes)),
                  true);
    }
    if (header_parser_->is_done()) {  // no body (GET and friends): answer right away
      header_parser_.reset();
      return respond();
    }
    string_parser_.emplace(std::move(*header_parser_));
    string_parser_->body_limit(cfg().max_body_bytes);
    continue_then(
        [self = shared_from_this()] {
          self->stream_.expires_after(std::chrono::milliseconds(self->cfg().read_timeout_ms));
          http::async_read(self->stream_, self->buffer_, *self->string_parser_,
                           beast::bind_front_handler(&Session::on_body, self));
        },
        expect_continue && !string_parser_->is_done());
  }

  template <typename Next>
  void continue_then(Next next, bool expect_continue) {
    if (!expect_continue) return next();
    static const std::string kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
    stream_.expires_after(std::chrono::milliseconds(cfg().write_timeout_ms));
    net::async_write(stream_, net::buffer(kContinue),
                     [self = shared_from_this(), next](beast::error_code ec, std::size_t) {
                       if (ec) return self->close_now();
                       next();
                     });
  }

  void on_body(beast::error_code ec, std::size_t) {
    if (ec == http::error::body_limit) {
      return send(json_error(413, "request body larger than max_body_bytes = " +
                                      std::to_string(cfg().max_body_bytes)),
                  true);
    }
    if (ec) return close_now();
    req_.body = string_parser_->release().body();
    string_parser_.reset();
    respond();
  }

  void on_file_body(beast::error_code ec, std::size_t) {
    if (ec == http::error::body_limit) {
      return send(json_error(413, "upload larger than max_upload_bytes = " +
                                      std::to_string(cfg().max_upload_bytes)),
                  true);
    }
    if (ec) return close_now();
    file_parser_->get().body().close();
    req_.body_file_size = file_parser_->get().body().size();
    file_parser_.reset();
    req_.body_file = std::move(upload_path_);  // handle() owns the file from here
    upload_path_.clear();
    respond();
  }

  void respond() {
    Response res = handle(req_, server_.ctx);
    send(std::move(res), !keep_alive_);
  }

  void send(Response res, bool close_after) {
    close_after_ = close_after || server_.stopping;
    route_ = res.route;
    status_ = res.status;
    const bool head = req_.method == "HEAD";
    const std::size_t full = res.payload().size();
    body_bytes_ = head ? 0 : full;
    if (res.shared_body && !head) {
      // Cached bytes: point the serializer at them; shared_body_ keeps them alive until written.
      auto msg = std::make_shared<http::response<http::buffer_body>>();
      shared_body_ = std::move(res.shared_body);
      msg->body().data = const_cast<char*>(shared_body_->data());
      msg->body().size = shared_body_->size();
      msg->body().more = false;
      return write(std::move(msg), res, full);
    }
    auto msg = std::make_shared<http::response<http::string_body>>();
    if (!head) msg->body() = std::move(res.body);
    write(std::move(msg), res, full);
  }

  template <typename Message>
  void write(std::shared_ptr<Message> msg, const Response& res, std::size_t content_length) {
    msg->version(version_);
    msg->result(static_cast<unsigned>(res.status));
    msg->set(http::field::server, "tinstream");
    for (const auto& [k, v] : res.headers) msg->set(k, v);
    msg->keep_alive(!close_after_);
    if (res.status != 304 && res.status != 204) msg->content_length(content_length);
    response_ = msg;
    stream_.expires_after(std::chrono::milliseconds(cfg().write_timeout_ms));
    http::async_write(stream_, *msg,
                      beast::bind_front_handler(&Session::on_write, shared_from_this()));
  }

  void on_write(beast::error_code ec, std::size_t) {
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(
                        std::chrono::steady_clock::now() - start_)
                        .count();
    server_.metrics.record(route_, status_, ec ? 0 : body_bytes_, static_cast<double>(us) / 1e6);
    if (cfg().access_log) {
      spdlog::info("{} {} {} {} {}us{}", req_.method, req_.target, status_, body_bytes_, us,
                   ec ? " (write failed: " + ec.message() + ")" : std::string());
    }
    response_.reset();
    shared_body_.reset();
    if (ec) return close_now();
    if (close_after_ || server_.stopping) return lingering_close();
    do_read();
  }

  // Half-close, then drain what the client still sends (bounded in bytes and time) so that it
  // reads our response instead of a connection reset.
  void lingering_close() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
    drained_ = 0;
    drain();
  }

  void drain() {
    stream_.expires_after(
        std::chrono::milliseconds(std::min<std::uint32_t>(cfg().read_timeout_ms, 2000)));
    stream_.async_read_some(net::buffer(drain_buffer_),
                            [self = shared_from_this()](beast::error_code ec, std::size_t n) {
                              self->drained_ += n;
                              if (ec || self->drained_ > (4u << 20)) return self->close_now();
                              self->drain();
                            });
  }

  void close_now() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ec);
    stream_.socket().close(ec);
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  Server::Impl& server_;
  std::optional<http::request_parser<http::empty_body>> header_parser_;
  std::optional<http::request_parser<http::string_body>> string_parser_;
  std::optional<http::request_parser<http::file_body>> file_parser_;
  std::shared_ptr<void> response_;
  std::shared_ptr<const std::string> shared_body_;  // bytes a buffer_body response points into
  std::filesystem::path upload_path_;  // removed by the destructor unless handed to handle()
  Request req_;
  std::chrono::steady_clock::time_point start_;
  std::string route_ = "other";
  int status_ = 0;
  std::size_t body_bytes_ = 0;
  unsigned version_ = 11;
  bool keep_alive_ = false;
  bool close_after_ = false;
  bool reading_header_ = false;
  std::size_t drained_ = 0;
  std::array<char, 8192> drain_buffer_{};
};

Server::Impl::~Impl() {
  // Handlers still pending after a forced stop (grace period over) own sessions that refer to
  // this object: close their sockets and let those handlers finish before any member goes away.
  beast::error_code ec;
  acceptor.close(ec);
  signals.cancel(ec);
  grace.cancel();
  std::vector<std::shared_ptr<Session>> live;
  {
    std::lock_guard lock(sessions_mutex);
    for (auto& [ptr, weak] : sessions) {
      if (auto s = weak.lock()) live.push_back(std::move(s));
    }
  }
  for (auto& s : live) s->force_close();
  live.clear();
  ioc.restart();
  ioc.run_for(std::chrono::seconds(5));
}

void Server::Impl::do_accept() {
  acceptor.async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (!acceptor.is_open() || stopping) return;
      spdlog::warn("accept failed: {}", ec.message());
    } else {
      beast::error_code nd;
      socket.set_option(tcp::no_delay(true), nd);  // responses go out in one write; no Nagle wait
      auto session = std::make_shared<Session>(std::move(socket), *this);
      if (metrics.open_connections() > static_cast<std::int64_t>(config.max_connections)) {
        metrics.connection_rejected();
        session->reject();
      } else {
        session->start();
      }
    }
    if (!stopping) do_accept();
  });
}

void Server::Impl::stop() {
  if (stopping.exchange(true)) return;
  spdlog::info("shutting down: finishing in-flight requests (grace {} ms)",
               config.shutdown_grace_ms);
  stop_deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(config.shutdown_grace_ms);
  net::post(acceptor.get_executor(), [this] {
    beast::error_code ec;
    acceptor.close(ec);
  });
  signals.cancel();
  std::vector<std::shared_ptr<Session>> live;
  {
    std::lock_guard lock(sessions_mutex);
    for (auto& [ptr, weak] : sessions) {
      if (auto s = weak.lock()) live.push_back(std::move(s));
    }
  }
  for (auto& s : live) s->shutdown_posted();
  net::post(ioc, [this] { watch_drain(); });
}

void Server::Impl::watch_drain() {
  bool empty;
  {
    std::lock_guard lock(sessions_mutex);
    empty = sessions.empty();
  }
  if (empty) return;  // nothing left: run() returns once the handlers finish
  if (std::chrono::steady_clock::now() >= stop_deadline) {
    spdlog::warn("shutdown grace period over; closing remaining connections");
    ioc.stop();
    return;
  }
  grace.expires_after(std::chrono::milliseconds(20));
  grace.async_wait([this](beast::error_code) { watch_drain(); });
}

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() {
  stop();
  if (impl_->jobs) impl_->jobs->shutdown();
}

Result<std::unique_ptr<Server>> Server::create(const ServerConfig& config, IngestRunner runner) {
  // Create the store file and schema when absent, so the server can start empty and be filled
  // through the admin API.
  {
    auto rw = store::TileStore::open(config.store, store::TileStore::Mode::read_write);
    if (!rw)
      return Error(rw.error().code, "store " + config.store.string() + ": " + rw.error().message);
  }
  auto impl = std::make_unique<Impl>(config);
  Impl* raw = impl.get();
  // A finished job may have published or replaced a layer: forget cached layer rows.
  IngestRunner wrapped = [runner = std::move(runner), raw](const IngestJobSpec& job,
                                                           const ProgressSink& progress) {
    Status s =
        runner ? runner(job, progress) : Status(Error(ErrorCode::unsupported, "no ingest runner"));
    raw->layers.clear();
    return s;
  };
  impl->jobs = std::make_unique<JobManager>(std::move(wrapped), config.max_queued_jobs);
  if (config.terrain_cache_bytes > 0)
    impl->cache = std::make_unique<TerrainCache>(config.terrain_cache_bytes);
  impl->ctx.config = config;
  impl->ctx.admin_token = resolve_admin_token(config);
  impl->ctx.metrics = &impl->metrics;
  impl->ctx.jobs = impl->jobs.get();
  impl->ctx.terrain_cache = impl->cache.get();
  impl->ctx.layer_cache = &impl->layers;
  impl->ctx.store = [raw] { return thread_store(raw->serial, raw->config.store); };

  beast::error_code ec;
  const auto address = net::ip::make_address(config.address, ec);
  if (ec) return invalid_argument("address \"" + config.address + "\": " + ec.message());
  const tcp::endpoint endpoint{address, config.port};
  impl->acceptor.open(endpoint.protocol(), ec);
  if (!ec) impl->acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) impl->acceptor.bind(endpoint, ec);
  if (!ec) impl->acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) {
    return io_error("cannot listen on " + config.address + ":" + std::to_string(config.port) +
                    ": " + ec.message());
  }
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

std::uint16_t Server::port() const {
  beast::error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

void Server::run(bool handle_signals) {
  Impl& s = *impl_;
  if (handle_signals) {
    s.signals.async_wait([&s](beast::error_code ec, int signo) {
      if (ec) return;
      spdlog::info("signal {} received", signo);
      s.stop();
    });
  }
  if (!s.stopping) s.do_accept();
  const unsigned n =
      s.config.threads > 0 ? s.config.threads : std::max(1u, std::thread::hardware_concurrency());
  spdlog::info("tinstream-server listening on {}:{} with {} threads, store {}", s.config.address,
               port(), n, s.config.store.string());
  std::vector<std::thread> threads;
  auto serve = [&s] {
    s.ioc.run();
    thread_stores().erase(s.serial);
  };
  for (unsigned i = 1; i < n; ++i) threads.emplace_back(serve);
  serve();
  for (auto& t : threads) t.join();
  s.jobs->shutdown();
  spdlog::info("tinstream-server stopped");
}

void Server::stop() { impl_->stop(); }

}  // namespace tinstream::server
