// tinstream/store/queued_writer.hpp — a LayerWriter fed by several threads through a bounded
// queue and drained by one thread of its own.
//
// Workers prepare tiles (store::prepare_tile: encoding and compression, the CPU-heavy part) and
// push() them; the queue's thread put()s them into the LayerWriter, so no worker waits while
// SQLite commits a batch (and checkpoints the WAL). push() waits only while `capacity` tiles, or
// `max_bytes` of compressed tiles, are queued (a tile larger than max_bytes alone still goes in
// once the queue is empty). The first store error stops the queue: the next push() and finish()
// return it. An exception thrown by the store, or a queue thread that cannot be started, is such
// an error too (fault points "store.queue" and "store.queue.spawn").
#pragma once

#include <cstdint>
#include <memory>

#include "tinstream/base/result.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::store {

class QueuedWriter {
 public:
  // `writer` must outlive the QueuedWriter and not be used by others until finish() returned.
  QueuedWriter(LayerWriter& writer, std::size_t capacity,
               std::size_t max_bytes = static_cast<std::size_t>(-1));
  QueuedWriter(const QueuedWriter&) = delete;
  QueuedWriter& operator=(const QueuedWriter&) = delete;
  ~QueuedWriter();  // finish()es

  // Thread-safe.
  Status push(StoredTile&& tile);
  // Stores what is queued and stops the thread; the first store error, if any. Idempotent.
  Status finish();
  // Tiles stored so far (exact after finish()).
  std::uint64_t stored() const;
  // What waits in the queue (tiles not yet taken by its thread), now and at most so far.
  struct Occupancy {
    std::size_t tiles = 0;
    std::size_t bytes = 0;
  };
  Occupancy queued() const;
  Occupancy peak() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tinstream::store
