#include "tinstream/client/request_queue.hpp"

#include <algorithm>
#include <tuple>
#include <unordered_set>

namespace tinstream::client {

namespace {

// The keys' order, member by member as TileKey's defaulted <=> (spelled out: clang-tidy reports
// modernize-use-nullptr inside synthesised three-way comparisons).
auto key_order(const TileKey& k) {
  return std::tuple(static_cast<int>(k.kind), k.layer, k.tile.z, k.tile.x, k.tile.y);
}

}  // namespace

bool less_urgent(const TileRequest& a, const TileRequest& b) {
  // Larger priority is more urgent; then smaller distance; then the key (determinism).
  return std::tuple(a.priority, b.distance, key_order(b.key)) <
         std::tuple(b.priority, a.distance, key_order(a.key));
}

std::size_t RequestQueue::replace(std::vector<TileRequest> wanted) {
  // Sort and de-duplicate outside the lock.
  std::sort(wanted.begin(), wanted.end(), [](const TileRequest& a, const TileRequest& b) {
    return key_order(a.key) < key_order(b.key);
  });
  wanted.erase(
      std::unique(wanted.begin(), wanted.end(),
                  [](const TileRequest& a, const TileRequest& b) { return a.key == b.key; }),
      wanted.end());
  std::unordered_set<TileKey, TileKeyHash> keys;
  keys.reserve(wanted.size());
  for (const TileRequest& r : wanted) keys.insert(r.key);
  std::sort(wanted.begin(), wanted.end(), less_urgent);

  std::vector<TileRequest> old;
  {
    std::lock_guard lock(mutex_);
    // A tile in flight is not queued again, but the view's present need raises its priority
    // (for its decode: in_flight_priority).
    std::erase_if(wanted, [&](const TileRequest& r) {
      const auto it = in_flight_.find(r.key);
      if (it == in_flight_.end()) return false;
      if (r.priority > it->second) it->second = r.priority;  // (a NaN raises nothing)
      return true;
    });
    old.swap(queue_);
    queue_ = std::move(wanted);
  }
  ready_.notify_all();
  return static_cast<std::size_t>(std::count_if(
      old.begin(), old.end(), [&](const TileRequest& r) { return !keys.contains(r.key); }));
}

std::optional<TileRequest> RequestQueue::pop(std::size_t worker) {
  std::unique_lock lock(mutex_);
  for (;;) {
    ready_.wait(lock, [&] { return closed_ || (!paused_ && worker < active_ && !queue_.empty()); });
    if (closed_) return std::nullopt;
    TileRequest r = queue_.back();
    queue_.pop_back();
    if (in_flight_.emplace(r.key, r.priority).second) return r;
  }
}

void RequestQueue::finish(std::span<const TileKey> keys) {
  std::lock_guard lock(mutex_);
  for (const TileKey& k : keys) in_flight_.erase(k);
}

void RequestQueue::set_active_workers(std::size_t n) {
  {
    std::lock_guard lock(mutex_);
    active_ = n;
  }
  ready_.notify_all();
}

void RequestQueue::set_paused(bool paused) {
  {
    std::lock_guard lock(mutex_);
    paused_ = paused;
  }
  ready_.notify_all();
}

void RequestQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

std::size_t RequestQueue::queued() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

double RequestQueue::in_flight_priority(const TileKey& key, double priority) const {
  std::lock_guard lock(mutex_);
  const auto it = in_flight_.find(key);
  return it != in_flight_.end() && it->second > priority ? it->second : priority;
}

std::size_t RequestQueue::in_flight() const {
  std::lock_guard lock(mutex_);
  return in_flight_.size();
}

std::array<std::uint32_t, 31> RequestQueue::in_flight_per_level() const {
  std::array<std::uint32_t, 31> levels{};
  std::lock_guard lock(mutex_);
  for (const auto& [k, priority] : in_flight_) ++levels[k.tile.z];
  return levels;
}

}  // namespace tinstream::client
