// ChunkPipeline: worker threads decode whole chunks ahead of the reader, which takes them in
// file order.
//
//   slots (2 per worker):  slot s holds chunk s, then s + K, s + 2K, ...   (K = slot count)
//   state of a slot:       queued --(a worker takes it)--> busy --> done --(reader releases)-->
//                          queued with the chunk K further on (or idle past the last chunk)
//
// Memory: K buffers of at most kMaxParallelChunkBytes (LazReader checks) plus one ChunkDecoder
// per worker. The reader never waits on a worker's lock while the worker decodes: decoding runs
// outside the mutex; the mutex guards only the slot states. Each worker catches everything
// (std::bad_alloc included) and turns it into its chunk's Error; a thread that cannot be created
// is started() 's Error, never std::terminate (the workers already running are stopped and
// joined by the destructor). Fault points (fault.hpp): laz.decode (one chunk), laz.decode.spawn.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <span>
#include <vector>

#include "chunk_decoder.hpp"
#include "tinstream/base/worker_threads.hpp"

namespace tinstream::laz::detail {

class ChunkPipeline {
 public:
  ChunkPipeline(const LaszipVlr& vlr, std::uint16_t record_length, const LayerSelection& layers,
                int fd, std::vector<ChunkExtent> chunks, unsigned workers);
  ~ChunkPipeline();  // stops and joins the workers
  // Whether every worker started: an Error when a thread could not be created (the reader must
  // not wait on this pipeline then).
  const Status& started() const { return started_; }
  ChunkPipeline(const ChunkPipeline&) = delete;
  ChunkPipeline& operator=(const ChunkPipeline&) = delete;

  // Waits for chunk `index` (the reader asks in order) and returns its records, valid until
  // release(index), or the Error its decoding met (a phrase without the file and chunk).
  Result<std::span<const std::uint8_t>> wait(std::size_t index);
  void release(std::size_t index);

 private:
  enum class SlotState { idle, queued, busy, done };
  struct Slot {
    SlotState state = SlotState::idle;
    std::size_t chunk = 0;
    std::vector<std::uint8_t> records;  // guarded by the state: only its owner touches it
    Status status;
  };
  void work();
  Status decode_chunk(ChunkDecoder& decoder, Slot& slot);

  const LaszipVlr vlr_;
  const std::uint16_t record_length_;
  const LayerSelection layers_;
  const int fd_;
  const std::vector<ChunkExtent> chunks_;

  std::mutex mutex_;
  std::condition_variable work_ready_;  // a slot was queued, or stop
  std::condition_variable chunk_done_;  // a slot became done
  std::vector<Slot> slots_;             // states guarded by mutex_
  bool stop_ = false;                   // guarded by mutex_
  Status started_;
  WorkerThreads threads_{"LAZ chunk decoder", "laz.decode"};  // last: joined first
};

}  // namespace tinstream::laz::detail
