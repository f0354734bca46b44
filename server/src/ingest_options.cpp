#include "tinstream/server/ingest_options.hpp"

#include <cmath>
#include <string>
#include <string_view>

#include "tinstream/server/ingest_paths.hpp"

namespace tinstream::server {
namespace {

using nlohmann::json;

Error bad(std::string_view key, std::string_view expected) {
  return invalid_argument("ingest option \"" + std::string(key) + "\": expected " +
                          std::string(expected));
}

// An integer in [lo, hi]: JSON integers only (no 2.5, no "3"), negative ones checked before any
// unsigned conversion.
Status integer_in(const json& v, std::string_view key, std::int64_t lo, std::int64_t hi) {
  const std::string range = "an integer " + std::to_string(lo) + "-" + std::to_string(hi);
  if (!v.is_number_integer()) return bad(key, range);
  if (v.is_number_unsigned()) {  // how a parser reads every non-negative integer
    const std::uint64_t n = v.get<std::uint64_t>();
    if (n > static_cast<std::uint64_t>(hi) || static_cast<std::int64_t>(n) < lo)
      return bad(key, range);
    return {};
  }
  const std::int64_t n = v.get<std::int64_t>();
  if (n < lo || n > hi) return bad(key, range);
  return {};
}

// AUTHORITY:CODE, or WKT (a keyword and a bracket); no PROJ string.
bool crs_ok(std::string_view s) {
  if (s.empty()) return true;  // the file's own CRS
  if (s.size() > 8192 || s.find('+') != std::string_view::npos) return false;
  const auto colon = s.find(':');
  if (colon != std::string_view::npos && colon > 0 && colon + 1 < s.size()) {
    bool simple = true;
    for (char c : s) {
      simple = simple && ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                          (c >= '0' && c <= '9') || c == ':' || c == '_');
    }
    if (simple) return true;
  }
  const auto bracket = s.find_first_of("[(");
  if (bracket == std::string_view::npos || bracket == 0) return false;
  for (char c : s.substr(0, bracket)) {
    if (!((c >= 'A' && c <= 'Z') || c == '_' || (c >= '0' && c <= '9'))) return false;
  }
  return true;
}

}  // namespace

Status validate_ingest_options(const json& o) {
  if (!o.is_object()) return invalid_argument("ingest options: expected a JSON object");
  for (const auto& [key, v] : o.items()) {
    if (key == "projection") {
      if (!v.is_string() || (v != "spherical" && v != "ellipsoidal"))
        return bad(key, "\"spherical\" or \"ellipsoidal\"");
    } else if (key == "max_points") {
      if (Status s = integer_in(v, key, 3, 65535); !s) return s;
    } else if (key == "max_level" || key == "min_level") {
      if (Status s = integer_in(v, key, 0, 30); !s) return s;
    } else if (key == "epsilon") {
      if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0 ||
          v.get<double>() > 10000)
        return bad(key, "a number 0-10000 (metres)");
    } else if (key == "pyramid" || key == "skip_invalid") {
      if (!v.is_boolean()) return bad(key, "true or false");
    } else if (key == "memory_mb") {
      if (Status s = integer_in(v, key, 16, 16384); !s) return s;
    } else if (key == "threads") {
      if (Status s = integer_in(v, key, 0, kMaxIngestThreads); !s) return s;
    } else if (key == "attribution") {
      if (!v.is_string() || v.get_ref<const std::string&>().size() > 1000)
        return bad(key, "a string of at most 1000 bytes");
    } else if (key == "crs") {
      if (!v.is_string() || !crs_ok(v.get_ref<const std::string&>()))
        return bad(key, "AUTHORITY:CODE (EPSG:2169) or WKT; PROJ strings are not accepted");
    } else if (key == "vertical") {
      if (!v.is_string() || !sanitize_filename(v.get_ref<const std::string&>()).ok())
        return bad(key, "a datum or geoid grid name ([A-Za-z0-9_.-], no path)");
    } else if (key == "z_units") {
      if (!v.is_string() || v.get_ref<const std::string&>().size() > 32)
        return bad(key, "a unit name (metre, foot, us-foot)");
    } else {
      return invalid_argument("ingest option \"" + key + "\" is unknown");
    }
  }
  const auto level = [&](const char* key, std::int64_t fallback) {
    return o.contains(key) ? o[key].get<std::int64_t>() : fallback;
  };
  if (level("min_level", 0) > level("max_level", 24)) {
    return invalid_argument("ingest option \"min_level\" is above \"max_level\" (default 24)");
  }
  return {};
}

}  // namespace tinstream::server
