// The admin job's options as the ingest pipeline's (src/default_ingest_runner.cpp), for the
// runner and its tests; only in builds with the ingest pipeline (TINSTREAM_SERVER_WITH_INGEST).
#pragma once

#include "tinstream/server/jobs.hpp"

#ifdef TINSTREAM_SERVER_WITH_INGEST
#include "tinstream/ingest/ingest.hpp"

namespace tinstream::server {

// The job's options (checked again: a runner may be called another way) and its sources, each
// confined to the job's root; unknown keys and out-of-range values are errors.
Result<ingest::IngestOptions> ingest_options_for(const IngestJobSpec& job);

}  // namespace tinstream::server
#endif
