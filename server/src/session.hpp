// session.hpp — one HTTP connection, from accept to close, as a chain of asynchronous steps (the
// shape of Boost.Beast's example sessions). Private to the server.
//
//   start ──▶ do_read ──▶ on_read ──▶ on_header ──┬──────────────────────────▶ respond
//               ▲  (more bytes needed: do_read_some)  └─ read_body ─▶ on_body ─┘    │
//               │                                                                   ▼
//               └──────────── keep-alive, not stopping ◀── on_write ◀───────── do_write
//   an error, a timeout, `Connection: close` or a 4xx that ends the connection:
//               do_write(…, close) ─▶ on_write ─▶ do_close ─▶ on_drain … ─▶ closed
//
// Every step runs on the session's shard thread; each pending operation's handler holds
// shared_from_this(), which is what keeps the session alive. Deadlines are not timers: the
// shard's sweep calls check_deadline() (server_state.hpp), which closes an overdue socket and so
// ends the pending operation with an error.
//
// Requests are read by the session itself (read_some into a buffer it keeps, then Beast's
// basic_parser over it: request_parser.hpp), not by Beast's composed read: no allocation per
// request field, and a pipelined burst is parsed from one read. A response goes out as one
// gather write (head and body, offered whole to each writev) or, for a large cached body, as its
// head and a sendfile(2) from the shard's body file (sendfile_writer.hpp).
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/error.hpp>
#include <boost/beast/core/file.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "request_parser.hpp"
#include "sendfile_writer.hpp"
#include "server_state.hpp"

namespace tinstream::server {

class Session : public std::enable_shared_from_this<Session> {
 public:
  using tcp = boost::asio::ip::tcp;

  // `admin_listener`: accepted on the admin listener (config admin_address). `counted`: the
  // connection holds one of its address's slots (AddressCounts), released by the destructor.
  // `peer`: the client's address when `socket` is not the client's own (the plain end of a TLS
  // connection, tls.hpp); empty: the socket's remote address.
  Session(tcp::socket&& socket, ServerState& server, Shard& shard, bool admin_listener = false,
          bool counted = false, std::string peer = {});
  ~Session();

  // On the shard's thread. `refusal` non-empty: answer 503 with it and close (over
  // max_connections or max_connections_per_ip).
  void start(std::string refusal = {});
  // On the shard's thread, when the server stops: idle connections close now, busy ones after
  // their response (bounded by the timeouts and shutdown_grace_ms), with `Connection: close`.
  void shutdown();
  // On the shard's thread: closes the connection when its current read or write is overdue.
  void check_deadline(Clock::time_point now);
  void close_now();

 private:
  const ServerConfig& cfg() const { return server_.config; }
  void expires_after(std::uint32_t ms, Clock::time_point now = Clock::now());
  bool idle();
  void reset_request();

  // 1. Reading a request: its header, then its body (to memory, or to a file for uploads).
  void do_read(Clock::time_point now = Clock::now());
  void parse_buffered();
  void do_read_some();
  void on_read(beast::error_code ec, std::size_t n);
  void on_parsed(beast::error_code ec);
  void on_header(beast::error_code ec);
  std::optional<Response> begin_upload(const boost::optional<std::uint64_t>& length);
  std::optional<Response> reserve_upload_space(std::uint64_t bytes);
  void release_upload_space();
  void extend_upload_deadline(Clock::time_point now);
  void read_body(bool expect_continue);
  void on_body(beast::error_code ec);

  // 2. Answering it (an answer the handler defers is computed on the blocking worker).
  void respond();
  void defer(std::function<Response()> work);
  void do_write(Response res, bool close_after);
  void on_write(beast::error_code ec, std::size_t n);

  void release_large_buffers();

  // 3. Closing: half-close, then drain what the client still sends so that it reads the
  //    response instead of a connection reset: bounded in bytes, in total time (linger_ms, not
  //    renewed by the bytes) and in number (a quarter of max_connections drain at once; the
  //    others close at once).
  void do_close();
  void do_drain();
  void on_drain(beast::error_code ec, std::size_t n);

  tcp::socket socket_;
  beast::flat_buffer buffer_;
  ServerState& server_;
  Shard& shard_;
  Clock::time_point deadline_ = Clock::time_point::max();  // of the pending read or write
  std::optional<RequestParser> parser_;                    // of the request being read, into req_
  beast::file upload_file_;                                // open while an upload body is read
  std::string head_;                                       // the response's header block
  std::string body_;                                       // the response's own body bytes
  std::shared_ptr<const std::string> shared_body_;         // or shared, cached ones
  std::shared_ptr<const HeaderBlock> prebuilt_;            // holds a shared head being written
  SendfileJob sendfile_;               // sendfile path: what is left (head in head_/prebuilt_)
  std::filesystem::path upload_path_;  // removed by the destructor unless handed to handle()
  std::uint64_t upload_reserved_ = 0;  // of ServerState::uploading, until the body is complete
  Clock::time_point upload_start_;
  Request req_;
  Clock::time_point start_;
  std::string route_ = "other";
  int status_ = 0;
  std::size_t body_bytes_ = 0;
  unsigned version_ = 11;
  bool keep_alive_ = false;
  bool close_after_ = false;
  bool reading_header_ = false;
  bool counted_ = false;    // holds a slot of its address (AddressCounts)
  bool lingering_ = false;  // counted in ServerState::lingering
  std::size_t drained_ = 0;
  std::array<char, 8192> drain_buffer_{};
};

}  // namespace tinstream::server
