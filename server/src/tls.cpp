#include "tls.hpp"

#include <openssl/ssl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <boost/asio/local/stream_protocol.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/stream.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/write.hpp>
#include <cerrno>
#include <cstring>

namespace tinstream::server {

namespace net = boost::asio;
namespace ssl = boost::asio::ssl;
using tcp = net::ip::tcp;
using boost::system::error_code;

Result<std::shared_ptr<ssl::context>> make_tls_context(const ServerConfig& config) {
  auto context = std::make_shared<ssl::context>(ssl::context::tls_server);
  // TLS 1.2 and 1.3 only; no compression (CRIME), no renegotiation by the client.
  if (SSL_CTX_set_min_proto_version(context->native_handle(), TLS1_2_VERSION) != 1) {
    return io_error("tls: cannot require TLS 1.2 or later");
  }
  context->set_options(ssl::context::default_workarounds | ssl::context::no_compression |
                       ssl::context::single_dh_use);
  SSL_CTX_set_options(context->native_handle(), SSL_OP_NO_RENEGOTIATION);
  error_code ec;
  context->use_certificate_chain_file(config.tls_cert.string(), ec);
  if (ec) {
    return io_error("config key \"tls_cert\": cannot use " + config.tls_cert.string() + ": " +
                    ec.message());
  }
  context->use_private_key_file(config.tls_key.string(), ssl::context::pem, ec);
  if (ec) {
    return io_error("config key \"tls_key\": cannot use " + config.tls_key.string() + ": " +
                    ec.message());
  }
  if (SSL_CTX_check_private_key(context->native_handle()) != 1) {
    return invalid_argument(
        "config keys \"tls_cert\" and \"tls_key\": the key is not the "
        "certificate's");
  }
  return context;
}

namespace {

using Local = net::local::stream_protocol;

// Copies bytes between the client's TLS stream and the session's end of the socket pair, one
// read and one write in flight per direction; owned by its pending operations.
class TlsPump : public std::enable_shared_from_this<TlsPump> {
 public:
  TlsPump(tcp::socket client, std::shared_ptr<ssl::context> context, Local::socket plain)
      : context_(std::move(context)),
        tls_(std::move(client), *context_),
        plain_(std::move(plain)),
        timer_(tls_.get_executor()) {}

  void start(std::chrono::milliseconds handshake_timeout) {
    timer_.expires_after(handshake_timeout);
    timer_.async_wait([self = shared_from_this()](error_code ec) {
      if (!ec && !self->handshaken_) self->close();
    });
    tls_.async_handshake(ssl::stream_base::server, [self = shared_from_this()](error_code ec) {
      self->timer_.cancel();
      if (ec || self->closed_) return self->close();
      self->handshaken_ = true;
      self->read_client();
      self->read_plain();
    });
  }

 private:
  // Client → session. The client's end of the stream (close_notify, a reset) half-closes the
  // pair, so the session reads its end of input and answers what it already has.
  void read_client() {
    reading_client_ = true;
    tls_.async_read_some(net::buffer(up_),
                         [self = shared_from_this()](error_code ec, std::size_t n) {
                           self->reading_client_ = false;
                           if (self->closing_) return self->send_close_notify();
                           if (ec) {
                             error_code ignored;
                             self->plain_.shutdown(Local::socket::shutdown_send, ignored);
                             return;
                           }
                           net::async_write(self->plain_, net::buffer(self->up_.data(), n),
                                            [self](error_code write_ec, std::size_t) {
                                              if (write_ec)
                                                return self->close();  // the session is gone
                                              if (!self->closing_) self->read_client();
                                            });
                         });
  }

  // Session → client. The session's end of output (its close, or a close after its deadline)
  // ends the connection.
  void read_plain() {
    plain_.async_read_some(net::buffer(down_),
                           [self = shared_from_this()](error_code ec, std::size_t n) {
                             if (ec) return self->finish();
                             net::async_write(self->tls_, net::buffer(self->down_.data(), n),
                                              [self](error_code write_ec, std::size_t) {
                                                if (write_ec)
                                                  return self->close();  // the client is gone
                                                self->read_plain();
                                              });
                           });
  }

  // close_notify, bounded by a second; a pending read of the client is cancelled first (one
  // read at a time on the TLS stream, and the shutdown reads the client's close_notify).
  void finish() {
    if (closing_ || closed_) return;
    closing_ = true;
    timer_.expires_after(std::chrono::seconds(1));
    timer_.async_wait([self = shared_from_this()](error_code ec) {
      if (!ec) self->close();
    });
    if (reading_client_) {
      error_code ignored;
      tls_.next_layer().cancel(ignored);  // its handler sends close_notify
    } else {
      send_close_notify();
    }
  }

  void send_close_notify() {
    if (closed_ || shutting_down_) return;
    shutting_down_ = true;
    tls_.async_shutdown([self = shared_from_this()](error_code) { self->close(); });
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    error_code ignored;
    timer_.cancel();
    tls_.next_layer().shutdown(tcp::socket::shutdown_both, ignored);
    tls_.next_layer().close(ignored);
    plain_.close(ignored);
  }

  std::shared_ptr<ssl::context> context_;
  ssl::stream<tcp::socket> tls_;
  Local::socket plain_;
  net::steady_timer timer_;
  std::array<char, 16384> up_{};
  std::array<char, 16384> down_{};
  bool handshaken_ = false;
  bool reading_client_ = false;
  bool closing_ = false;
  bool shutting_down_ = false;
  bool closed_ = false;
};

}  // namespace

Result<tcp::socket> start_tls_pump(tcp::socket client, std::shared_ptr<ssl::context> context,
                                   net::io_context& ioc,
                                   std::chrono::milliseconds handshake_timeout) {
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0) {
    return io_error(std::string("tls: no socket pair: ") + std::strerror(errno));
  }
  Local::socket pump_end(ioc);
  tcp::socket session_end(ioc);
  error_code ec;
  pump_end.assign(Local(), fds[0], ec);
  if (ec) {
    ::close(fds[0]);
    ::close(fds[1]);
    return io_error("tls: " + ec.message());
  }
  // The session's end is a stream socket like a TCP one (read, writev, sendfile, shutdown);
  // the session is told the client's address instead of asking this socket for it.
  session_end.assign(tcp::v4(), fds[1], ec);
  if (ec) {
    ::close(fds[1]);
    return io_error("tls: " + ec.message());
  }
  auto pump = std::make_shared<TlsPump>(std::move(client), std::move(context), std::move(pump_end));
  net::post(ioc, [pump, handshake_timeout] { pump->start(handshake_timeout); });
  return session_end;
}

}  // namespace tinstream::server
