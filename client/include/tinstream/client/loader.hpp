// tinstream/client/loader.hpp — the download pool: up to eight download workers that fetch,
// revalidate and cache tiles on disk, and decoder threads that turn the payloads into meshes
// and hand them to the render thread.
//
//   render thread ──submit(wanted)──▶ RequestQueue ──pop──▶ download worker k (own TileConnection)
//        ▲                                                   │ disk cache get / put / touch, fetch
//        │                                                   ▼
//        └──take_results() (swap)◀── ready list ◀── decoder ◀── decode jobs (most urgent first)
//                                   (404s, failures        inflate → decode → mesh
//                                    straight from workers)
//
// A download worker hands the payload to the decoders and asks for its next tile at once: its
// connection is not idle while a tile decodes (with 30 ms per request, ~12 ms a tile of wall time
// on a busy 2-core machine; bench/client). At most LoaderOptions::decode_threads decode at once,
// the most urgent job first; at most kMaxDecodeBacklog payloads wait (a worker waits for room).
// A decode job's priority follows the render thread: a prefetched tile (ranked after every needed
// one) that the view needs by the time its payload waits, or while it still downloads, is decoded
// as needed.
// Neither submit() nor take_results() waits on a worker: both hold a lock only for a swap (or,
// in submit, one hash lookup per request and one per waiting payload).
// Workers never touch the RAM or GPU tiers.
// Every worker and decoder runs its jobs inside an exception barrier; a failure becomes a
// `failed` result. The download thread count can change at run time (set_threads): extra
// workers are parked, not joined.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tinstream/client/disk_cache.hpp"
#include "tinstream/client/layer.hpp"
#include "tinstream/client/render_mesh.hpp"
#include "tinstream/client/request_queue.hpp"
#include "tinstream/client/tile_source.hpp"
#include "tinstream/client/timeline.hpp"

namespace tinstream::imagery {
struct RgbaImage;
}

namespace tinstream::client {

enum class LoadStatus { loaded, absent, failed };
// Where a loaded tile's bytes came from.
enum class LoadOrigin { network, revalidated, disk, store };

struct LoadResult {
  TileKey key;
  LoadStatus status = LoadStatus::failed;
  LoadOrigin origin = LoadOrigin::network;
  std::shared_ptr<const TileMesh> mesh;  // when loaded (terrain)
  std::string error;                     // when failed
  std::uint64_t payload_bytes = 0;       // compressed bytes of the tile
  // When loaded (imagery): the decoded image.
  std::shared_ptr<const imagery::RgbaImage> image = nullptr;
};

// Cumulative counters (read with relaxed atomics: a consistent snapshot is not needed).
struct LoaderCounters {
  std::uint64_t requests = 0;     // fetches sent to the source (HTTP attempts or store reads)
  std::uint64_t retries = 0;      // attempts beyond the first
  std::uint64_t connections = 0;  // connections opened
  std::uint64_t ok = 0, not_modified = 0, not_found = 0, failed = 0;
  std::uint64_t wire_bytes = 0;        // bytes received from the network (headers and bodies)
  std::uint64_t downloaded_bytes = 0;  // bodies of 200 answers (new bytes)
  std::uint64_t decoded = 0, decode_errors = 0;
  std::uint64_t dropped = 0;  // queued requests dropped because the view moved on
  std::uint64_t queued = 0, in_flight = 0;
  std::array<std::uint32_t, 31> in_flight_levels{};
  double decode_seconds = 0;        // worker time spent inflating, decoding and building meshes
  double decode_cpu_seconds = 0;    // the CPU time of it (less when workers wait for a core)
  double decode_wait_seconds = 0;   // time payloads waited for a decoder
  int most_decoding = 0;            // the most decodes that ran at once
  std::uint64_t decode_queued = 0;  // payloads waiting for a decoder now
};

struct LoaderOptions {
  int threads = 0;         // download threads; 0: one per core, at most 8
  int decode_threads = 0;  // decoder threads (decodes at once, most urgent first); 0: one per core
  // Where workers record when each request was sent, answered and decoded (timeline.hpp); null:
  // nowhere (the default).
  std::shared_ptr<RequestTimeline> timeline = nullptr;
};

class TileLoader {
 public:
  // `disk` may be null; it is only used for remote sources.
  TileLoader(std::shared_ptr<TileSource> source, std::vector<LayerDescription> layers,
             std::shared_ptr<DiskCache> disk, LoaderOptions options = {});
  ~TileLoader();  // cancels requests in flight and joins the workers
  TileLoader(const TileLoader&) = delete;
  TileLoader& operator=(const TileLoader&) = delete;

  static int default_threads();
  void set_threads(int threads);  // clamped to 1…8
  int threads() const { return threads_; }
  // Workers finish what is in flight but take nothing new while paused.
  void set_paused(bool paused);

  // Render thread: what the view lacks now, replacing the previous submission. A wanted tile
  // whose payload already waits for a decoder or is still downloading (a prefetched tile the view
  // now needs) is decoded with the larger of its old and new priorities.
  void submit(std::vector<TileRequest> wanted);
  // Render thread: results finished since the last call (never blocks on a worker).
  std::vector<LoadResult> take_results();
  // Called on a worker's or decoder's thread after each result it made ready, outside every
  // loader lock (the
  // window: wakes the render thread from its wait for events). Must not call into the loader.
  // Set or cleared (nullptr) from any thread; returns once no worker runs the old one any more.
  void set_result_callback(std::function<void()> callback);
  // Blocks until a result is ready or `timeout` passed (headless driver only).
  bool wait_for_results(std::chrono::milliseconds timeout);

  LoaderCounters counters() const;
  const std::vector<LayerDescription>& layers() const { return layers_; }
  const TileSource& source() const { return *source_; }
  const DiskCache* disk() const { return disk_.get(); }
  // LoaderOptions::timeline (null: none); the streamer records the render thread's steps in it.
  RequestTimeline* timeline() const { return timeline_.get(); }

 private:
  // A payload on its way from a download worker to a decoder.
  struct DecodeJob {
    TileKey key;
    double priority = 0;  // the request's: larger first
    std::vector<std::uint8_t> bytes;
    ContentEncoding encoding = ContentEncoding::identity;
    LoadOrigin origin = LoadOrigin::network;
    std::chrono::steady_clock::time_point queued{};
  };
  static constexpr std::size_t kMaxDecodeBacklog = 16;

  void run_worker(std::size_t index);
  void run_decoder();
  // A finished result: to the ready list, then the callback.
  void publish(LoadResult result);
  // Fetches the tile; a payload to decode goes to the decoders (nullopt), anything else (404,
  // failure) is the result.
  std::optional<LoadResult> load(const TileRequest& request,
                                 std::unique_ptr<TileConnection>& connection);
  // submit(): a waiting decode job's priority rises to its tile's in-flight priority (the most
  // urgent one asked for it since it was sent: RequestQueue::in_flight_priority).
  void raise_decode_priorities();
  void queue_decode(const TileKey& key, std::vector<std::uint8_t> bytes, ContentEncoding encoding,
                    LoadOrigin origin, double priority);
  LoadResult finish_payload(DecodeJob& job);
  // An imagery payload (imagery.hpp): decoded into an image instead of a mesh.
  LoadResult finish_image(const TileKey& key, const LayerDescription& layer,
                          const std::vector<std::uint8_t>& bytes, ContentEncoding encoding,
                          LoadOrigin origin, std::chrono::steady_clock::time_point start,
                          std::uint64_t start_cpu_micros);

  std::shared_ptr<TileSource> source_;
  std::vector<LayerDescription> layers_;
  std::shared_ptr<DiskCache> disk_;
  RequestQueue queue_;
  std::shared_ptr<RequestTimeline> timeline_;
  std::atomic<bool> cancel_{false};
  int threads_ = 1;
  std::vector<std::thread> workers_;  // grows up to 8, touched by the owner's thread only

  mutable std::mutex decode_mutex_;
  std::condition_variable decode_ready_;  // a job was queued, or closing
  std::condition_variable decode_room_;   // a job was taken, or closing
  std::vector<DecodeJob> decode_jobs_;    // guarded by decode_mutex_
  bool decode_closed_ = false;            // guarded by decode_mutex_
  int decoding_ = 0, most_decoding_ = 0;  // guarded by decode_mutex_
  std::vector<std::thread> decoders_;     // made in the constructor, joined in the destructor

  std::mutex results_mutex_;
  std::condition_variable results_ready_;
  std::vector<LoadResult> results_;        // guarded by results_mutex_
  std::mutex callback_mutex_;              // held while the callback runs (one at a time)
  std::function<void()> result_callback_;  // guarded by callback_mutex_

  struct Atomics {
    std::atomic<std::uint64_t> requests{0}, retries{0}, connections{0}, ok{0}, not_modified{0},
        not_found{0}, failed{0}, wire_bytes{0}, downloaded_bytes{0}, decoded{0}, decode_errors{0},
        dropped{0}, decode_micros{0}, decode_cpu_micros{0}, decode_wait_micros{0};
  };
  Atomics counters_;
};

}  // namespace tinstream::client
