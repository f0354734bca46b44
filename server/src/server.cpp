// The socket side of the server: Boost.Beast request parsing over N shards, one io_context and one
// thread each. All request logic is in handler.cpp; this file only moves bytes, enforces limits
// and timeouts, and shuts down gracefully.
//
//   acceptor (shard 0) ──round robin──▶ shard k: io_context k, run by thread k
//                                        └─ its sessions, its timeout sweep, its TileStore
//
// A session lives on one shard from accept to close: no strands, no lock and no thread hand-off
// per request (the acceptor hands each connection over once). Timeouts are deadlines that the
// shard's sweep timer checks every `sweep` interval (no timer operation per read or write).
//
// Session states (each handler on the session's shard; shared_from_this keeps it alive while an
// operation is pending):
//
//   read header ──▶ read body (string, or file for uploads) ──▶ handle() ──▶ write ──┐
//        ▲                                                                         │
//        └──────────────────────── keep-alive and not stopping ◀───────────────────┘
//   any error / timeout / Connection: close / stopping ──▶ lingering close (drain, bounded) ──▶
//   closed
//
// Requests are read by the session's own loop (read_some into a buffer the session keeps, Beast's
// basic_parser over it, the handler's fields stored straight into the Request), not Beast's
// composed read operations and field containers: no allocation per request field, and a
// pipelined burst is parsed from one read. A response goes out as one gather write: the header
// block (formatted into a buffer the session reuses, or prebuilt by the handler for cached tiles)
// and the body bytes (cached tiles: shared, not copied), offered whole to each writev.
#include "tinstream/server/server.hpp"

#include <spdlog/spdlog.h>
#include <sys/sendfile.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <cassert>
#include <charconv>
#include <chrono>
#include <csignal>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <thread>
#include <unordered_set>

#include "body_file.hpp"
#include "tinstream/server/handler.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::server {

namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

class Session;

// One io_context, run by one thread, and the sessions on it.
struct Shard {
  Shard(std::chrono::milliseconds sweep_every, std::uint64_t body_file_bytes)
      : ioc(1),
        work(net::make_work_guard(ioc)),
        sweep(ioc),
        every(sweep_every),
        bodies(body_file_bytes) {}

  // Touched only by the shard's own thread (or, once no thread runs the shard, by the thread
  // destroying the server). Declared before ioc: it outlives the handlers ioc destroys.
  std::unordered_set<Session*> sessions;
  net::io_context ioc;
  // Keeps run() going while the shard has no session; dropped by stop().
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work;
  net::steady_timer sweep;  // checks the sessions' deadlines, collects unused bodies
  std::chrono::milliseconds every;
  BodyFile bodies;  // cached bodies this shard's sessions send with sendfile
};

struct Server::Impl {
  ~Impl();
  Impl(const ServerConfig& c, unsigned n_shards)
      : serial(next_serial.fetch_add(1)),
        config(c),
        shards(make_shards(c, n_shards)),
        acceptor(shards.front()->ioc),
        signals(shards.front()->ioc, SIGINT, SIGTERM),
        grace(shards.front()->ioc) {}

  static std::vector<std::unique_ptr<Shard>> make_shards(const ServerConfig& c, unsigned n) {
    // Timeouts fire up to one sweep interval late: an eighth of the shortest one, 5-250 ms.
    const auto every = std::chrono::milliseconds(
        std::clamp<std::uint32_t>(std::min(c.read_timeout_ms, c.write_timeout_ms) / 8, 5, 250));
    std::vector<std::unique_ptr<Shard>> out;
    // Room for the whole terrain cache plus the bodies still in flight after their eviction.
    const std::uint64_t body_file = 2 * c.terrain_cache_bytes + (64u << 20);
    for (unsigned i = 0; i < std::max(1u, n); ++i)
      out.push_back(std::make_unique<Shard>(every, body_file));
    return out;
  }

  static inline std::atomic<std::uint64_t> next_serial{1};
  std::uint64_t serial;
  ServerConfig config;
  Metrics metrics;
  std::unique_ptr<JobManager> jobs;
  std::unique_ptr<TerrainCache> cache;
  LayerCache layers{1000};
  Context ctx;
  std::atomic<bool> stopping{false};
  std::atomic<std::int64_t> live_sessions{0};
  Clock::time_point stop_deadline;
  std::vector<std::unique_ptr<Shard>> shards;  // at least one; shard 0 also runs what follows
  tcp::acceptor acceptor;
  net::signal_set signals;
  net::steady_timer grace;
  std::size_t next_shard = 0;  // round robin; the accept handler only

  void do_accept();
  void sweep(Shard& shard);
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

std::string_view view(beast::string_view s) { return {s.data(), s.size()}; }

// Completion condition of a response write: offer the kernel everything left in each call.
// (Asio's transfer_all caps every writev at 64 KiB, which splits most terrain tiles in two
// system calls and two pushes of TCP segments.)
std::size_t whole_buffers(const beast::error_code& ec, std::size_t) {
  return ec ? 0 : std::numeric_limits<std::size_t>::max();
}

void append_number(std::string& out, std::uint64_t v) {
  std::array<char, 24> digits{};
  auto [end, ec] = std::to_chars(digits.data(), digits.data() + digits.size(), v);
  out.append(digits.data(), end);
}

// Bytes asked of the socket per read when the buffer has less room: a few requests' worth.
constexpr std::size_t kReadSize = 4096;

// Beast's HTTP/1 request grammar and limits (header_limit, body_limit, chunked decoding), with
// the fields the handler reads stored straight into the session's Request: no field container
// and no allocation per field. The body goes to Request::body, or to the upload file once
// write_body_to() has named one. Repeated fields: the first one counts.
class RequestParser final : public http::basic_parser<true> {
 public:
  explicit RequestParser(Request& request) : req_(request) {}

  unsigned version() const { return version_; }
  bool expect_continue() const { return expect_continue_; }
  unsigned host_fields() const { return hosts_; }
  std::uint64_t body_bytes() const { return body_bytes_; }
  void write_body_to(beast::file& file) { file_ = &file; }

 private:
  void on_request_impl(http::verb, beast::string_view method, beast::string_view target,
                       int version, beast::error_code&) override {
    req_.method.assign(method.data(), method.size());
    req_.target.assign(target.data(), target.size());
    version_ = static_cast<unsigned>(version);
  }
  void on_response_impl(int, beast::string_view, int, beast::error_code&) override {}

  void on_field_impl(http::field name, beast::string_view, beast::string_view value,
                     beast::error_code&) override {
    const auto first = [&](std::string& out, unsigned bit) {
      if (seen_ & bit) return;
      seen_ |= bit;
      out.assign(value.data(), value.size());
    };
    switch (name) {
      case http::field::accept:
        return first(req_.accept, 1u);
      case http::field::accept_encoding:
        return first(req_.accept_encoding, 2u);
      case http::field::if_none_match:
        return first(req_.if_none_match, 4u);
      case http::field::authorization:
        return first(req_.authorization, 8u);
      case http::field::content_type:
        return first(req_.content_type, 16u);
      case http::field::host:
        ++hosts_;
        return;
      case http::field::expect:
        if (seen_ & 32u) return;
        seen_ |= 32u;
        expect_continue_ = beast::iequals(value, "100-continue");
        return;
      default:
        return;
    }
  }
  void on_header_impl(beast::error_code&) override {}

  void on_body_init_impl(const boost::optional<std::uint64_t>& length,
                         beast::error_code&) override {
    if (!file_ && length) req_.body.reserve(static_cast<std::size_t>(*length));
  }
  std::size_t on_body_impl(beast::string_view body, beast::error_code& ec) override {
    if (file_) {
      file_->write(body.data(), body.size(), ec);
    } else {
      req_.body.append(body.data(), body.size());
    }
    body_bytes_ += body.size();
    return body.size();
  }
  void on_chunk_header_impl(std::uint64_t, beast::string_view, beast::error_code&) override {}
  std::size_t on_chunk_body_impl(std::uint64_t, beast::string_view body,
                                 beast::error_code& ec) override {
    return on_body_impl(body, ec);
  }
  void on_finish_impl(beast::error_code&) override {}

  Request& req_;
  beast::file* file_ = nullptr;
  std::uint64_t body_bytes_ = 0;
  unsigned version_ = 11;
  unsigned seen_ = 0;   // bits of the fields already stored
  unsigned hosts_ = 0;  // Host field lines
  bool expect_continue_ = false;
};

}  // namespace

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket&& socket, Server::Impl& server, Shard& shard)
      : socket_(std::move(socket)), server_(server), shard_(shard) {
    server_.metrics.connection_opened();
    server_.live_sessions.fetch_add(1);
  }
  ~Session() {
    shard_.sessions.erase(this);
    server_.metrics.connection_closed();
    if (!upload_path_.empty()) {
      std::error_code ec;
      std::filesystem::remove(upload_path_, ec);
    }
    server_.live_sessions.fetch_sub(1);
  }

  // On the shard's thread. `reject`: answer 503 and close (over max_connections).
  void start(bool reject) {
    shard_.sessions.insert(this);
    beast::error_code ec;
    socket_.native_non_blocking(true, ec);  // send_file() calls send/sendfile itself
    if (!reject) return do_read();
    start_ = Clock::now();
    reset_request();
    send(json_error(503, "too many connections"), true);
  }

  // On the shard's thread, when the server stops: idle connections close now, busy ones after
  // their response (bounded by the timeouts and shutdown_grace_ms), with `Connection: close`.
  // The wait for a next request is cancelled, not closed: the reactor may already have read the
  // first bytes of one (neither in buffer_ nor in the socket yet), and on_header still gets them.
  void shutdown() {
    if (!reading_header_ || !idle()) return;
    beast::error_code ec;
    socket_.cancel(ec);
  }

  // On the shard's thread: closes the connection when its current read or write is overdue.
  void check_deadline(Clock::time_point now) {
    if (now >= deadline_) {
      deadline_ = Clock::time_point::max();
      close_now();
    }
  }

  void close_now() {
    beast::error_code ec;
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
  }

 private:
  const ServerConfig& cfg() const { return server_.config; }

  void expires_after(std::uint32_t ms, Clock::time_point now = Clock::now()) {
    deadline_ = now + std::chrono::milliseconds(ms);
  }

  // No bytes of a next request received, neither buffered nor waiting in the socket.
  bool idle() {
    beast::error_code ec;
    return buffer_.size() == 0 && socket_.available(ec) == 0;
  }

  // The request fields are reused from one request to the next (their capacity with them).
  void reset_request() {
    req_.method.assign("-");
    req_.target.assign("-");
    req_.accept.clear();
    req_.accept_encoding.clear();
    req_.if_none_match.clear();
    req_.authorization.clear();
    req_.content_type.clear();
    req_.body.clear();
    req_.body_file.clear();
    req_.body_file_size = 0;
  }

  // Waits for the next request: its header within read_timeout_ms of now, however it trickles in.
  void do_read(Clock::time_point now = Clock::now()) {
    if (server_.stopping && idle()) return close_now();
    reset_request();
    parser_.emplace(req_);
    parser_->header_limit(cfg().max_header_bytes);
    // Body limits depend on the route (uploads vs. the rest): set once the header is known.
    parser_->body_limit(std::numeric_limits<std::uint64_t>::max());
    reading_header_ = true;
    expires_after(cfg().read_timeout_ms, now);
    parse();
  }

  // Feeds the buffered bytes to the parser until the header (or, after it, the body) is
  // complete, reading more while it needs them; then on_header or on_body. A pipelined next
  // request stays in buffer_.
  void parse() {
    beast::error_code ec;
    const auto complete = [this] {
      return reading_header_ ? parser_->is_header_done() : parser_->is_done();
    };
    while (buffer_.size() > 0 && !complete()) {
      buffer_.consume(parser_->put(buffer_.data(), ec));
      if (ec == http::error::need_more) {
        ec = {};
        break;
      }
      if (ec) break;
    }
    if (!ec && !complete()) return read_more();
    parsed(ec);
  }

  void parsed(beast::error_code ec) { reading_header_ ? on_header(ec) : on_body(ec); }

  void read_more() {
    // At least a few requests' worth per read: a pipelined burst costs one system call.
    const std::size_t size = std::max<std::size_t>(kReadSize, buffer_.capacity() - buffer_.size());
    socket_.async_read_some(
        buffer_.prepare(size),
        [self = shared_from_this()](beast::error_code ec, std::size_t n) { self->on_read(ec, n); });
  }

  void on_read(beast::error_code ec, std::size_t n) {
    buffer_.commit(n);
    if (ec == net::error::eof) {
      if (!parser_->got_some()) return parsed(http::error::end_of_stream);
      ec = {};
      parser_->put_eof(ec);  // a message cut short: partial_message
      return parsed(ec);
    }
    if (ec) return parsed(ec);
    parse();
  }

  void on_header(beast::error_code ec) {
    reading_header_ = false;
    start_ = Clock::now();
    // Cancelled by shutdown(): do_read() closes the connection unless a request arrived since.
    if (ec == net::error::operation_aborted && server_.stopping) return do_read();
    if (ec) reset_request();  // the answer to a broken request names no method or target
    if (ec == http::error::end_of_stream || ec == net::error::eof ||
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
    // RFC 9112 §3.2: an HTTP/1.1 request without Host, or any with more than one, is a 400.
    if (parser_->host_fields() > 1) {
      return send(json_error(400, "malformed request: more than one Host header"), true);
    }
    if (parser_->host_fields() == 0 && parser_->version() >= 11) {
      return send(json_error(400, "malformed request: HTTP/1.1 without a Host header"), true);
    }

    keep_alive_ = parser_->keep_alive();
    version_ = parser_->version();
    const bool expect_continue = parser_->expect_continue();
    const auto length = parser_->content_length();
    // Reads the body (on_body once complete), after a 100 Continue when the client asked for it.
    const auto read_body = [self = shared_from_this()] {
      self->expires_after(self->cfg().read_timeout_ms);
      self->parse();
    };

    if (is_upload(req_)) {
      if (auto denied = check_admin(req_, server_.ctx)) return send(std::move(*denied), true);
      if (cfg().upload_dir.empty()) {
        return send(json_error(403, "uploads are disabled (no upload_dir configured)"), true);
      }
      if (!length && !parser_->chunked()) {
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
      beast::error_code open_ec;
      upload_file_.open(upload_path_.c_str(), beast::file_mode::write_new, open_ec);
      if (open_ec) {
        upload_path_.clear();
        return send(
            json_error(500, "upload: cannot create a file in upload_dir: " + open_ec.message()),
            true);
      }
      parser_->write_body_to(upload_file_);
      parser_->body_limit(cfg().max_upload_bytes);
      return continue_then(read_body, expect_continue);
    }
    if (length && *length > cfg().max_body_bytes) {
      return send(json_error(413, "request body larger than max_body_bytes = " +
                                      std::to_string(cfg().max_body_bytes)),
                  true);
    }
    if (parser_->is_done()) return respond();  // no body (GET and friends): answer right away
    parser_->body_limit(cfg().max_body_bytes);
    continue_then(read_body, expect_continue);
  }

  template <typename Next>
  void continue_then(Next next, bool expect_continue) {
    if (!expect_continue) return next();
    static const std::string kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
    expires_after(cfg().write_timeout_ms);
    net::async_write(socket_, net::buffer(kContinue),
                     [self = shared_from_this(), next](beast::error_code ec, std::size_t) {
                       if (ec) return self->close_now();
                       next();
                     });
  }

  void on_body(beast::error_code ec) {
    const bool upload = upload_file_.is_open();
    if (ec == http::error::body_limit) {
      return send(upload ? json_error(413, "upload larger than max_upload_bytes = " +
                                               std::to_string(cfg().max_upload_bytes))
                         : json_error(413, "request body larger than max_body_bytes = " +
                                               std::to_string(cfg().max_body_bytes)),
                  true);
    }
    if (ec) return close_now();
    if (upload) {
      upload_file_.close(ec);
      if (ec) return send(json_error(500, "upload: " + ec.message()), true);
      req_.body_file_size = parser_->body_bytes();
      req_.body_file = std::move(upload_path_);  // handle() owns the file from here
      upload_path_.clear();
    }
    respond();
  }

  void respond() { send(handle(req_, server_.ctx), !keep_alive_); }

  // Status line and headers into `out`: the handler's headers, its prebuilt block, then what
  // depends on the connection.
  void format_head(std::string& out, const Response& res, std::size_t content_length) const {
    out.clear();
    out.append(version_ == 10 ? "HTTP/1.0 " : "HTTP/1.1 ");
    append_number(out, static_cast<std::uint64_t>(res.status));
    out.push_back(' ');
    out.append(view(http::obsolete_reason(http::int_to_status(static_cast<unsigned>(res.status)))));
    out.append("\r\nServer: tinstream\r\n");
    for (const auto& [k, v] : res.headers) out.append(k).append(": ").append(v).append("\r\n");
    if (res.prebuilt) out.append(res.prebuilt->wire);
    if (close_after_ && version_ != 10) out.append("Connection: close\r\n");
    if (!close_after_ && version_ == 10) out.append("Connection: keep-alive\r\n");
    if (res.status != 304 && res.status != 204) {
      out.append("Content-Length: ");
      append_number(out, content_length);
      out.append("\r\n");
    }
    out.append("\r\n");
  }

  // The head of `res` when it is the same for every keep-alive HTTP/1.1 request (a cached tile's
  // 200): formatted once into its prebuilt block and shared; else null.
  const std::string* shared_head(const Response& res, std::size_t content_length) const {
    if (!res.prebuilt || res.status != 200 || !res.headers.empty() || version_ != 11 ||
        close_after_) {
      return nullptr;
    }
    const HeaderBlock& block = *res.prebuilt;
    std::call_once(block.keep_alive_once, [&] {
      format_head(block.keep_alive_head, res, content_length);
      block.keep_alive_length = content_length;
      // The terrain cache charges at most this for the head (HeaderBlock::memory_bytes).
      assert(block.keep_alive_head.size() <= block.wire.size() + HeaderBlock::kKeepAliveExtra);
    });
    return block.keep_alive_length == content_length ? &block.keep_alive_head : nullptr;
  }

  void send(Response res, bool close_after) {
    close_after_ = close_after || server_.stopping;
    route_ = res.route;
    status_ = res.status;
    const bool head = req_.method == "HEAD";
    const std::size_t full = res.payload().size();
    body_bytes_ = head ? 0 : full;
    const std::string* whole_head = shared_head(res, full);
    if (!whole_head) format_head(head_, res, full);
    // The body (and a shared head) stays owned by the session until written: shared cached
    // bytes, or the string.
    prebuilt_ = std::move(res.prebuilt);
    shared_body_ = std::move(res.shared_body);
    body_ = std::move(res.body);
    expires_after(cfg().write_timeout_ms);
    // Only bodies the terrain cache keeps are worth a copy in the body file: without the cache
    // every answer would be a new body, written there once and sent once.
    if (!head && shared_body_ && cfg().sendfile && cfg().terrain_cache_bytes > 0 &&
        shared_body_->size() >= cfg().sendfile_min_bytes) {
      if (const auto at = shard_.bodies.place(shared_body_)) {
        pending_head_ = whole_head ? std::string_view(*whole_head) : std::string_view(head_);
        file_at_ = *at;
        file_end_ = *at + static_cast<off_t>(shared_body_->size());
        return send_file();
      }
    }
    const std::array<net::const_buffer, 2> buffers{
        net::buffer(whole_head ? *whole_head : head_),
        head ? net::const_buffer() : net::buffer(shared_body_ ? *shared_body_ : body_)};
    net::async_write(socket_, buffers, whole_buffers,
                     beast::bind_front_handler(&Session::on_write, shared_from_this()));
  }

  // The head from memory (MSG_MORE: it leaves with the body), then the body from the shard's
  // body file; waits for room in the socket whenever it is full. The write deadline still holds:
  // the sweep closes the socket, which ends the wait with an error.
  void send_file() {
    const int fd = socket_.native_handle();
    const auto failed = [this](int err) {
      on_write(beast::error_code(err, beast::system_category()), 0);
    };
    while (!pending_head_.empty()) {
      const ssize_t n =
          ::send(fd, pending_head_.data(), pending_head_.size(), MSG_NOSIGNAL | MSG_MORE);
      if (n < 0) {
        if (errno == EINTR) continue;
        return errno == EAGAIN ? wait_to_send_file() : failed(errno);
      }
      pending_head_.remove_prefix(static_cast<std::size_t>(n));
    }
    while (file_at_ < file_end_) {
      const ssize_t n = ::sendfile(fd, shard_.bodies.fd(), &file_at_,
                                   static_cast<std::size_t>(file_end_ - file_at_));
      if (n < 0) {
        if (errno == EINTR) continue;
        return errno == EAGAIN ? wait_to_send_file() : failed(errno);
      }
      if (n == 0) return failed(EIO);  // the file is shorter than placed: never expected
    }
    on_write({}, 0);
  }

  void wait_to_send_file() {
    socket_.async_wait(tcp::socket::wait_write, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return self->on_write(ec, 0);
      self->send_file();
    });
  }

  void on_write(beast::error_code ec, std::size_t) {
    deadline_ = Clock::time_point::max();
    const auto now = Clock::now();  // also the start of the wait for a next request
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(now - start_).count();
    server_.metrics.record(route_, status_, ec ? 0 : body_bytes_, static_cast<double>(us) / 1e6);
    if (cfg().access_log) {
      spdlog::info("{} {} {} {} {}us{}", req_.method, req_.target, status_, body_bytes_, us,
                   ec ? " (write failed: " + ec.message() + ")" : std::string());
    }
    prebuilt_.reset();
    shared_body_.reset();
    body_.clear();
    if (ec) return close_now();
    if (close_after_) return lingering_close();
    // Stopping or not, the client was told the connection stays open and may already have sent
    // its next request: do_read() closes an idle connection, else answers that request (with
    // `Connection: close` when stopping).
    do_read(now);
  }

  // Half-close, then drain what the client still sends (bounded in bytes and time) so that it
  // reads our response instead of a connection reset.
  void lingering_close() {
    beast::error_code ec;
    socket_.shutdown(tcp::socket::shutdown_send, ec);
    drained_ = 0;
    drain();
  }

  void drain() {
    expires_after(std::min<std::uint32_t>(cfg().read_timeout_ms, 2000));
    socket_.async_read_some(net::buffer(drain_buffer_),
                            [self = shared_from_this()](beast::error_code ec, std::size_t n) {
                              self->drained_ += n;
                              if (ec || self->drained_ > (4u << 20)) return self->close_now();
                              self->drain();
                            });
  }

  tcp::socket socket_;
  beast::flat_buffer buffer_;
  Server::Impl& server_;
  Shard& shard_;
  Clock::time_point deadline_ = Clock::time_point::max();  // of the pending read or write
  std::optional<RequestParser> parser_;                    // of the request being read, into req_
  beast::file upload_file_;                                // open while an upload body is read
  std::string head_;                                       // the response's header block
  std::string body_;                                       // the response's own body bytes
  std::shared_ptr<const std::string> shared_body_;         // or shared, cached ones
  std::shared_ptr<const HeaderBlock> prebuilt_;            // holds a shared head being written
  std::string_view pending_head_;     // sendfile path: head bytes not yet sent (in head_/prebuilt_)
  off_t file_at_ = 0, file_end_ = 0;  // sendfile path: body range left in the body file
  std::filesystem::path upload_path_;  // removed by the destructor unless handed to handle()
  Request req_;
  Clock::time_point start_;
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
  // this object. No thread runs the shards any more: close the sessions' sockets from here and
  // let those handlers finish before any member goes away.
  beast::error_code ec;
  acceptor.close(ec);
  signals.cancel(ec);
  grace.cancel();
  for (auto& shard : shards) {
    shard->work.reset();
    shard->sweep.cancel();
    for (Session* s : shard->sessions) s->close_now();
    shard->ioc.restart();
    shard->ioc.run_for(std::chrono::seconds(5));
  }
}

void Server::Impl::do_accept() {
  Shard& target = *shards[next_shard];
  next_shard = (next_shard + 1) % shards.size();
  acceptor.async_accept(target.ioc, [this, &target](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (!acceptor.is_open() || stopping) return;
      spdlog::warn("accept failed: {}", ec.message());
    } else if (!stopping) {
      beast::error_code nd;
      socket.set_option(tcp::no_delay(true), nd);  // responses go out in one write; no Nagle wait
      auto session = std::make_shared<Session>(std::move(socket), *this, target);
      const bool reject =
          metrics.open_connections() > static_cast<std::int64_t>(config.max_connections);
      if (reject) metrics.connection_rejected();
      net::post(target.ioc, [session = std::move(session), reject] { session->start(reject); });
    }
    if (!stopping) do_accept();
  });
}

void Server::Impl::sweep(Shard& shard) {
  const auto now = Clock::now();
  for (Session* s : shard.sessions) s->check_deadline(now);  // closing erases nothing here
  shard.bodies.collect();
  if (stopping && shard.sessions.empty()) return;  // lets run() return
  shard.sweep.expires_after(shard.every);
  shard.sweep.async_wait([this, &shard](beast::error_code ec) {
    if (!ec) sweep(shard);
  });
}

void Server::Impl::stop() {
  if (stopping.exchange(true)) return;
  spdlog::info("shutting down: finishing in-flight requests (grace {} ms)",
               config.shutdown_grace_ms);
  stop_deadline = Clock::now() + std::chrono::milliseconds(config.shutdown_grace_ms);
  net::post(acceptor.get_executor(), [this] {
    beast::error_code ec;
    acceptor.close(ec);
    signals.cancel(ec);
  });
  for (auto& shard : shards) {
    net::post(shard->ioc, [s = shard.get()] {
      for (Session* session : s->sessions) session->shutdown();
    });
    shard->work.reset();
  }
  net::post(shards.front()->ioc, [this] { watch_drain(); });
}

void Server::Impl::watch_drain() {
  if (live_sessions.load() == 0) return;  // nothing left: run() returns once the handlers finish
  if (Clock::now() >= stop_deadline) {
    spdlog::warn("shutdown grace period over; closing remaining connections");
    for (auto& shard : shards) shard->ioc.stop();
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
  const unsigned threads =
      config.threads > 0 ? config.threads : std::max(1u, std::thread::hardware_concurrency());
  auto impl = std::make_unique<Impl>(config, threads);
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
  // sendfile(2) has no MSG_NOSIGNAL: a peer gone mid-response must be an EPIPE, not a signal
  // that ends the process.
  std::signal(SIGPIPE, SIG_IGN);
  if (handle_signals) {
    s.signals.async_wait([&s](beast::error_code ec, int signo) {
      if (ec) return;
      spdlog::info("signal {} received", signo);
      s.stop();
    });
  }
  if (!s.stopping) {
    s.do_accept();
    for (auto& shard : s.shards) {
      net::post(shard->ioc, [&s, sh = shard.get()] { s.sweep(*sh); });
    }
  }
  spdlog::info("tinstream-server listening on {}:{} with {} threads, store {}", s.config.address,
               port(), s.shards.size(), s.config.store.string());
  std::vector<std::thread> threads;
  auto serve = [&s](Shard& shard) {
    shard.ioc.run();
    thread_stores().erase(s.serial);
  };
  for (std::size_t i = 1; i < s.shards.size(); ++i)
    threads.emplace_back(serve, std::ref(*s.shards[i]));
  serve(*s.shards.front());
  for (auto& t : threads) t.join();
  s.jobs->shutdown();
  spdlog::info("tinstream-server stopped");
}

void Server::stop() { impl_->stop(); }

}  // namespace tinstream::server
