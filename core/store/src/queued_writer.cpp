#include "tinstream/store/queued_writer.hpp"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

#include "tinstream/base/worker_threads.hpp"

namespace tinstream::store {

struct QueuedWriter::Impl {
  using Occupancy = QueuedWriter::Occupancy;
  LayerWriter& writer;
  const std::size_t capacity;
  const std::size_t max_bytes;
  std::mutex mutex;  // guards the members below
  std::condition_variable ready, space;
  std::deque<StoredTile> queue;
  std::size_t queued_bytes = 0;  // Σ compressed sizes in `queue`
  bool closed = false;
  Status failure;
  std::uint64_t stored = 0;
  Occupancy peak;                                      // the most ever queued
  WorkerThreads thread{"store queue", "store.queue"};  // last: started once the rest exists

  Impl(LayerWriter& w, std::size_t c, std::size_t b)
      : writer(w), capacity(std::max<std::size_t>(c, 1)), max_bytes(b) {
    // A thread that cannot start is the queue's first error: push() and finish() return it.
    if (Status s = thread.start([this] { run(); }); !s) failure = std::move(s);
  }

  void run() {
    for (;;) {
      StoredTile tile;
      {
        std::unique_lock lock(mutex);
        ready.wait(lock, [&] { return !queue.empty() || closed; });
        if (queue.empty()) return;
        tile = std::move(queue.front());
        queue.pop_front();
        queued_bytes -= tile.compressed.size();
        space.notify_all();  // a freed byte budget may let several pushes in
      }
      // The exception barrier: whatever put() throws is the queue's error like a store error.
      // Fault point "store.queue": one put.
      Status s = guarded("store queue", [&]() -> Status {
        fault::point("store.queue");
        return writer.put(std::move(tile));
      });
      std::lock_guard lock(mutex);
      if (!s.ok()) {
        failure = std::move(s);
        queue.clear();
        queued_bytes = 0;
        space.notify_all();
        return;
      }
      ++stored;
    }
  }
};

QueuedWriter::QueuedWriter(LayerWriter& writer, std::size_t capacity, std::size_t max_bytes)
    : impl_(std::make_unique<Impl>(writer, capacity, max_bytes)) {}

QueuedWriter::~QueuedWriter() { (void)finish(); }

Status QueuedWriter::push(StoredTile&& tile) {
  std::unique_lock lock(impl_->mutex);
  const std::size_t bytes = tile.compressed.size();
  impl_->space.wait(lock, [&] {
    const bool room = impl_->queue.empty() ||
                      (impl_->queue.size() < impl_->capacity &&
                       bytes <= impl_->max_bytes - std::min(impl_->queued_bytes, impl_->max_bytes));
    return room || !impl_->failure.ok() || impl_->closed;
  });
  if (!impl_->failure.ok()) return impl_->failure;
  if (impl_->closed) return invalid_argument("QueuedWriter: push() after finish()");
  impl_->queue.push_back(std::move(tile));
  impl_->queued_bytes += bytes;
  impl_->peak.tiles = std::max(impl_->peak.tiles, impl_->queue.size());
  impl_->peak.bytes = std::max(impl_->peak.bytes, impl_->queued_bytes);
  impl_->ready.notify_one();
  return {};
}

Status QueuedWriter::finish() {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->closed = true;
    impl_->ready.notify_one();
    impl_->space.notify_all();
  }
  (void)impl_->thread.join();  // run() keeps its own failures
  std::lock_guard lock(impl_->mutex);
  return impl_->failure;
}

QueuedWriter::Occupancy QueuedWriter::queued() const {
  std::lock_guard lock(impl_->mutex);
  return {impl_->queue.size(), impl_->queued_bytes};
}

QueuedWriter::Occupancy QueuedWriter::peak() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->peak;
}

std::uint64_t QueuedWriter::stored() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stored;
}

}  // namespace tinstream::store
