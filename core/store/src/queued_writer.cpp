#include "tinstream/store/queued_writer.hpp"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

namespace tinstream::store {

struct QueuedWriter::Impl {
  LayerWriter& writer;
  const std::size_t capacity;
  std::mutex mutex;  // guards the members below
  std::condition_variable ready, space;
  std::deque<StoredTile> queue;
  bool closed = false;
  Status failure;
  std::uint64_t stored = 0;
  std::thread thread;  // last: started once the members above exist

  Impl(LayerWriter& w, std::size_t c)
      : writer(w), capacity(std::max<std::size_t>(c, 1)), thread([this] { run(); }) {}

  void run() {
    for (;;) {
      StoredTile tile;
      {
        std::unique_lock lock(mutex);
        ready.wait(lock, [&] { return !queue.empty() || closed; });
        if (queue.empty()) return;
        tile = std::move(queue.front());
        queue.pop_front();
        space.notify_one();
      }
      Status s = writer.put(std::move(tile));
      std::lock_guard lock(mutex);
      if (!s.ok()) {
        failure = std::move(s);
        queue.clear();
        space.notify_all();
        return;
      }
      ++stored;
    }
  }
};

QueuedWriter::QueuedWriter(LayerWriter& writer, std::size_t capacity)
    : impl_(std::make_unique<Impl>(writer, capacity)) {}

QueuedWriter::~QueuedWriter() { (void)finish(); }

Status QueuedWriter::push(StoredTile&& tile) {
  std::unique_lock lock(impl_->mutex);
  impl_->space.wait(lock, [&] {
    return impl_->queue.size() < impl_->capacity || !impl_->failure.ok() || impl_->closed;
  });
  if (!impl_->failure.ok()) return impl_->failure;
  if (impl_->closed) return invalid_argument("QueuedWriter: push() after finish()");
  impl_->queue.push_back(std::move(tile));
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
  if (impl_->thread.joinable()) impl_->thread.join();
  std::lock_guard lock(impl_->mutex);
  return impl_->failure;
}

std::uint64_t QueuedWriter::stored() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stored;
}

}  // namespace tinstream::store
