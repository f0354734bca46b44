// sendfile_writer.hpp — a response written as its head from memory and its body from a file with
// sendfile(2): the kernel hands the file's pages to the socket instead of copying the bytes (what
// nginx does for static files). The session uses it for cached bodies placed in its shard's
// BodyFile (body_file.hpp). Private to the server.
//
//   head (send, MSG_MORE: leaves with the body) ──▶ body (sendfile from the file range) ──▶ done
//        ▲  socket full (EAGAIN): wait until writable, then go on where it stopped  │
//        └──────────────────────────────────────────────────────────────────────────┘
//
// The socket must be non-blocking (the session sets it so at start). A deadline is enforced by
// whoever owns the socket: closing it ends a pending wait with an error.
#pragma once

#include <sys/types.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/error.hpp>
#include <string_view>
#include <utility>

namespace tinstream::server {

// What is left to write. The head's bytes belong to the caller and stay valid until done.
struct SendfileJob {
  std::string_view head;
  int file = -1;
  off_t at = 0, end = 0;  // the body's range left in `file`
};

enum class SendProgress { done, would_block, failed };

// Writes as much of `job` as the socket takes now, advancing it. On `failed`, `err` is the errno.
SendProgress send_some(int socket_fd, SendfileJob& job, int& err);

// Writes all of `job`, waiting for room in the socket whenever it is full; then calls
// handler(error_code). `socket` and `job` must outlive the operation (the handler owns their
// owner). The handler may run before this returns (when the socket takes everything at once).
template <typename Handler>
void async_sendfile(boost::asio::ip::tcp::socket& socket, SendfileJob& job, Handler handler) {
  namespace beast = boost::beast;
  int err = 0;
  switch (send_some(socket.native_handle(), job, err)) {
    case SendProgress::done:
      return handler(beast::error_code{});
    case SendProgress::failed:
      return handler(beast::error_code(err, beast::system_category()));
    case SendProgress::would_block:
      socket.async_wait(
          boost::asio::ip::tcp::socket::wait_write,
          [&socket, &job, handler = std::move(handler)](beast::error_code ec) mutable {
            if (ec) return handler(ec);
            async_sendfile(socket, job, std::move(handler));
          });
      return;
  }
}

}  // namespace tinstream::server
