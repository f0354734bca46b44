// tinstream/server/jobs.hpp — admin ingest jobs, run one at a time on a background worker.
//
// The server does not know how to ingest: it is handed an IngestRunner (the lead plugs the real
// pipeline in through server/src/default_ingest_runner.cpp). The runner is called on the job
// worker thread — never on an io thread — with the validated job and a ProgressSink; it writes
// the layer through store::TileStore::begin_layer / LayerWriter::publish on its own read-write
// TileStore, so readers see the new layer atomically when it publishes. Returning false from the
// sink's callback means "cancel" (server shutdown); the runner then returns ErrorCode::cancelled.
//
// Threads: submit()/get()/list()/counts() from any thread (one mutex guards the job table); the
// runner on the worker thread only. The destructor cancels the running job and joins the worker.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tinstream/base/progress.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/server/ingest_paths.hpp"
#include "tinstream/server/metrics.hpp"

namespace tinstream::server {

struct IngestJobSpec {
  std::string job_id;
  std::string layer;                           // valid layer name
  std::vector<std::filesystem::path> sources;  // canonical, existing, under data_root or uploads
  nlohmann::json options = nlohmann::json::object();  // passed through from the request
  std::filesystem::path store_path;                   // the server's store (open it read-write)
  std::filesystem::path scratch_dir;  // private (0700) folder for temporary files; may be empty
  // How the job names its sources to the admin (relative to the data root, or the uploaded
  // name); empty: their file names.
  std::vector<std::string> source_names;
  // Sources opened when the job was submitted (ingest_paths.hpp), held until the job is gone.
  std::vector<std::shared_ptr<const HeldSource>> held;
  // Ingest confinement (sources::RasterPolicy): every file the ingest reads, a VRT's sources
  // included, lies under `root` — the data root, or the upload directory for an upload (which
  // may not be a VRT: its sources could not have been uploaded with it).
  std::filesystem::path root;
  bool allow_vrt = true;
};

using IngestRunner = std::function<Status(const IngestJobSpec&, const ProgressSink&)>;

enum class JobState { queued, running, succeeded, failed, cancelled };
std::string_view to_string(JobState s);

struct JobStatus {
  std::string id;
  std::string layer;
  JobState state = JobState::queued;
  Progress progress;          // latest report
  std::uint64_t reports = 0;  // progress reports received
  std::string error;          // when failed/cancelled
  std::int64_t created_unix = 0, started_unix = 0, finished_unix = 0;
  std::vector<std::string> sources;

  nlohmann::json to_json() const;
};

class JobManager {
 public:
  // Finished jobs beyond this many are forgotten, oldest (lowest id) first.
  static constexpr std::size_t kKeptJobs = 1000;

  JobManager(IngestRunner runner, std::uint32_t max_pending);
  ~JobManager();
  JobManager(const JobManager&) = delete;
  JobManager& operator=(const JobManager&) = delete;

  // Queues a job (its id is assigned here). Files in `delete_after` are removed when the job ends.
  // Error (unsupported → 503) when max_pending jobs are queued or running.
  Result<std::string> submit(IngestJobSpec spec,
                             std::vector<std::filesystem::path> delete_after = {});
  std::optional<JobStatus> get(const std::string& id) const;
  std::vector<JobStatus> list() const;  // oldest first
  JobCounts counts() const;
  // Cancels queued jobs and asks the running one to stop; joins the worker.
  void shutdown();

 private:
  struct Job {
    JobStatus status;
    IngestJobSpec spec;
    std::vector<std::filesystem::path> delete_after;
  };
  void work();

  IngestRunner runner_;
  std::uint32_t max_pending_;
  mutable std::mutex mutex_;  // guards everything below
  std::condition_variable wake_;
  std::map<std::uint64_t, std::shared_ptr<Job>> jobs_;  // by id: oldest first
  std::deque<std::shared_ptr<Job>> queue_;
  std::uint64_t next_id_ = 1;
  bool stopping_ = false;
  std::thread worker_;  // last: started after the members above exist
};

}  // namespace tinstream::server
