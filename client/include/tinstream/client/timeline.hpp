// tinstream/client/timeline.hpp — when each tile went through each step of streaming (a debug
// record for `tinstream-viewer --timeline FILE`, bench/client).
//
//   prefetched / needed ─▶ sent ─▶ headers ─▶ body ─▶ decode_start ─▶ decoded ─▶ taken ─▶ uploaded
//   (render thread:         (download worker: popped, HTTP answer's headers and   (render thread:
//    first asked for)        body read; decoder: job taken, mesh built)           result, GPU)
//
// The first time of each step per tile is kept (seconds since the timeline was made); a step a
// tile never went through stays absent. Thread-safe: the render thread and the workers record
// into it under one mutex (a hash lookup), only when a timeline was asked for — without one the
// loader and the streamer hold a null pointer and record nothing.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <ostream>
#include <unordered_map>

#include "tinstream/client/tile_key.hpp"

namespace tinstream::client {

enum class TileEvent : std::uint8_t {
  prefetched,    // first asked for ahead of a missing ancestor (streamer)
  needed,        // first asked for because the view needs it (streamer)
  sent,          // a download worker took the request (before the disk cache and the fetch)
  headers,       // the answer's headers were read (HTTP; the store: the body below)
  body,          // the whole answer was read
  decode_start,  // a decoder took the payload
  decoded,       // the mesh was built (or the decode failed)
  taken,         // the render thread took the result
  uploaded,      // the mesh reached the GPU tier
};
inline constexpr std::size_t kTileEvents = 9;

class RequestTimeline {
 public:
  using Clock = std::chrono::steady_clock;
  RequestTimeline() : start_(Clock::now()) {}

  // Keeps the first time of `event` for `key` (later ones are ignored).
  void record(const TileKey& key, TileEvent event, Clock::time_point when = Clock::now());
  // The priority the request had when a worker took it (negative: a prefetch).
  void record_priority(const TileKey& key, double priority);
  // One JSON object a line per tile, in the order of first record: {"kind", "layer", "z", "x",
  // "y", "quadkey", "priority", then each step's seconds, absent steps left out}.
  void write(std::ostream& out) const;
  std::size_t size() const;

 private:
  struct Entry {
    std::uint64_t order = 0;
    std::array<double, kTileEvents> at{};  // seconds; < 0: not seen
    double priority = 0;
    bool has_priority = false;
  };
  Entry& entry(const TileKey& key);  // Requires: mutex_ held

  const Clock::time_point start_;
  mutable std::mutex mutex_;
  std::unordered_map<TileKey, Entry, TileKeyHash> tiles_;  // guarded by mutex_
};

std::string_view to_string(TileEvent event);

}  // namespace tinstream::client
