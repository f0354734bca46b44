// HTTPS (config tls_cert / tls_key): a real server on 127.0.0.1 with a certificate the test makes
// (EC P-256, self-signed, for IP 127.0.0.1), fetched over TLS by Beast's SSL stream that verifies
// the certificate and the host. Old protocol versions, plain HTTP on the TLS port and a client that
// never finishes its handshake are refused or closed.
#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/ssl/host_name_verification.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>
#include <chrono>
#include <cstdio>
#include <optional>
#include <thread>

#include "test_support.hpp"
#include "tinstream/server/server.hpp"

namespace tinstream::server {
namespace {

namespace net = boost::asio;
namespace ssl = boost::asio::ssl;
namespace beast = boost::beast;
namespace http = boost::beast::http;
using testing::OpenFilesLimit;
using testing::TempDir;

// Writes key.pem and cert.pem into `dir`: a fresh P-256 key and a self-signed certificate for
// 127.0.0.1 (subjectAltName IP), valid from an hour ago for a day.
void make_certificate(const std::filesystem::path& dir) {
  EVP_PKEY* key = EVP_EC_gen("P-256");
  ASSERT_NE(key, nullptr);
  X509* cert = X509_new();
  ASSERT_NE(cert, nullptr);
  X509_set_version(cert, 2);
  ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
  X509_gmtime_adj(X509_getm_notBefore(cert), -3600);
  X509_gmtime_adj(X509_getm_notAfter(cert), 86400);
  X509_set_pubkey(cert, key);
  X509_NAME* name = X509_get_subject_name(cert);
  X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                             reinterpret_cast<const unsigned char*>("127.0.0.1"), -1, -1, 0);
  X509_set_issuer_name(cert, name);
  X509V3_CTX v3;
  X509V3_set_ctx_nodb(&v3);
  X509V3_set_ctx(&v3, cert, cert, nullptr, nullptr, 0);
  for (auto [nid, value] : {std::pair{NID_subject_alt_name, "IP:127.0.0.1"},
                            {NID_basic_constraints, "critical,CA:TRUE"}}) {
    X509_EXTENSION* ext = X509V3_EXT_conf_nid(nullptr, &v3, nid, value);
    ASSERT_NE(ext, nullptr);
    X509_add_ext(cert, ext, -1);
    X509_EXTENSION_free(ext);
  }
  ASSERT_GT(X509_sign(cert, key, EVP_sha256()), 0);
  FILE* k = std::fopen((dir / "key.pem").c_str(), "wb");
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(PEM_write_PrivateKey(k, key, nullptr, nullptr, 0, nullptr, nullptr), 1);
  std::fclose(k);
  FILE* c = std::fopen((dir / "cert.pem").c_str(), "wb");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(PEM_write_X509(c, cert), 1);
  std::fclose(c);
  X509_free(cert);
  EVP_PKEY_free(key);
}

struct HttpsAnswer {
  bool handshake = false;  // the TLS handshake succeeded
  int protocol = 0;        // the negotiated version (TLS1_2_VERSION, TLS1_3_VERSION)
  std::vector<http::response<http::string_body>> responses;  // in order, one per target
};

// GETs each target over one TLS connection to 127.0.0.1:port, verifying the server's
// certificate against `ca` and its address; `max_version` caps the client's protocol. Every
// operation together is bounded by 20 s.
HttpsAnswer https_get(std::uint16_t port, const std::filesystem::path& ca,
                      const std::vector<std::string>& targets, int max_version = 0) {
  HttpsAnswer out;
  net::io_context ioc;
  ssl::context ctx(ssl::context::tls_client);
  ctx.load_verify_file(ca.string());
  ctx.set_verify_mode(ssl::verify_peer);
  if (max_version != 0) {
    SSL_CTX_set_min_proto_version(ctx.native_handle(), 0);
    SSL_CTX_set_max_proto_version(ctx.native_handle(), max_version);
    SSL_CTX_set_security_level(ctx.native_handle(), 0);  // let the client offer TLS 1.0/1.1
  }
  beast::ssl_stream<beast::tcp_stream> stream(ioc, ctx);
  stream.set_verify_callback(ssl::host_name_verification("127.0.0.1"));
  beast::get_lowest_layer(stream).expires_after(std::chrono::seconds(20));
  beast::error_code ec;
  beast::get_lowest_layer(stream).socket().connect(
      net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), port), ec);
  if (ec) return out;
  stream.async_handshake(ssl::stream_base::client, [&](beast::error_code e) { ec = e; });
  ioc.run();
  if (ec) return out;
  out.handshake = true;
  out.protocol = SSL_version(stream.native_handle());
  beast::flat_buffer buffer;
  for (const auto& target : targets) {
    http::request<http::empty_body> req{http::verb::get, target, 11};
    req.set(http::field::host, "127.0.0.1");
    http::response<http::string_body> res;
    ioc.restart();
    http::async_write(stream, req, [&](beast::error_code e, std::size_t) {
      ec = e;
      if (!e)
        http::async_read(stream, buffer, res, [&](beast::error_code r, std::size_t) { ec = r; });
    });
    ioc.run();
    if (ec) break;
    out.responses.push_back(std::move(res));
  }
  ioc.restart();
  stream.async_shutdown([](beast::error_code) {});
  ioc.run();
  return out;
}

class TlsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    make_certificate(dir_.path);
    testing::write_test_layer(dir_.path / "store.db", "lux");
  }
  void TearDown() override {
    if (server_) server_->stop();
    if (thread_.joinable()) thread_.join();
  }

  ServerConfig config() const {
    ServerConfig c;
    c.address = "127.0.0.1";
    c.port = 0;
    c.store = dir_.path / "store.db";
    c.threads = 2;
    c.log_level = "warn";
    c.access_log = false;
    c.tls_cert = dir_.path / "cert.pem";
    c.tls_key = dir_.path / "key.pem";
    return c;
  }

  void start(const ServerConfig& c) {
    auto s = Server::create(c, {});
    ASSERT_TRUE(s.ok()) << s.error().message;
    server_ = std::move(*s);
    port_ = server_->port();
    thread_ = std::thread([this] { server_->run(false); });
  }

  TempDir dir_{"tls"};
  std::unique_ptr<Server> server_;
  std::thread thread_;
  std::uint16_t port_ = 0;
};

TEST_F(TlsTest, ServesOverHttpsWithTls12OrLater) {
  ServerConfig c = config();
  c.sendfile_min_bytes = 0;  // a cached tile goes out with sendfile(2), into the socket pair
  start(c);
  const auto tile = *geo::TileId::from_zxy(12, 2121, 1401);
  const std::string terrain = "/tiles/lux/12/2121/" + std::to_string(tile.tms_row()) + ".terrain";
  const auto answer =
      https_get(port_, dir_.path / "cert.pem",
                {"/healthz", "/tiles/lux/" + tile.quadkey(), terrain, terrain, "/layers/nope"});
  ASSERT_TRUE(answer.handshake);
  EXPECT_GE(answer.protocol, TLS1_2_VERSION);
  ASSERT_EQ(answer.responses.size(), 5u);  // five requests, one connection (keep-alive)
  EXPECT_EQ(answer.responses[0].result_int(), 200);
  EXPECT_EQ(answer.responses[1].result_int(), 200);
  EXPECT_FALSE(answer.responses[1].body().empty());
  EXPECT_EQ(answer.responses[2].result_int(), 200);
  EXPECT_FALSE(answer.responses[2].body().empty());
  // The second answer of the terrain tile is the cached one (sendfile): the same bytes.
  EXPECT_EQ(answer.responses[3].result_int(), 200);
  EXPECT_EQ(answer.responses[3].body(), answer.responses[2].body());
  EXPECT_EQ(answer.responses[4].result_int(), 404);
}

TEST_F(TlsTest, RefusesOldProtocolsPlainHttpAndStalledHandshakes) {
  ServerConfig c = config();
  c.read_timeout_ms = 500;
  start(c);
  // A client that speaks at most TLS 1.1 gets no connection.
  const auto old = https_get(port_, dir_.path / "cert.pem", {"/healthz"}, TLS1_1_VERSION);
  EXPECT_FALSE(old.handshake);
  // Plain HTTP on the HTTPS port gets no HTTP answer.
  {
    testing::HttpConnection plain(port_);
    EXPECT_EQ(plain.request("GET", "/healthz").status, 0);
  }
  // A client that connects and never starts its handshake is closed after read_timeout_ms
  // (waited for up to 20 s: a loaded machine may be slow, never fast).
  {
    testing::HttpConnection silent(port_);
    EXPECT_TRUE(silent.readable(20000));
    EXPECT_TRUE(silent.closed_by_peer());
  }
  // And the server still serves.
  const auto fine = https_get(port_, dir_.path / "cert.pem", {"/healthz"});
  ASSERT_EQ(fine.responses.size(), 1u);
  EXPECT_EQ(fine.responses[0].result_int(), 200);
}

// A TLS connection holds three descriptors (the TCP socket and the socket pair to its session):
// max_connections stays below the open-files limit counting three per connection, so the server
// never runs out of descriptors for its stores and body files before it refuses connections.
TEST_F(TlsTest, MaxConnectionsCountsThreeDescriptorsPerConnection) {
  const OpenFilesLimit low(256, 512);  // raised to 512 by the server; (512 - 128) / 3 = 128
  ServerConfig c = config();
  c.max_connections = 100000;
  start(c);
  EXPECT_LE(server_->max_connections(), (512u - 128u) / 3);
  EXPECT_GE(server_->max_connections(), 100u);
}

TEST_F(TlsTest, CertificateAndKeyAreCheckedAtStart) {
  ServerConfig c = config();
  c.tls_cert = dir_.path / "missing.pem";
  auto s = Server::create(c, {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("tls_cert"), std::string::npos) << s.error().message;
  c = config();
  c.tls_key = dir_.path / "cert.pem";  // not a key
  s = Server::create(c, {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("tls_key"), std::string::npos) << s.error().message;
  // The config file needs both keys or neither.
  auto half = config_from_json(R"({"tls_cert": "cert.pem"})");
  ASSERT_FALSE(half.ok());
  EXPECT_NE(half.error().message.find("tls_key"), std::string::npos);
  auto both = config_from_json(R"({"tls_cert": "c.pem", "tls_key": "k.pem"})");
  ASSERT_TRUE(both.ok()) << both.error().message;
  EXPECT_EQ(both->tls_key, "k.pem");
}

}  // namespace
}  // namespace tinstream::server
