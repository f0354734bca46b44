#include "tinstream/server/config.hpp"

#include <cstdlib>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "address_ranges.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;

template <typename T>
Status read_uint(const json& j, const char* key, T& out) {
  if (!j.contains(key)) return {};
  const json& v = j.at(key);
  if (!v.is_number_unsigned() ||
      v.get<std::uint64_t>() > static_cast<std::uint64_t>(std::numeric_limits<T>::max())) {
    return invalid_argument(std::string("config key \"") + key +
                            "\": expected an unsigned integer in range");
  }
  out = static_cast<T>(v.get<std::uint64_t>());
  return {};
}

Status read_string(const json& j, const char* key, std::string& out) {
  if (!j.contains(key)) return {};
  if (!j.at(key).is_string()) {
    return invalid_argument(std::string("config key \"") + key + "\": expected a string");
  }
  out = j.at(key).get<std::string>();
  return {};
}

Status read_path(const json& j, const char* key, std::filesystem::path& out) {
  std::string s = out.string();
  if (Status st = read_string(j, key, s); !st) return st;
  out = s;
  return {};
}

}  // namespace

Result<ServerConfig> config_from_json(std::string_view text) {
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false, /*ignore_comments=*/true);
  if (j.is_discarded()) return invalid_argument("config: not valid JSON");
  if (!j.is_object()) return invalid_argument("config: expected a JSON object");
  static const char* kKeys[] = {"address",
                                "port",
                                "store",
                                "threads",
                                "admin_token",
                                "admin_token_env",
                                "data_root",
                                "upload_dir",
                                "max_upload_bytes",
                                "max_header_bytes",
                                "max_body_bytes",
                                "max_connections",
                                "max_connections_per_ip",
                                "linger_ms",
                                "read_timeout_ms",
                                "write_timeout_ms",
                                "cache_max_age_s",
                                "cors_allow_origin",
                                "admin_address",
                                "admin_port",
                                "admin_allow",
                                "terrain_cache_bytes",
                                "sendfile",
                                "sendfile_min_bytes",
                                "max_queued_jobs",
                                "shutdown_grace_ms",
                                "log_level",
                                "access_log",
                                "tls_cert",
                                "tls_key"};
  for (const auto& [key, value] : j.items()) {
    bool known = false;
    for (const char* k : kKeys) known = known || key == k;
    if (!known) return invalid_argument("config: unknown key \"" + key + "\"");
  }
  ServerConfig c;
  Status st;
  if (!(st = read_string(j, "address", c.address))) return st.error();
  if (!(st = read_uint(j, "port", c.port))) return st.error();
  if (!(st = read_path(j, "store", c.store))) return st.error();
  if (!(st = read_uint(j, "threads", c.threads))) return st.error();
  if (!(st = read_string(j, "admin_token", c.admin_token))) return st.error();
  if (!(st = read_string(j, "admin_token_env", c.admin_token_env))) return st.error();
  if (!(st = read_path(j, "data_root", c.data_root))) return st.error();
  if (!(st = read_path(j, "upload_dir", c.upload_dir))) return st.error();
  if (!(st = read_uint(j, "max_upload_bytes", c.max_upload_bytes))) return st.error();
  if (!(st = read_uint(j, "max_header_bytes", c.max_header_bytes))) return st.error();
  if (!(st = read_uint(j, "max_body_bytes", c.max_body_bytes))) return st.error();
  if (!(st = read_uint(j, "max_connections", c.max_connections))) return st.error();
  if (!(st = read_uint(j, "max_connections_per_ip", c.max_connections_per_ip))) return st.error();
  if (!(st = read_uint(j, "linger_ms", c.linger_ms))) return st.error();
  if (!(st = read_uint(j, "read_timeout_ms", c.read_timeout_ms))) return st.error();
  if (!(st = read_uint(j, "write_timeout_ms", c.write_timeout_ms))) return st.error();
  if (!(st = read_uint(j, "cache_max_age_s", c.cache_max_age_s))) return st.error();
  if (!(st = read_string(j, "cors_allow_origin", c.cors_allow_origin))) return st.error();
  if (!(st = read_string(j, "admin_address", c.admin_address))) return st.error();
  if (!(st = read_uint(j, "admin_port", c.admin_port))) return st.error();
  if (j.contains("admin_allow")) {
    const json& list = j["admin_allow"];
    if (!list.is_array()) return invalid_argument("config key \"admin_allow\": expected an array");
    for (const json& item : list) {
      if (!item.is_string())
        return invalid_argument("config key \"admin_allow\": expected IP addresses or ranges");
      auto range = AddressRange::parse(item.get<std::string>());
      if (!range) return invalid_argument("config key \"admin_allow\": " + range.error().message);
      c.admin_allow.push_back(item.get<std::string>());
    }
  }
  if (!(st = read_uint(j, "terrain_cache_bytes", c.terrain_cache_bytes))) return st.error();
  if (!(st = read_uint(j, "sendfile_min_bytes", c.sendfile_min_bytes))) return st.error();
  if (!(st = read_uint(j, "max_queued_jobs", c.max_queued_jobs))) return st.error();
  if (!(st = read_uint(j, "shutdown_grace_ms", c.shutdown_grace_ms))) return st.error();
  if (!(st = read_string(j, "log_level", c.log_level))) return st.error();
  if (!(st = read_path(j, "tls_cert", c.tls_cert))) return st.error();
  if (!(st = read_path(j, "tls_key", c.tls_key))) return st.error();
  if (c.tls_cert.empty() != c.tls_key.empty()) {
    return invalid_argument(
        "config keys \"tls_cert\" and \"tls_key\": set both (HTTPS) or neither");
  }
  for (auto [key, flag] : {std::pair{"access_log", &c.access_log}, {"sendfile", &c.sendfile}}) {
    if (!j.contains(key)) continue;
    if (!j[key].is_boolean()) {
      return invalid_argument(std::string("config key \"") + key + "\": expected true/false");
    }
    *flag = j[key].get<bool>();
  }
  if (c.max_header_bytes < 512)
    return invalid_argument("config key \"max_header_bytes\": at least 512");
  if (c.max_connections == 0) return invalid_argument("config key \"max_connections\": at least 1");
  if (c.read_timeout_ms == 0 || c.write_timeout_ms == 0) {
    return invalid_argument("config: timeouts must be positive");
  }
  static const char* kLevels[] = {"trace", "debug", "info", "warn", "error", "critical", "off"};
  bool level_ok = false;
  for (const char* l : kLevels) level_ok = level_ok || c.log_level == l;
  if (!level_ok)
    return invalid_argument("config key \"log_level\": unknown level \"" + c.log_level + "\"");
  return c;
}

Result<ServerConfig> load_config(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return io_error("config: cannot open " + path.string());
  std::stringstream ss;
  ss << in.rdbuf();
  auto c = config_from_json(ss.str());
  if (!c) return Error(c.error().code, path.string() + ": " + c.error().message);
  return c;
}

std::string resolve_admin_token(const ServerConfig& config) {
  if (!config.admin_token.empty()) return config.admin_token;
  if (!config.admin_token_env.empty()) {
    if (const char* v = std::getenv(config.admin_token_env.c_str())) return v;
  }
  return {};
}

}  // namespace tinstream::server
