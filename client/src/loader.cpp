#include "tinstream/client/loader.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>

#include "tinstream/client/imagery.hpp"

namespace tinstream::client {

namespace {
constexpr int kMaxThreads = 8;

void add_micros_since(std::atomic<std::uint64_t>& micros,
                      std::chrono::steady_clock::time_point start) {
  micros.fetch_add(static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(
                                                  std::chrono::steady_clock::now() - start)
                                                  .count()),
                   std::memory_order_relaxed);
}

// CPU time of the calling thread in microseconds: beside the wall time of a decode, it tells how
// much of that wall time the thread waited for a core (decoding threads outnumbering free cores).
std::uint64_t thread_cpu_micros() {
  timespec t{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<std::uint64_t>(t.tv_sec) * 1000000u +
         static_cast<std::uint64_t>(t.tv_nsec) / 1000u;
}

void add_cpu_micros_since(std::atomic<std::uint64_t>& micros, std::uint64_t start) {
  micros.fetch_add(thread_cpu_micros() - start, std::memory_order_relaxed);
}
}  // namespace

int TileLoader::default_threads() {
  const unsigned hw = std::thread::hardware_concurrency();
  return std::clamp(static_cast<int>(hw == 0 ? 1 : hw), 1, kMaxThreads);
}

TileLoader::TileLoader(std::shared_ptr<TileSource> source, std::vector<LayerDescription> layers,
                       std::shared_ptr<DiskCache> disk, LoaderOptions options)
    : source_(std::move(source)),
      layers_(std::move(layers)),
      disk_(std::move(disk)),
      timeline_(std::move(options.timeline)) {
  if (!source_->remote()) disk_.reset();
  const int decoders = options.decode_threads <= 0 ? default_threads() : options.decode_threads;
  for (int i = 0; i < decoders; ++i) decoders_.emplace_back([this] { run_decoder(); });
  set_threads(options.threads <= 0 ? default_threads() : options.threads);
}

TileLoader::~TileLoader() {
  cancel_.store(true);
  {
    std::lock_guard lock(decode_mutex_);
    decode_closed_ = true;  // payloads still queued are dropped
  }
  decode_ready_.notify_all();
  decode_room_.notify_all();
  queue_.close();
  for (std::thread& t : workers_)
    if (t.joinable()) t.join();
  for (std::thread& t : decoders_)
    if (t.joinable()) t.join();
}

void TileLoader::set_threads(int threads) {
  threads_ = std::clamp(threads, 1, kMaxThreads);
  queue_.set_active_workers(static_cast<std::size_t>(threads_));
  while (static_cast<int>(workers_.size()) < threads_) {
    const std::size_t index = workers_.size();
    workers_.emplace_back([this, index] { run_worker(index); });
  }
}

void TileLoader::set_paused(bool paused) { queue_.set_paused(paused); }

void TileLoader::submit(std::vector<TileRequest> wanted) {
  // The queue first: it raises the priority of every wanted tile in flight, which is what both a
  // waiting payload (raised below) and one still downloading (queue_decode) read. A payload queued
  // before the raise below is raised by it, one queued after it reads the raised priority.
  counters_.dropped.fetch_add(queue_.replace(std::move(wanted)), std::memory_order_relaxed);
  raise_decode_priorities();
}

void TileLoader::raise_decode_priorities() {
  // A waiting payload's tile is in flight (until its result is taken): at most kMaxDecodeBacklog
  // lookups in the queue.
  std::lock_guard lock(decode_mutex_);
  for (DecodeJob& job : decode_jobs_)
    job.priority = queue_.in_flight_priority(job.key, job.priority);
}

std::vector<LoadResult> TileLoader::take_results() {
  std::vector<LoadResult> out;
  {
    std::lock_guard lock(results_mutex_);
    out.swap(results_);
  }
  std::vector<TileKey> keys;
  keys.reserve(out.size());
  for (const LoadResult& r : out) keys.push_back(r.key);
  queue_.finish(keys);
  return out;
}

void TileLoader::set_result_callback(std::function<void()> callback) {
  std::lock_guard lock(callback_mutex_);
  result_callback_ = std::move(callback);
}

bool TileLoader::wait_for_results(std::chrono::milliseconds timeout) {
  std::unique_lock lock(results_mutex_);
  return results_ready_.wait_for(lock, timeout, [&] { return !results_.empty(); });
}

LoaderCounters TileLoader::counters() const {
  const auto get = [](const std::atomic<std::uint64_t>& a) {
    return a.load(std::memory_order_relaxed);
  };
  LoaderCounters c;
  c.requests = get(counters_.requests);
  c.retries = get(counters_.retries);
  c.connections = get(counters_.connections);
  c.ok = get(counters_.ok);
  c.not_modified = get(counters_.not_modified);
  c.not_found = get(counters_.not_found);
  c.failed = get(counters_.failed);
  c.wire_bytes = get(counters_.wire_bytes);
  c.downloaded_bytes = get(counters_.downloaded_bytes);
  c.decoded = get(counters_.decoded);
  c.decode_errors = get(counters_.decode_errors);
  c.dropped = get(counters_.dropped);
  c.decode_seconds = static_cast<double>(get(counters_.decode_micros)) * 1e-6;
  c.decode_cpu_seconds = static_cast<double>(get(counters_.decode_cpu_micros)) * 1e-6;
  c.decode_wait_seconds = static_cast<double>(get(counters_.decode_wait_micros)) * 1e-6;
  {
    std::lock_guard lock(decode_mutex_);
    c.most_decoding = most_decoding_;
    c.decode_queued = decode_jobs_.size();
  }
  c.queued = queue_.queued();
  c.in_flight = queue_.in_flight();
  c.in_flight_levels = queue_.in_flight_per_level();
  return c;
}

void TileLoader::run_worker(std::size_t index) {
  std::unique_ptr<TileConnection> connection;
  while (auto request = queue_.pop(index)) {
    if (timeline_) {
      timeline_->record(request->key, TileEvent::sent);
      timeline_->record_priority(request->key, request->priority);
    }
    std::optional<LoadResult> result;
    try {
      result = load(*request, connection);
    } catch (const std::exception& e) {  // the barrier: nothing escapes a worker
      result = LoadResult{request->key,
                          LoadStatus::failed,
                          LoadOrigin::network,
                          nullptr,
                          std::string("internal error: ") + e.what(),
                          0};
      connection.reset();
    } catch (...) {
      result = LoadResult{request->key, LoadStatus::failed, LoadOrigin::network,
                          nullptr,      "internal error",   0};
      connection.reset();
    }
    if (result) publish(std::move(*result));  // else a decoder publishes it
  }
}

void TileLoader::run_decoder() {
  for (;;) {
    DecodeJob job;
    {
      std::unique_lock lock(decode_mutex_);
      decode_ready_.wait(lock, [&] { return decode_closed_ || !decode_jobs_.empty(); });
      if (decode_closed_) return;
      // The most urgent job; among equal priorities the one queued first.
      const auto next =
          std::ranges::max_element(decode_jobs_, [](const DecodeJob& a, const DecodeJob& b) {
            return a.priority < b.priority || (a.priority == b.priority && a.queued > b.queued);
          });
      job = std::move(*next);
      decode_jobs_.erase(next);
      ++decoding_;
      most_decoding_ = std::max(most_decoding_, decoding_);
    }
    decode_room_.notify_one();
    LoadResult result;
    try {
      result = finish_payload(job);
    } catch (const std::exception& e) {  // the barrier: nothing escapes a decoder
      result = LoadResult{job.key,
                          LoadStatus::failed,
                          job.origin,
                          nullptr,
                          std::string("internal error: ") + e.what(),
                          0};
    } catch (...) {
      result = LoadResult{job.key, LoadStatus::failed, job.origin, nullptr, "internal error", 0};
    }
    {
      std::lock_guard lock(decode_mutex_);
      --decoding_;
    }
    publish(std::move(result));
  }
}

void TileLoader::publish(LoadResult result) {
  if (result.status == LoadStatus::failed) counters_.failed.fetch_add(1, std::memory_order_relaxed);
  // The key stays in flight until the render thread takes the result (take_results), so a
  // frame that looked for it before it was ready cannot queue it again.
  {
    std::lock_guard lock(results_mutex_);
    results_.push_back(std::move(result));
  }
  results_ready_.notify_all();
  std::lock_guard lock(callback_mutex_);
  if (result_callback_) result_callback_();
}

void TileLoader::queue_decode(const TileKey& key, std::vector<std::uint8_t> bytes,
                              ContentEncoding encoding, LoadOrigin origin, double priority) {
  // (A NaN would not order against the others: it waits behind every other priority.)
  if (std::isnan(priority)) priority = -std::numeric_limits<double>::infinity();
  {
    std::unique_lock lock(decode_mutex_);
    decode_room_.wait(lock,
                      [&] { return decode_closed_ || decode_jobs_.size() < kMaxDecodeBacklog; });
    if (decode_closed_) return;  // shutting down: nobody takes results any more
    // The view may have come to need the tile while it downloaded (submit()).
    priority = queue_.in_flight_priority(key, priority);
    decode_jobs_.push_back(DecodeJob{key, priority, std::move(bytes), encoding, origin,
                                     std::chrono::steady_clock::now()});
  }
  decode_ready_.notify_one();
}

std::optional<LoadResult> TileLoader::load(const TileRequest& request,
                                           std::unique_ptr<TileConnection>& connection) {
  const TileKey& key = request.key;
  const LayerDescription& layer = layers_.at(key.layer);
  LoadResult failed{key, LoadStatus::failed, LoadOrigin::network, nullptr, {}, 0};
  if (!connection) {
    auto c = source_->connect();
    if (!c) {
      failed.error = c.error().message;
      return failed;
    }
    connection = std::move(*c);
  }
  std::optional<DiskEntry> cached;
  if (disk_) cached = disk_->get(key, layer);

  FetchRequest fetch{key, &layer, cached ? std::optional<std::string>(cached->etag) : std::nullopt};
  FetchResponse response = connection->fetch(fetch, cancel_);
  if (timeline_) {
    const auto now = std::chrono::steady_clock::now();
    const bool has_headers = response.headers_at != std::chrono::steady_clock::time_point{};
    timeline_->record(key, TileEvent::headers, has_headers ? response.headers_at : now);
    timeline_->record(key, TileEvent::body, now);
  }
  counters_.requests.fetch_add(response.attempts, std::memory_order_relaxed);
  counters_.retries.fetch_add(response.attempts > 0 ? response.attempts - 1 : 0,
                              std::memory_order_relaxed);
  counters_.connections.fetch_add(response.reconnects, std::memory_order_relaxed);
  counters_.wire_bytes.fetch_add(response.wire_bytes, std::memory_order_relaxed);
  const LoadOrigin fetched = source_->remote() ? LoadOrigin::network : LoadOrigin::store;

  switch (response.status) {
    case FetchResponse::Status::ok: {
      counters_.ok.fetch_add(1, std::memory_order_relaxed);
      counters_.downloaded_bytes.fetch_add(response.body.size(), std::memory_order_relaxed);
      if (disk_) disk_->put(key, layer, DiskEntry{response.etag, response.encoding, response.body});
      queue_decode(key, std::move(response.body), response.encoding, fetched, request.priority);
      return std::nullopt;
    }
    case FetchResponse::Status::not_modified:
      counters_.not_modified.fetch_add(1, std::memory_order_relaxed);
      if (!cached) {
        failed.error = "tile " + key.tile.quadkey() + ": 304 Not Modified without a cached copy";
        return failed;
      }
      disk_->touch(key, layer);
      queue_decode(key, std::move(cached->bytes), cached->encoding, LoadOrigin::revalidated,
                   request.priority);
      return std::nullopt;
    case FetchResponse::Status::not_found:
      counters_.not_found.fetch_add(1, std::memory_order_relaxed);
      if (cached) disk_->erase(key, layer);
      return LoadResult{key, LoadStatus::absent, fetched, nullptr, {}, 0};
    case FetchResponse::Status::failed:
      break;
  }
  // The source failed after its retries: a copy on disk is better than nothing (offline use).
  if (cached && response.error.code != ErrorCode::cancelled) {
    queue_decode(key, std::move(cached->bytes), cached->encoding, LoadOrigin::disk,
                 request.priority);
    return std::nullopt;
  }
  failed.error = response.error.message;
  return failed;
}

LoadResult TileLoader::finish_payload(DecodeJob& job) {
  const TileKey& key = job.key;
  const LayerDescription& layer = layers_.at(key.layer);
  const std::vector<std::uint8_t>& bytes = job.bytes;
  const ContentEncoding encoding = job.encoding;
  const LoadOrigin origin = job.origin;
  add_micros_since(counters_.decode_wait_micros, job.queued);
  const auto start = std::chrono::steady_clock::now();
  if (timeline_) timeline_->record(key, TileEvent::decode_start, start);
  const std::uint64_t start_cpu = thread_cpu_micros();
  if (key.kind == TileKind::imagery)
    return finish_image(key, layer, bytes, encoding, origin, start, start_cpu);
  auto mesh = decode_render_mesh(bytes, encoding, layer, key);
  if (timeline_) timeline_->record(key, TileEvent::decoded);
  add_micros_since(counters_.decode_micros, start);
  add_cpu_micros_since(counters_.decode_cpu_micros, start_cpu);
  if (!mesh) {
    counters_.decode_errors.fetch_add(1, std::memory_order_relaxed);
    // A damaged copy must not come back from the disk cache.
    if (disk_) disk_->erase(key, layer);
    return LoadResult{key, LoadStatus::failed, origin, nullptr, mesh.error().message, bytes.size()};
  }
  counters_.decoded.fetch_add(1, std::memory_order_relaxed);
  return LoadResult{key,    LoadStatus::loaded,
                    origin, std::make_shared<const TileMesh>(std::move(*mesh)),
                    {},     bytes.size()};
}

LoadResult TileLoader::finish_image(const TileKey& key, const LayerDescription& layer,
                                    const std::vector<std::uint8_t>& bytes,
                                    ContentEncoding encoding, LoadOrigin origin,
                                    std::chrono::steady_clock::time_point start,
                                    std::uint64_t start_cpu) {
  auto image = decode_imagery_tile(bytes, encoding, layer, key);
  add_micros_since(counters_.decode_micros, start);
  add_cpu_micros_since(counters_.decode_cpu_micros, start_cpu);
  LoadResult r{key, LoadStatus::failed, origin, nullptr, {}, bytes.size()};
  if (!image) {
    counters_.decode_errors.fetch_add(1, std::memory_order_relaxed);
    if (disk_) disk_->erase(key, layer);
    r.error = image.error().message;
    return r;
  }
  counters_.decoded.fetch_add(1, std::memory_order_relaxed);
  r.status = LoadStatus::loaded;
  r.image = std::make_shared<const imagery::RgbaImage>(std::move(*image));
  return r;
}

}  // namespace tinstream::client
