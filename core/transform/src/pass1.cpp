#include "tinstream/transform/pass1.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

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

}  // namespace

Result<RunSummary> transform_sources(std::span<const InputSpec> inputs,
                                     const TransformOptions& options,
                                     const ProgressSink& progress) {
  if (options.batch_size == 0) return invalid_argument("batch size must be at least 1");
  if (options.output.empty()) return invalid_argument("no run file path given");
  ProgressThrottle throttle(progress);
  const std::uint64_t total = progress ? total_records(inputs) : 0;

  auto writer = RunFileWriter::create(options.output, options.projection,
                                      static_cast<std::uint32_t>(inputs.size()));
  if (!writer.ok()) return writer.error();
  const geo::NormalisedMercator mercator(options.projection);

  RunSummary summary;
  summary.run_file = options.output;
  std::uint64_t done_before = 0;  // records of the inputs already finished
  std::vector<sources::SourcePoint> batch;
  std::vector<GeoPoint> geo_points;
  std::vector<RunPoint> run_points;
  std::vector<geo::LonLat> lonlat;
  batch.reserve(options.batch_size);

  for (std::size_t index = 0; index < inputs.size(); ++index) {
    const InputSpec& in = inputs[index];
    auto source = sources::open_source(in.path, in.source);
    if (!source.ok()) return source.error();
    sources::PointSource& src = **source;
    auto reprojector = Reprojector::create(src.info(), in.reproject);
    if (!reprojector.ok()) return reprojector.error();

    InputSummary s;
    s.path = src.info().path;
    s.format = src.info().format;
    s.plan = reprojector->plan();
    const auto input_tag = static_cast<std::uint16_t>(std::min<std::size_t>(index, 65535));
    const bool skip_invalid = in.source.invalid == sources::InvalidPolicy::skip;

    while (true) {
      batch.clear();
      auto got = src.read(batch, options.batch_size);
      if (!got.ok()) return got.error();
      if (*got == 0) break;
      if (auto st = reprojector->transform(batch, geo_points); !st.ok()) return st.error();
      run_points.clear();
      lonlat.clear();
      for (std::size_t i = 0; i < batch.size(); ++i) {
        const GeoPoint& g = geo_points[i];
        auto m = mercator.forward_checked(geo::LonLat{g.lon, g.lat});
        if (!m.ok() || !std::isfinite(g.h)) {
          if (skip_invalid) {
            ++s.outside_mercator;
            continue;
          }
          return Error(ErrorCode::corrupt_data,
                       s.path + ": record " + std::to_string(batch[i].record) + ": lon " +
                           std::to_string(g.lon) + ", lat " + std::to_string(g.lat) +
                           " is outside the normalised Mercator square (|lat| ≤ " +
                           std::to_string(mercator.max_latitude()) + "°)");
        }
        run_points.push_back(
            RunPoint{m->x, m->y, g.h, in.weight, input_tag, batch[i].classification});
        lonlat.push_back(geo::LonLat{g.lon, g.lat});
      }
      if (auto st = writer->append(run_points, lonlat); !st.ok()) return st.error();
      s.points_written += run_points.size();
      if (!throttle.report(done_before + src.counters().records_read, total, false)) {
        return Error(ErrorCode::cancelled, "transform cancelled while reading " + s.path);
      }
    }
    s.counters = src.counters();
    s.counters.accepted -= s.outside_mercator;
    s.counters.rejected_invalid += s.outside_mercator;
    s.notes = src.info().notes;
    s.notes.insert(s.notes.end(), s.plan.notes.begin(), s.plan.notes.end());
    done_before += s.counters.records_read;
    summary.inputs.push_back(std::move(s));
  }
  if (!throttle.report(done_before, total, true)) {
    return Error(ErrorCode::cancelled, "transform cancelled before the run file was committed");
  }
  auto header = writer->commit();
  if (!header.ok()) return header.error();
  summary.header = *header;
  return summary;
}

}  // namespace tinstream::transform
