#include "tinstream/transform/pass1.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>

#include "tinstream/base/worker_threads.hpp"

namespace tinstream::transform {
namespace {

using Clock = std::chrono::steady_clock;

class ProgressThrottle {
 public:
  explicit ProgressThrottle(const ProgressSink& sink) : sink_(sink) {}
  // Returns false when the sink asks to stop.
  bool report(std::uint64_t done, std::uint64_t total, bool force) {
    if (!sink_) return true;
    const auto now = Clock::now();
    if (!force && now - last_ < std::chrono::milliseconds(200)) return true;
    last_ = now;
    return sink_(Progress{"transform", done, total, "records"});
  }

 private:
  const ProgressSink& sink_;
  Clock::time_point last_{};
};

// Opens every input once to learn its record count (cheap: headers only; the class pre-scan is
// avoided by an explicit all-classes filter). Returns 0 when any count is unknown.
std::uint64_t total_records(std::span<const InputSpec> inputs) {
  std::uint64_t total = 0;
  for (const InputSpec& in : inputs) {
    sources::SourceOptions probe = in.source;
    std::vector<std::uint8_t> all(256);
    for (std::size_t c = 0; c < 256; ++c) all[c] = static_cast<std::uint8_t>(c);
    probe.class_filter.classes = std::move(all);
    auto src = sources::open_source(in.path, probe);
    if (!src.ok() || !(*src)->info().record_count) return 0;
    total += *(*src)->info().record_count;
  }
  return total;
}

// What transforming one batch needs besides the reprojector (shared, read-only).
struct BatchContext {
  const geo::NormalisedMercator* mercator;
  const std::string& path;
  float weight;
  std::uint16_t input_tag;
  bool skip_invalid;
};

// One batch of source points and what became of it.
struct BatchWork {
  std::vector<sources::SourcePoint> batch;
  std::vector<GeoPoint> geo_points;
  std::vector<RunPoint> run_points;
  std::vector<geo::LonLat> lonlat;
  std::uint64_t outside_mercator = 0;
  std::uint64_t implausible_height = 0;
  Status status;
  bool done = false;  // guarded by the pipeline's mutex while the batch is in flight
};

// Reprojects a batch and maps it to normalised Mercator. Touches only `w` and the reprojector,
// so two batches with two reprojectors may run on two threads.
void transform_batch(const BatchContext& c, Reprojector& reprojector, BatchWork& w) {
  w.run_points.clear();
  w.lonlat.clear();
  w.outside_mercator = 0;
  w.implausible_height = 0;
  w.status = {};
  if (auto st = reprojector.transform(w.batch, w.geo_points); !st.ok()) {
    w.status = st;
    return;
  }
  for (std::size_t i = 0; i < w.batch.size(); ++i) {
    const GeoPoint& g = w.geo_points[i];
    auto m = c.mercator->forward_checked(geo::LonLat{g.lon, g.lat});
    if (!m.ok() || !std::isfinite(g.h)) {
      if (c.skip_invalid) {
        ++w.outside_mercator;
        continue;
      }
      w.status = Error(ErrorCode::corrupt_data,
                       c.path + ": record " + std::to_string(w.batch[i].record) + ": lon " +
                           std::to_string(g.lon) + ", lat " + std::to_string(g.lat) +
                           " is outside the normalised Mercator square (|lat| ≤ " +
                           std::to_string(c.mercator->max_latitude()) + "°)");
      return;
    }
    if (std::abs(g.h) > kMaxAbsHeight) {
      if (c.skip_invalid) {
        ++w.implausible_height;
        continue;
      }
      w.status = Error(ErrorCode::corrupt_data,
                       c.path + ": record " + std::to_string(w.batch[i].record) + ": height " +
                           std::to_string(g.h) + " m is outside the Earth's range (|h| ≤ " +
                           std::to_string(static_cast<int>(kMaxAbsHeight)) +
                           " m): a NODATA value the file does not declare, or wrong z units? "
                           "(--skip-invalid drops such records)");
      return;
    }
    w.run_points.push_back(
        RunPoint{m->x, m->y, g.h, c.weight, c.input_tag, w.batch[i].classification});
    w.lonlat.push_back(geo::LonLat{g.lon, g.lat});
  }
}

// transform_batch inside the exception barrier: an exception (out of memory, a throwing PROJ
// callback) becomes the batch's Status, which the caller reports in record order like any
// other error of the batch. Fault point "pass1.transform".
void transform_guarded(const BatchContext& c, Reprojector& reprojector, BatchWork& w) {
  Status s = guarded("pass 1 transform", [&] {
    fault::point("pass1.transform");
    transform_batch(c, reprojector, w);
  });
  if (!s.ok()) w.status = std::move(s);
}

// Worker threads that transform batches, one Reprojector each (PROJ contexts are not shared).
// The calling thread submits batches in record order and collects them in the same order, so
// the points handed on and the first error reported do not depend on the number of workers.
//
//   reader (calling thread) ──submit──▶ todo_ ──▶ worker k: transform_batch ──▶ done = true
//   writer (calling thread) ◀──wait(oldest)───────────────────────────────────────┘
class TransformWorkers {
 public:
  explicit TransformWorkers(const BatchContext& context) : context_(context) {}
  TransformWorkers(const TransformWorkers&) = delete;
  TransformWorkers& operator=(const TransformWorkers&) = delete;
  // Batches still queued are dropped; those being transformed finish first.
  ~TransformWorkers() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
      todo_.clear();
    }
    wake_workers_.notify_all();
    (void)threads_.join();
  }
  // Starts one worker per reprojector; an Error when one cannot be started (the destructor stops
  // and joins those that were).
  Status start(std::vector<Reprojector>& reprojectors) {
    for (Reprojector& r : reprojectors) {
      if (Status s = threads_.start([this, &r] { work(r); }); !s) return s;
    }
    return {};
  }
  void submit(BatchWork& w) {
    {
      std::lock_guard lock(mutex_);
      w.done = false;
      todo_.push_back(&w);
    }
    wake_workers_.notify_one();
  }
  // Blocks until `w` (submitted) is transformed.
  void wait(BatchWork& w) {
    std::unique_lock lock(mutex_);
    batch_done_.wait(lock, [&] { return w.done; });
  }

 private:
  void work(Reprojector& reprojector) {
    for (;;) {
      BatchWork* w = nullptr;
      {
        std::unique_lock lock(mutex_);
        wake_workers_.wait(lock, [&] { return stop_ || !todo_.empty(); });
        if (todo_.empty()) return;  // stop_
        w = todo_.front();
        todo_.pop_front();
      }
      transform_guarded(context_, reprojector, *w);
      {
        std::lock_guard lock(mutex_);
        w->done = true;
      }
      batch_done_.notify_all();
    }
  }

  const BatchContext& context_;
  std::mutex mutex_;  // guards todo_, stop_ and every submitted BatchWork::done
  std::condition_variable wake_workers_, batch_done_;
  std::deque<BatchWork*> todo_;
  bool stop_ = false;
  WorkerThreads threads_{"pass 1 transform",
                         "pass1.transform"};  // last: started after, joined before the rest goes
};

// Accumulates the RunHeader (count, boxes, z range) over the batches handed on.
class RunHeaderBuilder {
 public:
  RunHeaderBuilder(geo::Projection projection, std::uint32_t input_count) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    header_.projection = projection;
    header_.input_count = input_count;
    header_.mercator = Extent{inf, inf, -inf, -inf};
    header_.lonlat = Extent{inf, inf, -inf, -inf};
    header_.min_z = inf;
    header_.max_z = -inf;
  }

  // Requires: `lonlat` holds the same points as `points`.
  void add(std::span<const RunPoint> points, std::span<const geo::LonLat> lonlat) {
    Extent& m = header_.mercator;
    for (const RunPoint& p : points) {
      m.min_x = std::min(m.min_x, p.x), m.max_x = std::max(m.max_x, p.x);
      m.min_y = std::min(m.min_y, p.y), m.max_y = std::max(m.max_y, p.y);
      header_.min_z = std::min(header_.min_z, p.z);
      header_.max_z = std::max(header_.max_z, p.z);
    }
    Extent& e = header_.lonlat;
    for (const geo::LonLat& g : lonlat) {
      e.min_x = std::min(e.min_x, g.lon), e.max_x = std::max(e.max_x, g.lon);
      e.min_y = std::min(e.min_y, g.lat), e.max_y = std::max(e.max_y, g.lat);
    }
    header_.point_count += points.size();
  }

  const RunHeader& header() const { return header_; }

 private:
  RunHeader header_;
};

Result<RunSummary> transform_unguarded(std::span<const InputSpec> inputs,
                                       const TransformOptions& options,
                                       const ProgressSink& progress) {
  if (options.batch_size == 0) return invalid_argument("batch size must be at least 1");
  if (!options.on_points) return invalid_argument("no consumer of the points (on_points)");
  ProgressThrottle throttle(progress);
  const std::uint64_t total = progress ? total_records(inputs) : 0;

  const auto input_count = static_cast<std::uint32_t>(inputs.size());
  RunHeaderBuilder header(options.projection, input_count);
  const geo::NormalisedMercator mercator(options.projection);

  RunSummary summary;
  std::uint64_t done_before = 0;  // records of the inputs already finished
  // Batches in flight: one per worker plus the one the reader fills.
  const unsigned workers = options.threads > 1 ? options.threads : 0;
  std::vector<BatchWork> slots(workers + 1);
  for (auto& w : slots) w.batch.reserve(options.batch_size);

  for (std::size_t index = 0; index < inputs.size(); ++index) {
    const InputSpec& in = inputs[index];
    auto source = sources::open_source(in.path, in.source);
    if (!source.ok()) return source.error();
    sources::PointSource& src = **source;
    auto reprojector = Reprojector::create(src.info(), in.reproject);
    if (!reprojector.ok()) return reprojector.error();
    std::vector<Reprojector> worker_reprojectors;
    for (unsigned k = 0; k < workers; ++k) {
      auto r = Reprojector::create(src.info(), in.reproject);
      if (!r.ok()) return r.error();
      worker_reprojectors.push_back(std::move(*r));
    }

    InputSummary s;
    s.path = src.info().path;
    s.format = src.info().format;
    s.plan = reprojector->plan();
    const BatchContext context{&mercator, s.path, in.weight,
                               static_cast<std::uint16_t>(std::min<std::size_t>(index, 65535)),
                               in.source.invalid == sources::InvalidPolicy::skip};

    // Hands one transformed batch on (or returns the first error of its records).
    auto append = [&](BatchWork& w) -> Status {
      if (!w.status.ok()) return w.status;
      s.outside_mercator += w.outside_mercator;
      s.implausible_height += w.implausible_height;
      header.add(w.run_points, w.lonlat);
      s.points_written += w.run_points.size();
      return options.on_points(w.run_points);
    };
    // Fault point "pass1.read": a reader that throws.
    auto read = [&](BatchWork& w) {
      fault::point("pass1.read");
      return src.read(w.batch, options.batch_size);
    };
    auto report = [&]() -> Status {
      if (!throttle.report(done_before + src.counters().records_read, total, false)) {
        return Error(ErrorCode::cancelled, "transform cancelled while reading " + s.path);
      }
      return {};
    };
    if (workers == 0) {
      BatchWork& w = slots[0];
      for (;;) {
        w.batch.clear();
        auto got = read(w);
        if (!got.ok()) return got.error();
        if (*got == 0) break;
        transform_guarded(context, *reprojector, w);
        if (Status st = append(w); !st.ok()) return st.error();
        if (Status st = report(); !st.ok()) return st.error();
      }
    } else {
      // Slots are used round robin: batch i lives in slots[i % size], so the oldest batch in
      // flight is always the next slot to refill.
      TransformWorkers pool(context);
      if (Status st = pool.start(worker_reprojectors); !st.ok()) return st.error();
      std::size_t next = 0, in_flight = 0;
      bool more = true;
      while (more || in_flight > 0) {
        if (more && in_flight < slots.size()) {
          BatchWork& w = slots[(next + in_flight) % slots.size()];
          w.batch.clear();
          auto got = read(w);
          if (!got.ok()) {
            // Batches before the failing read come first: their errors win.
            for (; in_flight > 0; --in_flight, next = (next + 1) % slots.size()) {
              pool.wait(slots[next]);
              if (Status st = append(slots[next]); !st.ok()) return st.error();
            }
            return got.error();
          }
          if (*got == 0) {
            more = false;
          } else {
            pool.submit(w);
            ++in_flight;
          }
          continue;
        }
        BatchWork& oldest = slots[next];
        pool.wait(oldest);
        if (Status st = append(oldest); !st.ok()) return st.error();
        next = (next + 1) % slots.size();
        --in_flight;
        if (Status st = report(); !st.ok()) return st.error();
      }
    }
    s.counters = src.counters();
    s.counters.accepted -= s.outside_mercator + s.implausible_height;
    s.counters.rejected_invalid += s.outside_mercator + s.implausible_height;
    s.notes = src.info().notes;
    s.notes.insert(s.notes.end(), s.plan.notes.begin(), s.plan.notes.end());
    done_before += s.counters.records_read;
    summary.inputs.push_back(std::move(s));
  }
  if (!throttle.report(done_before, total, true)) {
    return Error(ErrorCode::cancelled, "transform cancelled after the last input");
  }
  summary.header = header.header();
  return summary;
}

}  // namespace

Result<RunSummary> transform_sources(std::span<const InputSpec> inputs,
                                     const TransformOptions& options,
                                     const ProgressSink& progress) {
  Result<RunSummary> out = Error(ErrorCode::internal, "pass 1 did not run");
  // The calling thread's barrier: an exception (a throwing reader, out of memory) is an Error
  // too, after the workers were stopped and joined (TransformWorkers' destructor).
  if (Status s = guarded("pass 1", [&] { out = transform_unguarded(inputs, options, progress); });
      !s.ok()) {
    return s.error();
  }
  return out;
}

}  // namespace tinstream::transform
