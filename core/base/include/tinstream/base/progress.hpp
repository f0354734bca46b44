// tinstream/base/progress.hpp — how long operations report progress.
//
// A long step calls a ProgressSink with its phase name and how far it is. The CLI renders it on a
// terminal (rate, ETA); the server exposes it as JSON for `GET /admin/jobs/{id}`. A sink may be
// called from worker threads (it must be thread-safe) and should be cheap; producers call it at
// most a few times per second of work. A sink returning false asks the operation to stop
// (it then returns ErrorCode::cancelled).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace tinstream {

struct Progress {
  std::string phase;        // "transform", "sort", "triangulate", "lod", "publish", …
  std::uint64_t done = 0;   // units done in this phase
  std::uint64_t total = 0;  // 0 when unknown
  std::string unit;         // "points", "tiles", "bytes"
};

using ProgressSink = std::function<bool(const Progress&)>;

}  // namespace tinstream
