#include "session.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <sys/statvfs.h>

#include <algorithm>
#include <array>
#include <boost/asio/buffer.hpp>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core/bind_handler.hpp>
#include <boost/beast/http/error.hpp>
#include <cerrno>
#include <cstring>
#include <limits>
#include <random>

namespace tinstream::server {

namespace net = boost::asio;

namespace {

// Bytes asked of the socket per read when the buffer has less room: a few requests' worth.
constexpr std::size_t kReadSize = 4096;
// Buffers larger than this (a big request body, a big answer) are released after the response,
// so that an idle keep-alive connection holds no more.
constexpr std::size_t kKeptBufferBytes = 64u << 10;
// What a closing connection drains at most before it is closed hard.
constexpr std::size_t kMaxDrainBytes = 64u << 10;

std::string random_hex(std::size_t n) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  static constexpr char kHex[] = "0123456789abcdef";
  std::string s;
  for (std::size_t i = 0; i < n; ++i) s.push_back(kHex[rng() % 16]);
  return s;
}

// Completion condition of a response write: offer the kernel everything left in each call.
// (Asio's transfer_all caps every writev at 64 KiB, which splits most terrain tiles in two
// system calls and two pushes of TCP segments.)
std::size_t whole_buffers(const beast::error_code& ec, std::size_t) {
  return ec ? 0 : std::numeric_limits<std::size_t>::max();
}

}  // namespace

Session::Session(tcp::socket&& socket, ServerState& server, Shard& shard, bool admin_listener,
                 bool counted, std::string peer)
    : socket_(std::move(socket)), server_(server), shard_(shard), counted_(counted) {
  server_.metrics.connection_opened();
  server_.live_sessions.fetch_add(1);
  if (!peer.empty()) {
    req_.remote = std::move(peer);
  } else {
    beast::error_code ec;
    const auto endpoint = socket_.remote_endpoint(ec);
    if (!ec) req_.remote = endpoint.address().to_string();
  }
  req_.admin_listener = admin_listener;
}

Session::~Session() {
  shard_.sessions.erase(this);
  server_.metrics.connection_closed();
  if (!upload_path_.empty()) {
    std::error_code ec;
    std::filesystem::remove(upload_path_, ec);
  }
  if (counted_) server_.addresses.release(req_.remote);
  release_upload_space();
  if (lingering_) server_.lingering.fetch_sub(1);
  server_.live_sessions.fetch_sub(1);
}

void Session::start(const std::string& refusal) {
  shard_.sessions.insert(this);
  beast::error_code ec;
  socket_.native_non_blocking(true, ec);  // the sendfile writer calls send/sendfile itself
  if (refusal.empty()) return do_read();
  start_ = Clock::now();
  reset_request();
  do_write(json_error(503, refusal), true);
  // A refused client gets a second at most to take its 503.
  expires_after(std::min<std::uint32_t>(cfg().write_timeout_ms, 1000));
}

// The wait for a next request is cancelled, not closed: the reactor may already have read the
// first bytes of one (neither in buffer_ nor in the socket yet), and on_header still gets them.
void Session::shutdown() {
  if (!reading_header_ || !idle()) return;
  beast::error_code ec;
  socket_.cancel(ec);
}

void Session::check_deadline(Clock::time_point now) {
  if (now >= deadline_) {
    deadline_ = Clock::time_point::max();
    close_now();
  }
}

void Session::close_now() {
  beast::error_code ec;
  socket_.shutdown(tcp::socket::shutdown_both, ec);
  socket_.close(ec);
}

void Session::expires_after(std::uint32_t ms, Clock::time_point now) {
  deadline_ = now + std::chrono::milliseconds(ms);
}

// No bytes of a next request received, neither buffered nor waiting in the socket.
bool Session::idle() {
  beast::error_code ec;
  return buffer_.size() == 0 && socket_.available(ec) == 0;
}

// The request fields are reused from one request to the next (their capacity with them); the
// peer's address and the listener stay.
void Session::reset_request() {
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

// ---- 1. Reading a request ------------------------------------------------------------------

// Waits for the next request: its header within read_timeout_ms of now, however it trickles in.
void Session::do_read(Clock::time_point now) {
  if (server_.stopping && idle()) return close_now();
  reset_request();
  parser_.emplace(req_);
  parser_->header_limit(cfg().max_header_bytes);
  // Body limits depend on the route (uploads vs. the rest): set once the header is known.
  parser_->body_limit(std::numeric_limits<std::uint64_t>::max());
  reading_header_ = true;
  expires_after(cfg().read_timeout_ms, now);
  parse_buffered();
}

// Feeds the buffered bytes to the parser until the header (or, after it, the body) is complete,
// reading more while it needs them. A pipelined next request stays in buffer_.
void Session::parse_buffered() {
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
  if (!ec && !complete()) {
    if (!reading_header_ && upload_file_.is_open()) extend_upload_deadline(Clock::now());
    return do_read_some();
  }
  on_parsed(ec);
}

void Session::do_read_some() {
  // At least a few requests' worth per read: a pipelined burst costs one system call.
  const std::size_t size = std::max<std::size_t>(kReadSize, buffer_.capacity() - buffer_.size());
  socket_.async_read_some(buffer_.prepare(size),
                          beast::bind_front_handler(&Session::on_read, shared_from_this()));
}

void Session::on_read(beast::error_code ec, std::size_t n) {
  buffer_.commit(n);
  if (ec == net::error::eof) {
    if (!parser_->got_some()) return on_parsed(http::error::end_of_stream);
    ec = {};
    parser_->put_eof(ec);  // a message cut short: partial_message
    return on_parsed(ec);
  }
  if (ec) return on_parsed(ec);
  parse_buffered();
}

void Session::on_parsed(beast::error_code ec) { reading_header_ ? on_header(ec) : on_body(ec); }

void Session::on_header(beast::error_code ec) {
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
    return do_write(json_error(431, "request header fields too large (max_header_bytes = " +
                                        std::to_string(cfg().max_header_bytes) + ")"),
                    true);
  }
  if (ec == http::error::body_limit)
    return do_write(json_error(413, "request body too large"), true);
  if (ec) return do_write(json_error(400, "malformed request: " + ec.message()), true);
  // RFC 9112 §3.2: an HTTP/1.1 request without Host, or any with more than one, is a 400.
  if (parser_->host_fields() > 1) {
    return do_write(json_error(400, "malformed request: more than one Host header"), true);
  }
  if (parser_->host_fields() == 0 && parser_->version() >= 11) {
    return do_write(json_error(400, "malformed request: HTTP/1.1 without a Host header"), true);
  }

  keep_alive_ = parser_->keep_alive();
  version_ = parser_->version();
  const auto length = parser_->content_length();
  if (is_upload(req_)) {
    if (auto refused = begin_upload(length)) return do_write(std::move(*refused), true);
    parser_->body_limit(cfg().max_upload_bytes);
    return read_body(parser_->expect_continue());
  }
  if (length && *length > cfg().max_body_bytes) {
    return do_write(json_error(413, "request body larger than max_body_bytes = " +
                                        std::to_string(cfg().max_body_bytes)),
                    true);
  }
  if (parser_->is_done()) return respond();  // no body (GET and friends): answer right away
  parser_->body_limit(cfg().max_body_bytes);
  read_body(parser_->expect_continue());
}

// An upload's body goes to a new file in upload_dir; refused (the answer returned) before a byte
// is written when the token is wrong, uploads are off, the length is missing or too large.
std::optional<Response> Session::begin_upload(const boost::optional<std::uint64_t>& length) {
  if (auto denied = check_admin(req_, server_.ctx)) return denied;
  if (cfg().upload_dir.empty()) {
    return json_error(403, "uploads are disabled (no upload_dir configured)");
  }
  if (!length && !parser_->chunked()) {
    return json_error(411, "upload: Content-Length or chunked encoding required");
  }
  if (length && *length > cfg().max_upload_bytes) {
    return json_error(
        413, "upload larger than max_upload_bytes = " + std::to_string(cfg().max_upload_bytes));
  }
  if (auto refused = reserve_upload_space(length ? *length : cfg().max_upload_bytes))
    return refused;
  // The folder and the file are the server's own: 0700 and 0600, never through a symlink.
  std::error_code fs_ec;
  if (!std::filesystem::exists(cfg().upload_dir, fs_ec)) {
    std::filesystem::create_directories(cfg().upload_dir.parent_path(), fs_ec);
    ::mkdir(cfg().upload_dir.c_str(), 0700);
  }
  upload_path_ = cfg().upload_dir / ("upload-" + random_hex(16));
  const int fd =
      ::open(upload_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd < 0) {
    const std::string why = std::strerror(errno);
    upload_path_.clear();
    return json_error(500, "upload: cannot create a file in upload_dir: " + why);
  }
  upload_file_.native_handle(fd);
  parser_->write_body_to(upload_file_);
  upload_start_ = Clock::now();
  return std::nullopt;
}

// Room for an upload of `bytes`: within max_upload_total_bytes together with the uploads in
// progress and the upload files waiting for their jobs, and leaving upload_min_free_bytes on
// the disk. Reserved until the body is complete (or the session ends); 507 otherwise.
std::optional<Response> Session::reserve_upload_space(std::uint64_t bytes) {
  std::uint64_t waiting = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(cfg().upload_dir, ec)) {
    std::error_code size_ec;
    if (e.path().filename().string().rfind("upload-", 0) == 0 && e.is_regular_file(size_ec))
      waiting += e.file_size(size_ec);
  }
  const std::uint64_t before = server_.uploading.fetch_add(bytes);
  upload_reserved_ = bytes;
  if (before + waiting + bytes > cfg().max_upload_total_bytes) {
    release_upload_space();
    return json_error(507,
                      "upload: uploads in progress and waiting for their jobs would exceed "
                      "max_upload_total_bytes = " +
                          std::to_string(cfg().max_upload_total_bytes));
  }
  struct statvfs disk {};
  const auto& where = std::filesystem::exists(cfg().upload_dir, ec)
                          ? cfg().upload_dir
                          : cfg().upload_dir.parent_path();
  if (::statvfs(where.empty() ? "." : where.c_str(), &disk) == 0) {
    const std::uint64_t free_bytes =
        static_cast<std::uint64_t>(disk.f_bavail) * static_cast<std::uint64_t>(disk.f_frsize);
    if (free_bytes < bytes || free_bytes - bytes < cfg().upload_min_free_bytes) {
      release_upload_space();
      return json_error(507, "upload: not enough free disk space (upload_min_free_bytes = " +
                                 std::to_string(cfg().upload_min_free_bytes) + ")");
    }
  }
  return std::nullopt;
}

void Session::release_upload_space() {
  server_.uploading.fetch_sub(upload_reserved_);
  upload_reserved_ = 0;
}

// An upload's body has read_timeout_ms without a byte, and in all read_timeout_ms plus the time
// its bytes so far take at upload_min_bytes_per_s.
void Session::extend_upload_deadline(Clock::time_point now) {
  const std::uint64_t rate = std::max<std::uint32_t>(1, cfg().upload_min_bytes_per_s);
  const auto earned = std::chrono::milliseconds(parser_->body_bytes() * 1000 / rate);
  const auto idle = now + std::chrono::milliseconds(cfg().read_timeout_ms);
  deadline_ =
      std::min(idle, upload_start_ + std::chrono::milliseconds(cfg().read_timeout_ms) + earned);
}

// Reads the body (on_body once complete) within read_timeout_ms, after a 100 Continue when the
// client asked for it.
void Session::read_body(bool expect_continue) {
  if (!expect_continue) {
    expires_after(cfg().read_timeout_ms);
    upload_start_ = Clock::now();
    return parse_buffered();
  }
  static const std::string kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
  expires_after(cfg().write_timeout_ms);
  net::async_write(socket_, net::buffer(kContinue),
                   [self = shared_from_this()](beast::error_code ec, std::size_t) {
                     if (ec) return self->close_now();
                     self->read_body(false);
                   });
}

void Session::on_body(beast::error_code ec) {
  const bool upload = upload_file_.is_open();
  if (ec == http::error::body_limit) {
    return do_write(upload ? json_error(413, "upload larger than max_upload_bytes = " +
                                                 std::to_string(cfg().max_upload_bytes))
                           : json_error(413, "request body larger than max_body_bytes = " +
                                                 std::to_string(cfg().max_body_bytes)),
                    true);
  }
  if (ec) return close_now();
  if (upload) {
    upload_file_.close(ec);
    if (ec) return do_write(json_error(500, "upload: " + ec.message()), true);
    release_upload_space();  // the file now counts as waiting for its job
    req_.body_file_size = parser_->body_bytes();
    req_.body_file = std::move(upload_path_);  // handle() owns the file from here
    upload_path_.clear();
  }
  respond();
}

// ---- 2. Answering it -----------------------------------------------------------------------

void Session::respond() {
  Response res = handle(req_, server_.ctx);
  if (res.deferred && server_.blocking) return defer(std::move(res.deferred));
  if (res.deferred) res = res.deferred();  // no worker (never in a running server)
  do_write(std::move(res), !keep_alive_);
}

// The work runs on the blocking worker; its answer comes back to this shard's thread. The work
// guard keeps the shard's io_context running until it has (a graceful stop waits for it). The
// session's reference moves back with the answer, none stays in the worker's task: the last
// reference must drop on the shard's thread, since ~Session leaves the shard's session set (a
// copy left in the task made the worker destroy a closed session while the shard swept the set:
// TSan, ServerTest.IngestThroughTheAdminApiWhileServing).
void Session::defer(std::function<Response()> work) {
  deadline_ = Clock::time_point::max();  // no socket operation is pending meanwhile
  server_.blocking->post([self = shared_from_this(), work = std::move(work),
                          guard = net::make_work_guard(shard_.ioc)]() mutable {
    Response res = work();
    work = nullptr;  // what the work holds goes here, on the worker, not with the answer
    net::io_context& ioc = self->shard_.ioc;  // (before self moves into the handler)
    net::post(ioc,
              [self = std::move(self), res = std::move(res), guard = std::move(guard)]() mutable {
                self->do_write(std::move(res), !self->keep_alive_);
              });
  });
}

void Session::do_write(Response res, bool close_after) {
  close_after_ = close_after || server_.stopping;
  route_ = res.route;
  status_ = res.status;
  const bool head = req_.method == "HEAD";
  const std::size_t full = res.payload().size();
  body_bytes_ = head ? 0 : full;
  // A cached tile's 200 on a keep-alive HTTP/1.1 connection: its head was formatted once, with
  // its block (HeaderBlock::keep_alive_head); any other answer formats its own.
  const HeaderBlock* block = res.prebuilt.get();
  const bool shared_head = block && res.status == 200 && res.headers.empty() && version_ == 11 &&
                           !close_after_ && block->content_length == full;
  if (!shared_head)
    format_response_head(head_, res.status, version_, res.headers, block, close_after_, full);
  const std::string_view head_bytes = shared_head ? block->keep_alive_head : head_;
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
      sendfile_ = SendfileJob{head_bytes, shard_.bodies.fd(), *at,
                              *at + static_cast<off_t>(shared_body_->size())};
      return async_sendfile(socket_, sendfile_, [self = shared_from_this()](beast::error_code ec) {
        self->on_write(ec, 0);
      });
    }
  }
  const std::array<net::const_buffer, 2> buffers{
      net::buffer(head_bytes.data(), head_bytes.size()),
      head ? net::const_buffer() : net::buffer(shared_body_ ? *shared_body_ : body_)};
  net::async_write(socket_, buffers, whole_buffers,
                   beast::bind_front_handler(&Session::on_write, shared_from_this()));
}

void Session::on_write(beast::error_code ec, std::size_t) {
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
  release_large_buffers();
  if (ec) return close_now();
  if (close_after_) return do_close();
  // Stopping or not, the client was told the connection stays open and may already have sent
  // its next request: do_read() closes an idle connection, else answers that request (with
  // `Connection: close` when stopping).
  do_read(now);
}

// ---- 3. Closing ----------------------------------------------------------------------------

void Session::release_large_buffers() {
  if (body_.capacity() > kKeptBufferBytes) {
    std::string().swap(body_);
  } else {
    body_.clear();
  }
  if (req_.body.capacity() > kKeptBufferBytes) std::string().swap(req_.body);
  if (buffer_.size() == 0 && buffer_.capacity() > kKeptBufferBytes) buffer_.shrink_to_fit();
}

// ---- 3. Closing ----------------------------------------------------------------------------

void Session::do_close() {
  beast::error_code ec;
  socket_.shutdown(tcp::socket::shutdown_send, ec);
  const std::int64_t most = std::max<std::int64_t>(1, cfg().max_connections / 4);
  if (server_.lingering.fetch_add(1) >= most) {
    server_.lingering.fetch_sub(1);
    return close_now();
  }
  lingering_ = true;
  drained_ = 0;
  expires_after(cfg().linger_ms);  // once: the bytes that come do not extend it
  do_drain();
}

void Session::do_drain() {
  socket_.async_read_some(net::buffer(drain_buffer_),
                          beast::bind_front_handler(&Session::on_drain, shared_from_this()));
}

void Session::on_drain(beast::error_code ec, std::size_t n) {
  drained_ += n;
  if (ec || drained_ > kMaxDrainBytes) return close_now();
  do_drain();
}

}  // namespace tinstream::server
