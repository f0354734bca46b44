// tls.hpp — HTTPS termination (config tls_cert / tls_key). Private to the server.
//
// A TLS connection is terminated beside its session, not inside it: the accepted TCP socket gets
// an asio::ssl::stream (OpenSSL; TLS 1.2 or later), and the session (session.hpp, unchanged: its
// parser, deadlines, sendfile writer and lingering close) gets one end of a local socket pair
// whose other end the pump below copies to and from the TLS stream:
//
//   client ══TLS══ TlsPump ── socketpair ── Session (plain HTTP/1.1, same shard thread)
//
// Every bound of the session applies as it does to a plain connection (a client that stalls in
// the handshake stalls the session's header read and hits read_timeout_ms); when the session
// closes its end the pump sends close_notify (waiting at most a second for the client's) and
// closes the TCP socket. The session is given the client's address (per-address caps, admin
// allow-list, logs).
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/context.hpp>
#include <chrono>
#include <memory>

#include "tinstream/base/result.hpp"
#include "tinstream/server/config.hpp"

namespace tinstream::server {

// The server's TLS context: TLS 1.2 or later, the certificate chain and key of the config.
// Errors name the config key and file (never the file's contents).
Result<std::shared_ptr<boost::asio::ssl::context>> make_tls_context(const ServerConfig& config);

// Starts terminating TLS on `client` (a socket of `ioc`, whose thread runs the pump) and returns
// the plain end for the session, on the same io_context. A handshake not done within
// `handshake_timeout` closes the connection. Errors: no socket pair (out of descriptors).
Result<boost::asio::ip::tcp::socket> start_tls_pump(
    boost::asio::ip::tcp::socket client, std::shared_ptr<boost::asio::ssl::context> context,
    boost::asio::io_context& ioc, std::chrono::milliseconds handshake_timeout);

}  // namespace tinstream::server
