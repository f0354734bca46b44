// LazReader: chunk layout + sequential decoding on the calling thread, or a pipeline of worker
// threads decoding whole chunks ahead (chunk_pipeline) handed out in file order.
#include "tinstream/laz/laz_reader.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>
#include <thread>

#include "chunk_decoder.hpp"
#include "chunk_pipeline.hpp"
#include "chunk_table.hpp"

namespace tinstream::laz {

using detail::ChunkDecoder;
using detail::ChunkExtent;

struct LazReader::State {
  std::string path;
  PointDataLayout layout;
  LaszipVlr vlr;
  ReaderOptions options;
  int fd = -1;
  detail::ChunkLayout chunks;
  std::uint64_t expected_chunks = 0;  // for messages ("chunk 3 of 14")
  unsigned threads = 1;

  // Sequential decoding. For item lists that decode in lock step (ChunkDecoder::pairs_with),
  // `partner` decodes the next chunk beside `decoder`, record for record, into `ahead`; when
  // `decoder`'s chunk is done the reader hands out `ahead` (as `slot`) and then begins the chunk
  // after it. Error semantics stay those of one chunk at a time: a failure of the partner's
  // chunk is reported when the reader reaches that chunk.
  std::unique_ptr<ChunkDecoder> decoder;
  bool in_chunk = false;
  std::unique_ptr<ChunkDecoder> partner;
  bool partnered = false;           // partner is decoding chunk + 1 beside decoder
  std::vector<std::uint8_t> ahead;  // chunk + 1's records, partner's output
  std::uint64_t ahead_records = 0;  // of them decoded so far
  Status ahead_status;              // the partner's first error, reported at chunk + 1
  bool serving_ahead = false;       // slot is `ahead`: chunk's records already decoded
  // Parallel decoding.
  std::unique_ptr<detail::ChunkPipeline> pipeline;
  std::span<const std::uint8_t> slot;  // the current chunk's decoded records
  std::size_t slot_pos = 0;

  std::size_t chunk = 0;  // index of the chunk being read (or next to begin)
  std::uint64_t points_done = 0;
  std::optional<Error> failure;

  ~State() {
    pipeline.reset();  // joins the workers before the descriptor goes
    if (fd >= 0) ::close(fd);
  }

  std::string where(std::size_t index) const {
    std::string s =
        path + ": chunk " + std::to_string(index + 1) + " of " + std::to_string(expected_chunks);
    if (index < chunks.chunks.size()) {
      const ChunkInfo& c = chunks.chunks[index];
      s += " (points " + std::to_string(c.first_point + 1) + "-" +
           std::to_string(c.first_point + c.points) + ", at byte " + std::to_string(c.offset) + ")";
    }
    return s;
  }

  Result<std::size_t> fail(std::size_t index, const Error& e) {
    failure = Error(e.code, where(index) + ": " + e.message);
    return *failure;
  }

  // The next chunk's extent, discovering it when the table is being rebuilt.
  ChunkExtent extent(std::size_t index) {
    if (chunks.discover && index == chunks.chunks.size()) {
      ChunkInfo c;
      c.offset = index == 0 ? chunks.data_start
                            : chunks.chunks[index - 1].offset + chunks.chunks[index - 1].bytes;
      c.first_point = points_done;
      c.points = std::min<std::uint64_t>(vlr.chunk_size, layout.point_count - points_done);
      c.bytes = 0;  // known once decoded
      chunks.chunks.push_back(c);
    }
    const ChunkInfo& c = chunks.chunks[index];
    ChunkExtent e;
    e.offset = c.offset;
    e.points = c.points;
    e.exact_length = c.bytes != 0 && vlr.compressor != Compressor::pointwise;
    e.bytes =
        c.bytes != 0 ? c.bytes : (c.offset < chunks.data_end ? chunks.data_end - c.offset : 0);
    return e;
  }

  // Begins `partner` on the chunk after `chunk` when the two can decode in lock step: the
  // chunk table is known (not being rebuilt) and the next chunk's records fit the bound the
  // parallel path keeps to. A partner that cannot begin is dropped: its chunk is then begun
  // again, alone, when the reader reaches it, and fails there.
  void begin_partner() {
    partnered = false;
    if (!decoder->pairable() || chunks.discover || chunk + 1 >= chunks.chunks.size()) return;
    const ChunkInfo& next = chunks.chunks[chunk + 1];
    if (next.points == 0 || next.points * layout.record_length > kMaxParallelChunkBytes) return;
    if (!partner)
      partner = std::make_unique<ChunkDecoder>(vlr, layout.record_length, options.layers, fd);
    if (!partner->begin(extent(chunk + 1)).ok() || !decoder->pairs_with(*partner)) return;
    ahead.resize(static_cast<std::size_t>(next.points) * layout.record_length);
    ahead_records = 0;
    ahead_status = Status{};
    partnered = true;
  }

  // decoder's next n records into out; the partner's as many into ahead, in lock step while
  // both streams are healthy.
  Status decode_next(std::uint8_t* out, std::size_t n) {
    const std::uint16_t rl = layout.record_length;
    std::size_t paired = 0;
    if (partnered && ahead_status.ok()) {
      paired = static_cast<std::size_t>(std::min<std::uint64_t>(n, partner->left()));
      auto [mine, theirs] =
          decoder->decode_pair(*partner, out, ahead.data() + ahead_records * rl, paired);
      ahead_records += paired;
      if (!theirs.ok()) ahead_status = theirs;
      if (!mine.ok()) return mine;
    }
    return decoder->decode(out + paired * rl, n - paired);
  }

  // After decoder's chunk: the rest of the partner's chunk, alone, then its end checks.
  void finish_partner() {
    const std::uint16_t rl = layout.record_length;
    if (ahead_status.ok()) {
      const std::uint64_t rest = partner->left();
      ahead_status = partner->decode(ahead.data() + ahead_records * rl, rest);
      ahead_records += rest;
    }
    if (ahead_status.ok()) ahead_status = partner->finish();
    partnered = false;
    serving_ahead = true;
    slot = std::span<const std::uint8_t>(ahead.data(), ahead_records * rl);
    slot_pos = 0;
  }

  Result<std::size_t> read_sequential(std::uint8_t* out, std::size_t max) {
    const std::uint16_t rl = layout.record_length;
    std::size_t produced = 0;
    while (produced < max) {
      if (serving_ahead) {
        if (!ahead_status.ok()) return fail(chunk, ahead_status.error());
        if (take_from_slot(out, produced, max)) {
          serving_ahead = false;
          ++chunk;
        }
        continue;
      }
      if (!in_chunk) {
        if (points_done >= layout.point_count) break;
        if (chunks.discover && chunk >= kMaxChunks) {
          return fail(chunk, unsupported("more than " + std::to_string(kMaxChunks) +
                                         " chunks without a chunk table"));
        }
        if (!decoder) decoder = std::make_unique<ChunkDecoder>(vlr, rl, options.layers, fd);
        if (Status st = decoder->begin(extent(chunk)); !st.ok()) return fail(chunk, st.error());
        in_chunk = true;
        begin_partner();
      }
      const auto n =
          static_cast<std::size_t>(std::min<std::uint64_t>(max - produced, decoder->left()));
      if (Status st = decode_next(out + produced * rl, n); !st.ok()) {
        partnered = false;
        return fail(chunk, st.error());
      }
      produced += n;
      points_done += n;
      if (decoder->left() == 0) {
        if (Status st = decoder->finish(); !st.ok()) {
          partnered = false;
          return fail(chunk, st.error());
        }
        if (chunks.chunks[chunk].bytes == 0) chunks.chunks[chunk].bytes = decoder->consumed();
        in_chunk = false;
        ++chunk;
        if (partnered) finish_partner();
      }
    }
    return produced;
  }

  // Copies records from `slot` to out[produced..max); true when the slot is used up (then
  // cleared: the caller moves on to the next chunk).
  bool take_from_slot(std::uint8_t* out, std::size_t& produced, std::size_t max) {
    const std::uint16_t rl = layout.record_length;
    const std::size_t n = std::min(max - produced, (slot.size() - slot_pos) / rl);
    std::memcpy(out + produced * rl, slot.data() + slot_pos, n * rl);
    slot_pos += n * rl;
    produced += n;
    points_done += n;
    if (slot_pos != slot.size()) return false;
    slot = {};
    slot_pos = 0;
    return true;
  }

  Result<std::size_t> read_parallel(std::uint8_t* out, std::size_t max) {
    std::size_t produced = 0;
    while (produced < max) {
      if (slot_pos == slot.size()) {
        if (chunk == chunks.chunks.size()) break;
        auto records = pipeline->wait(chunk);
        if (!records.ok()) return fail(chunk, records.error());
        slot = *records;
        slot_pos = 0;
      }
      if (take_from_slot(out, produced, max)) {
        pipeline->release(chunk);
        ++chunk;
      }
    }
    return produced;
  }

  Status start_pipeline() {
    std::vector<ChunkExtent> extents;
    extents.reserve(chunks.chunks.size());
    for (std::size_t i = 0; i < chunks.chunks.size(); ++i) extents.push_back(extent(i));
    pipeline = std::make_unique<detail::ChunkPipeline>(vlr, layout.record_length, options.layers,
                                                       fd, std::move(extents), threads);
    if (!pipeline->started().ok()) {
      const Error e = pipeline->started().error();
      pipeline.reset();  // stops and joins the workers that did start
      return e;
    }
    return {};
  }
};

LazReader::LazReader(std::unique_ptr<State> state) : s_(std::move(state)) {}
LazReader::~LazReader() = default;

Result<std::unique_ptr<LazReader>> LazReader::open(const std::filesystem::path& fs_path,
                                                   const PointDataLayout& layout,
                                                   const LaszipVlr& vlr,
                                                   const ReaderOptions& options) {
  auto s = std::make_unique<State>();
  s->path = fs_path.string();
  s->layout = layout;
  s->vlr = vlr;
  s->options = options;
  if (layout.record_length == 0 || layout.points_end > layout.file_size ||
      layout.offset_to_points > layout.points_end) {
    return Error(ErrorCode::internal, s->path + ": inconsistent point data layout");
  }
  s->fd = ::open(s->path.c_str(), O_RDONLY | O_CLOEXEC);
  if (s->fd < 0) return io_error(s->path + ": cannot open: " + std::strerror(errno));

  auto found = detail::find_chunks(s->fd, s->path, layout, vlr);
  if (!found.ok()) return found.error();
  s->chunks = std::move(*found);
  s->expected_chunks = s->chunks.discover
                           ? (layout.point_count + vlr.chunk_size - 1) / vlr.chunk_size
                           : s->chunks.chunks.size();

  // Threads: only for several chunks whose decoded records fit the per-chunk bound.
  unsigned threads = options.threads;
  if (threads == 0) threads = std::clamp(std::thread::hardware_concurrency(), 1u, 8u);
  std::uint64_t largest = 0;
  for (const ChunkInfo& c : s->chunks.chunks) largest = std::max(largest, c.points);
  if (threads > 1) {
    if (s->chunks.discover || s->chunks.chunks.size() < 2) {
      threads = 1;  // discovered chunks: the note from find_chunks says why
    } else if (largest * layout.record_length > kMaxParallelChunkBytes) {
      threads = 1;
      s->chunks.notes.push_back("chunks of " + std::to_string(largest) +
                                " points are decoded on one thread, window by window");
    }
  }
  s->threads = std::min<unsigned>(
      threads, static_cast<unsigned>(std::max<std::size_t>(1, s->chunks.chunks.size())));
  // The workers start with the first read(): a reader opened only to look at the header (the
  // ingest's record count) decodes nothing.
  return std::unique_ptr<LazReader>(new LazReader(std::move(s)));
}

Result<std::size_t> LazReader::read(std::uint8_t* out, std::size_t max_records) {
  if (s_->failure) return *s_->failure;
  if (s_->threads > 1) {
    if (!s_->pipeline) {
      if (Status st = s_->start_pipeline(); !st.ok()) {
        s_->failure = Error(st.error().code, s_->path + ": " + st.error().message);
        return *s_->failure;
      }
    }
    return s_->read_parallel(out, max_records);
  }
  return s_->read_sequential(out, max_records);
}

Status LazReader::rewind() {
  s_->failure.reset();
  s_->chunk = 0;
  s_->points_done = 0;
  s_->in_chunk = false;
  s_->partnered = false;
  s_->serving_ahead = false;
  s_->slot = {};
  s_->slot_pos = 0;
  s_->pipeline.reset();  // joins the workers; the next read() starts them again
  return {};
}

const LaszipVlr& LazReader::vlr() const { return s_->vlr; }
const std::vector<ChunkInfo>& LazReader::chunks() const { return s_->chunks.chunks; }
unsigned LazReader::threads() const { return s_->threads; }
const std::vector<std::string>& LazReader::notes() const { return s_->chunks.notes; }

}  // namespace tinstream::laz
