// tinstream/server/config.hpp — the server's configuration (config/server.json).
//
// The file is JSON (comments allowed); every key is optional and unknown keys are an error, so a
// typo never silently falls back to a default. Command-line options override the file. Relative
// paths are relative to the working directory. server/README-section.md documents every key.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::server {

struct ServerConfig {
  std::string address = "0.0.0.0";
  std::uint16_t port = 8080;  // 0: any free port (tests)
  std::filesystem::path store = "tinstream.db";
  unsigned threads = 0;     // io threads; 0: one per core
  std::string admin_token;  // literal bearer token (prefer admin_token_env)
  std::string admin_token_env = "TINSTREAM_ADMIN_TOKEN";  // env var holding the token
  std::filesystem::path data_root;   // server-side ingest sources must be under it; empty: off
  std::filesystem::path upload_dir;  // uploaded sources are streamed here; empty: off
  std::uint64_t max_upload_bytes = 1ull << 30;
  // Uploads in progress plus upload files waiting for their job, all together (507 beyond).
  std::uint64_t max_upload_total_bytes = 4ull << 30;
  // An upload must leave this much free on upload_dir's file system (507 otherwise).
  std::uint64_t upload_min_free_bytes = 256ull << 20;
  // An upload body may take longer than read_timeout_ms while it arrives at this average rate
  // (and never pauses for read_timeout_ms).
  std::uint32_t upload_min_bytes_per_s = 16384;
  std::uint32_t max_header_bytes = 8192;
  std::uint64_t max_body_bytes = 1u << 20;     // non-upload request bodies
  std::uint32_t max_connections = 1024;        // kept below the open-files limit (Server::create)
  std::uint32_t max_connections_per_ip = 256;  // 0: no per-address cap
  std::uint32_t linger_ms = 1000;  // closing: at most this long draining what the client sends
  std::uint32_t read_timeout_ms = 30000;   // per request header (then body), idle time included
  std::uint32_t write_timeout_ms = 30000;  // per response write
  std::uint32_t cache_max_age_s = 86400;   // Cache-Control max-age for tiles
  std::string cors_allow_origin = "*";     // empty: no CORS headers
  // Admin API and metrics on a second listener (address:port) instead of the public one; empty
  // address: on the public listener.
  std::string admin_address;
  std::uint16_t admin_port = 8081;
  // Addresses (IPs or CIDR ranges, IPv4 or IPv6) allowed to reach /admin and /metrics; empty:
  // any address (the admin API still needs its token).
  std::vector<std::string> admin_allow;
  std::uint64_t terrain_cache_bytes = 64u << 20;  // LRU of encoded .terrain tiles; 0: off
  // Cached bodies of at least this many bytes are sent with sendfile(2) from a memory file
  // (server/src/body_file.hpp) instead of being copied into the socket; 0: every cached body.
  std::uint64_t sendfile_min_bytes = 16384;
  bool sendfile = true;
  std::uint32_t max_queued_jobs = 8;        // ingest jobs waiting or running
  std::uint32_t shutdown_grace_ms = 10000;  // in-flight responses get this long on SIGTERM
  // HTTPS: with both set, every listener (the admin one included) speaks TLS 1.2 or later with
  // this certificate chain and private key (PEM files); both empty: plain HTTP/1.1 (loopback,
  // or behind a proxy that terminates TLS).
  std::filesystem::path tls_cert;
  std::filesystem::path tls_key;
  std::string log_level = "info";  // trace, debug, info, warn, error, critical, off
  bool access_log = true;          // one line per request at info level
};

// Parses configuration JSON over the defaults. Errors name the key.
Result<ServerConfig> config_from_json(std::string_view text);
// Reads and parses a configuration file. Errors name the file.
Result<ServerConfig> load_config(const std::filesystem::path& path);
// The admin token: `admin_token` if set, else the value of the environment variable named by
// `admin_token_env`, else empty (admin API disabled).
std::string resolve_admin_token(const ServerConfig& config);

}  // namespace tinstream::server
