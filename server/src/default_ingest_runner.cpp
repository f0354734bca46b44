// The ingest runner of the `tinstream-server` executable: the real pipeline (core/ingest) when it
// is built, otherwise a runner that fails jobs with a clear message.
//
// Job options (the "options" object of POST /admin/ingest, all optional), as `tinstream ingest`:
//   projection ("spherical" | "ellipsoidal"), max_points, max_level, min_level, epsilon,
//   pyramid (bool), memory_mb, threads, attribution, crs, vertical, z_units, skip_invalid (bool).
// Runs on the job worker thread (jobs.hpp); run_ingest opens its own read-write store and
// publishes the layer atomically; a sink returning false (shutdown) cancels it.
#include "default_ingest_runner.hpp"

#include "tinstream/server/ingest_options.hpp"
#include "tinstream/server/server.hpp"

namespace tinstream::server {

#ifdef TINSTREAM_SERVER_WITH_INGEST

Result<ingest::IngestOptions> ingest_options_for(const IngestJobSpec& job) {
  const nlohmann::json& o = job.options;
  // The admin API checked them before queueing the job; a runner called another way checks too.
  if (Status valid = validate_ingest_options(o); !valid) return valid.error();
  static const char* kKeys[] = {"projection", "max_points", "max_level",   "min_level",   "epsilon",
                                "pyramid",    "memory_mb",  "threads",     "attribution", "crs",
                                "vertical",   "z_units",    "skip_invalid"};
  for (const auto& [key, value] : o.items()) {
    bool known = false;
    for (const char* k : kKeys) known = known || key == k;
    if (!known) return invalid_argument("ingest option \"" + key + "\" is unknown");
  }
  ingest::IngestOptions out;
  out.store_path = job.store_path;
  out.tmp_dir = job.scratch_dir;  // private to the server; empty: the system's
  out.layer = job.layer;
  try {
    if (o.contains("projection")) {
      auto p = geo::parse_projection(o["projection"].get<std::string>());
      if (!p) return p.error();
      out.projection = *p;
    }
    out.max_points = o.value("max_points", out.max_points);
    out.max_level = o.value("max_level", out.max_level);
    out.min_level = o.value("min_level", out.min_level);
    out.epsilon = o.value("epsilon", out.epsilon);
    out.pyramid = o.value("pyramid", out.pyramid);
    out.memory_bytes = o.value("memory_mb", std::size_t{256}) << 20;
    out.threads = o.value("threads", out.threads);
    out.attribution = o.value("attribution", std::string());
    for (const auto& path : job.sources) {
      transform::InputSpec in;
      in.path = path;
      // The strict policy (#22): GDAL reads only under the job's root, CRSs are authority codes.
      in.source.raster = sources::RasterPolicy::confined(
          job.root.empty() ? path.parent_path() : job.root, job.allow_vrt);
      in.reproject.confined = true;
      in.reproject.crs = o.value("crs", std::string());
      in.reproject.vertical_datum = o.value("vertical", std::string("ellipsoidal"));
      if (o.contains("z_units")) {
        auto unit = sources::parse_linear_unit(o["z_units"].get<std::string>());
        if (!unit) return unit.error();
        in.reproject.z_unit = *unit;
      }
      if (o.value("skip_invalid", false)) in.source.invalid = sources::InvalidPolicy::skip;
      // The job's thread budget also bounds LAZ chunk decoding (as `tinstream ingest --threads`);
      // 0 (the default) is one per core for both.
      in.source.decode_threads = out.threads;
      out.inputs.push_back(std::move(in));
    }
  } catch (const nlohmann::json::exception& e) {
    return invalid_argument(std::string("ingest options: ") + e.what());
  }
  if (out.max_points < 3 || out.max_points > 65535) {
    return invalid_argument("ingest option max_points must be 3-65535");
  }
  return out;
}

IngestRunner default_ingest_runner() {
  return [](const IngestJobSpec& job, const ProgressSink& progress) -> Status {
    auto options = ingest_options_for(job);
    if (!options) return options.error();
    auto summary = ingest::run_ingest(*options, progress);
    if (!summary) return summary.error();
    return {};
  };
}

#else

IngestRunner default_ingest_runner() {
  return [](const IngestJobSpec& job, const ProgressSink&) -> Status {
    return Error(ErrorCode::unsupported,
                 "layer " + job.layer +
                     ": this build of tinstream-server has no ingest pipeline (core/ingest)");
  };
}

#endif

}  // namespace tinstream::server
