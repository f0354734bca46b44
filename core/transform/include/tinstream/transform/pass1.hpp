// tinstream/transform/pass1.hpp — ingest pass 1 (docs/DESIGN.md §3.1): read every input, reproject
// to WGS84, map to normalised Mercator, and hand the points on in batches (on_points, the ingest
// gives them to pass 2, whose sorted spills are the only files of transformed points); the
// summary keeps the run's header (count, boxes, height range).
//
// Contract:
// - Inputs are processed in order, each with its own reader options and CRS options; formats
//   may be mixed. Memory is bounded by TransformOptions::batch_size (a few batches of points),
//   never by the inputs' sizes.
// - Pass 1 writes no file. On any error, or when the progress sink asks to stop, the pass stops
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

namespace tinstream::transform {

inline constexpr double kMaxAbsHeight = 1e5;  // metres, ellipsoidal

// One transformed point, as handed on.
struct RunPoint {
  double x = 0, y = 0;  // normalised Mercator
  double z = 0;         // metres above the WGS84 ellipsoid
  float weight = 1;
  std::uint16_t input = 0;          // index of the input (saturates at 65535)
  std::uint8_t classification = 0;  // ASPRS class (0 where the format has none)
};

struct Extent {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;
  bool empty() const { return min_x > max_x; }
};

// What pass 1 learnt about all its points.
struct RunHeader {
  std::uint64_t point_count = 0;
  geo::Projection projection = geo::Projection::spherical;
  // With no points, the extents are empty() (min = +inf, max = -inf) and so is the z range.
  Extent mercator;  // normalised Mercator
  Extent lonlat;    // x = lon, y = lat, degrees
  double min_z = 0, max_z = 0;
  std::uint32_t input_count = 0;
};

struct InputSpec {
  std::filesystem::path path;
  sources::SourceOptions source;  // format, class filter, text layout, invalid policy
  ReprojectOptions reproject;     // CRS override, z unit, vertical datum
  float weight = 1;               // written to every point of this input
};

struct TransformOptions {
  geo::Projection projection = geo::Projection::spherical;
  std::size_t batch_size = 65536;  // points per batch; Requires: > 0
  // > 1: that many worker threads (each with its own Reprojector) transform batches while this
  // thread reads the next ones and hands finished ones on; the points handed on are the same
  // (batches go in record order, and the first error in record order is the one reported).
  unsigned threads = 1;
  // Called on the calling thread with every batch of transformed points, in record order (the
  // ingest hands them to pass 2). An error stops the pass and is returned. Requires: set.
  std::function<Status(std::span<const RunPoint>)> on_points;
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
  RunHeader header;  // count, Mercator and lon/lat boxes, z range
  std::vector<InputSummary> inputs;
};

Result<RunSummary> transform_sources(std::span<const InputSpec> inputs,
                                     const TransformOptions& options,
                                     const ProgressSink& progress = {});

}  // namespace tinstream::transform
