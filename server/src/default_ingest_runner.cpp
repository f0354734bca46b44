// The ingest runner of the `tinstream-server` executable.
//
// PLUG-IN POINT for the ingest pipeline (core/ingest): replace the body of
// default_ingest_runner() with a call into it, e.g.
//
//   return [](const IngestJobSpec& job, const ProgressSink& progress) -> Status {
//     ingest::Options o = ingest::options_from_json(job.options);  // layer options
//     return ingest::run(job.sources, job.store_path, job.layer, o, progress);
//   };
//
// The runner runs on the job worker thread, opens its own read-write TileStore on
// job.store_path, writes the layer through begin_layer()/LayerWriter and publishes it at the
// end; it should return ErrorCode::cancelled when `progress` returns false.
#include "tinstream/server/server.hpp"

namespace tinstream::server {

IngestRunner default_ingest_runner() {
  return [](const IngestJobSpec& job, const ProgressSink&) -> Status {
    return Error(ErrorCode::unsupported,
                 "layer " + job.layer + ": this build of tinstream-server has no ingest pipeline linked in");
  };
}

}  // namespace tinstream::server
