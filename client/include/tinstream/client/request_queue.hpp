// tinstream/client/request_queue.hpp — the download requests, in the order the view needs them.
//
// The render thread replaces the whole queue once per frame with what the current view still
// lacks (replace()): a request queued before and no longer wanted is dropped before it is sent.
// Workers pop the most urgent request: the highest priority (the screen-space error of the tile
// that asks for it, so larger errors and nearer tiles first, and an ancestor always before its
// descendants, which are only asked for once it is drawn), then the nearest, then the key. A tile
// popped by one worker is "in flight" until finish(), which the loader calls when the render
// thread takes the tile's result; pop() never hands out a tile in flight, and replace() leaves
// it out but raises its in-flight priority to the one wanted now (in_flight_priority: a
// prefetched tile the view needs while it downloads is decoded as needed).
//
// Threads: replace() and finish() from one thread (the render thread), pop() from workers. The lock
// is held for a swap, a hash lookup per queued request or a pop, never during I/O.
#pragma once

#include <array>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include "tinstream/client/tile_key.hpp"

namespace tinstream::client {

struct TileRequest {
  TileKey key;
  double priority = 0;  // larger first
  double distance = 0;  // metres; nearer first among equal priorities
};

// Strict weak order "a is less urgent than b".
bool less_urgent(const TileRequest& a, const TileRequest& b);

class RequestQueue {
 public:
  // Replaces the queue by `wanted` (any order; duplicates and tiles in flight are left out).
  // Returns how many previously queued requests are not wanted any more (dropped, never sent).
  std::size_t replace(std::vector<TileRequest> wanted);
  // Blocks until worker `worker` may run (worker < active workers, not paused) and a request is
  // queued; returns it, now in flight. nullopt once close() was called.
  std::optional<TileRequest> pop(std::size_t worker);
  // The tiles are no longer in flight (their results reached the render thread).
  void finish(std::span<const TileKey> keys);
  // The larger of `priority` and the most urgent priority asked for `key` while in flight (its
  // pop's, raised by later replace() calls that wanted it); `priority` when not in flight.
  double in_flight_priority(const TileKey& key, double priority) const;

  void set_active_workers(std::size_t n);
  void set_paused(bool paused);
  void close();

  std::size_t queued() const;
  std::size_t in_flight() const;
  // Tiles in flight per quadtree level (index: level).
  std::array<std::uint32_t, 31> in_flight_per_level() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<TileRequest> queue_;  // guarded by mutex_; ascending urgency: the next at the back
  // The tiles in flight, each with the most urgent priority asked for it; guarded by mutex_.
  std::unordered_map<TileKey, double, TileKeyHash> in_flight_;
  std::size_t active_ = 1;                // guarded by mutex_
  bool paused_ = false, closed_ = false;  // guarded by mutex_
};

}  // namespace tinstream::client
