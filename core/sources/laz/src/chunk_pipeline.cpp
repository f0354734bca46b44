#include "chunk_pipeline.hpp"

#include <exception>

#include "tinstream/base/fault.hpp"

namespace tinstream::laz::detail {

ChunkPipeline::ChunkPipeline(const LaszipVlr& vlr, std::uint16_t record_length,
                             const LayerSelection& layers, int fd, std::vector<ChunkExtent> chunks,
                             unsigned workers)
    : vlr_(vlr),
      record_length_(record_length),
      layers_(layers),
      fd_(fd),
      chunks_(std::move(chunks)) {
  const std::size_t slot_count = std::min<std::size_t>(2 * std::size_t{workers}, chunks_.size());
  slots_.resize(slot_count);
  for (std::size_t s = 0; s < slot_count; ++s) {
    slots_[s].state = SlotState::queued;
    slots_[s].chunk = s;
  }
  for (unsigned w = 0; w < workers && started_.ok(); ++w) {
    started_ = threads_.start([this] { work(); });
  }
}

ChunkPipeline::~ChunkPipeline() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_ready_.notify_all();
  (void)threads_.join();  // work() keeps every failure in its slot
}

Status ChunkPipeline::decode_chunk(ChunkDecoder& decoder, Slot& slot) {
  const ChunkExtent& chunk = chunks_[slot.chunk];
  slot.records.resize(chunk.points * record_length_);
  if (Status st = decoder.begin(chunk); !st.ok()) return st;
  if (Status st = decoder.decode(slot.records.data(), chunk.points); !st.ok()) return st;
  return decoder.finish();
}

void ChunkPipeline::work() {
  std::unique_ptr<ChunkDecoder> decoder;
  for (;;) {
    Slot* slot = nullptr;
    {
      std::unique_lock lock(mutex_);
      work_ready_.wait(lock, [&] {
        if (stop_) return true;
        // The earliest queued chunk first: the reader waits for chunks in order.
        for (Slot& s : slots_) {
          if (s.state == SlotState::queued && (slot == nullptr || s.chunk < slot->chunk)) {
            slot = &s;
          }
        }
        return slot != nullptr;
      });
      if (stop_) return;
      slot->state = SlotState::busy;
    }
    // Exception barrier: nothing thrown here may leave the thread.
    try {
      fault::point("laz.decode");
      if (!decoder) {
        decoder = std::make_unique<ChunkDecoder>(vlr_, record_length_, layers_, fd_);
      }
      slot->status = decode_chunk(*decoder, *slot);
    } catch (const std::bad_alloc&) {
      slot->status = Error(ErrorCode::internal, "out of memory while decoding the chunk");
      decoder.reset();
    } catch (const std::exception& e) {
      slot->status = Error(ErrorCode::internal, std::string("decoding failed: ") + e.what());
      decoder.reset();
    } catch (...) {
      slot->status = Error(ErrorCode::internal, "decoding failed: unknown exception");
      decoder.reset();
    }
    {
      std::lock_guard lock(mutex_);
      slot->state = SlotState::done;
    }
    chunk_done_.notify_all();
  }
}

Result<std::span<const std::uint8_t>> ChunkPipeline::wait(std::size_t index) {
  Slot& slot = slots_[index % slots_.size()];
  std::unique_lock lock(mutex_);
  chunk_done_.wait(lock, [&] { return slot.chunk == index && slot.state == SlotState::done; });
  if (!slot.status.ok()) return slot.status.error();
  return std::span<const std::uint8_t>(slot.records);
}

void ChunkPipeline::release(std::size_t index) {
  Slot& slot = slots_[index % slots_.size()];
  {
    std::lock_guard lock(mutex_);
    slot.chunk = index + slots_.size();
    slot.status = {};
    slot.state = slot.chunk < chunks_.size() ? SlotState::queued : SlotState::idle;
  }
  work_ready_.notify_one();
}

}  // namespace tinstream::laz::detail
