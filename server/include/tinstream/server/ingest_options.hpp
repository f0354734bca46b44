// tinstream/server/ingest_options.hpp — the "options" object of an admin ingest, checked before a
// job is queued. Pure; thread-safe.
//
// Every key is optional; unknown keys are refused. Ranges (a value outside is refused with an
// error naming the key and the range):
//   projection    "spherical" | "ellipsoidal"
//   max_points    integer 3 … 65535             max_level, min_level   integers 0 … 30,
//   epsilon       number 0 … 10000 (metres)     min_level ≤ max_level (default max_level 24)
//   pyramid, skip_invalid   true | false
//   memory_mb     integer 16 … 16384            threads  integer 0 … kMaxIngestThreads (0: all
//   cores) attribution   string of at most 1000 bytes crs           "AUTHORITY:CODE" (EPSG:2169) or
//   WKT; never a PROJ string ('+' is refused: PROJ
//                 strings can name files, +init=, +grids=)
//   vertical      a datum or geoid grid name: [A-Za-z0-9_.-], 1-100, not starting with '.'
//                 (no path, no PROJ syntax)
//   z_units       string of at most 32 bytes (the ingest knows the unit names)
#pragma once

#include <nlohmann/json.hpp>

#include "tinstream/base/result.hpp"

namespace tinstream::server {

inline constexpr unsigned kMaxIngestThreads = 64;

// invalid_argument naming the first key that is wrong.
Status validate_ingest_options(const nlohmann::json& options);

}  // namespace tinstream::server
