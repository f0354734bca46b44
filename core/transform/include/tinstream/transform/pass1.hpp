// tinstream/transform/pass1.hpp — ingest pass 1 (DESIGN.md §3): read every input, reproject
// to WGS84, map to normalised Mercator, and hand the points on in batches (on_points) and/or
// stream them into one run file; the summary has the run's header (count, boxes) either way.
//
// Contract:
// - Inputs are processed in order, each with its own reader options and CRS options; formats
//   may be mixed. Memory is bounded by TransformOptions::batch_size (a few batches of points),
//   never by the inputs' sizes.
// - A run file (when TransformOptions::output is set) appears under that name only when every
//   input went through: it is written under a temporary name and renamed at the end (see
//   run_file.hpp). On any error, or when the progress sink asks to stop, nothing is left behind
//   and the Error names the file and the record.
// - A point outside the Mercator square (|lat| beyond ±85.05° spherical / ±85.08° ellipsoidal)
//   is an Error naming the record, like any other invalid point; with InvalidPolicy::skip it is
//   counted as invalid instead.
// - A height beyond the Earth's range (|ellipsoidal h| > kMaxAbsHeight: 100 km, where the deepest
//   trench is 11 km down and the highest summit 9 km up) is an Error naming the record — an
//   undeclared NODATA value such as -3.4e38, or wrong z units — or, with InvalidPolicy::skip,
//   counted as invalid; it never reaches the store.
// - Progress: phase "transform", unit "records", done = records read over all inputs, total =
//   the sum of the inputs' record counts when all are known in advance (LAS, rasters), else 0.
//   The sink is called from the calling thread, at most about 5 times a second, and once at the
//   end. Returning false cancels (ErrorCode::cancelled).
// Threads: runs on the calling thread, plus TransformOptions::threads workers when it is > 1.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/sources/point_source.hpp"
#include "tinstream/transform/reprojector.hpp"
#include "tinstream/transform/run_file.hpp"

namespace tinstream::transform {

inline constexpr double kMaxAbsHeight = 1e5;  // metres, ellipsoidal

struct InputSpec {
  std::filesystem::path path;
  sources::SourceOptions source;  // format, class filter, text layout, invalid policy
  ReprojectOptions reproject;     // CRS override, z unit, vertical datum
  float weight = 1;               // written to every point of this input
};

struct TransformOptions {
  // The run file; empty: none is written (the ingest's case: its points go to pass 2 through
  // on_points, whose sorted spills are the run files). Requires: set, or on_points given.
  std::filesystem::path output;
  geo::Projection projection = geo::Projection::spherical;
  std::size_t batch_size = 65536;  // points per batch; Requires: > 0
  // > 1: that many worker threads (each with its own Reprojector) transform batches while this
  // thread reads the next ones and appends finished ones; the run file is the same (batches are
  // appended in record order, and the first error in record order is the one reported).
  unsigned threads = 1;
  // Called on the calling thread with every batch of transformed points (after it is appended to
  // the run file, if any), in record order (the ingest hands them to pass 2). An error stops the
  // pass and is returned.
  std::function<Status(std::span<const RunPoint>)> on_points;
  // false: the run file is not fsynced before its rename (a scratch file its user removes soon).
  bool durable = true;
};

struct InputSummary {
  std::string path;
  std::string format;
  ReprojectionPlan plan;               // CRS used, z unit and the rule that chose it, geoid grid
  sources::SourceCounters counters;    // records read / rejected by class, NODATA, invalid
  std::uint64_t outside_mercator = 0;  // counted in counters.rejected_invalid too
  // |ellipsoidal height| > kMaxAbsHeight (skipped under InvalidPolicy::skip); in rejected_invalid.
  std::uint64_t implausible_height = 0;
  std::uint64_t points_written = 0;
  std::vector<std::string> notes;  // the reader's and reprojector's remarks
};

struct RunSummary {
  std::filesystem::path run_file;  // empty when none was written
  RunFileHeader header;            // count, Mercator and lon/lat boxes, z range
  std::vector<InputSummary> inputs;
};

Result<RunSummary> transform_sources(std::span<const InputSpec> inputs,
                                     const TransformOptions& options,
                                     const ProgressSink& progress = {});

}  // namespace tinstream::transform
