#include "tinstream/server/jobs.hpp"

#include <spdlog/spdlog.h>

#include <charconv>
#include <chrono>
#include <system_error>

namespace tinstream::server {
namespace {

std::int64_t now_unix() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

std::string_view to_string(JobState s) {
  switch (s) {
    case JobState::queued:
      return "queued";
    case JobState::running:
      return "running";
    case JobState::succeeded:
      return "succeeded";
    case JobState::failed:
      return "failed";
    case JobState::cancelled:
      return "cancelled";
  }
  return "unknown";
}

nlohmann::json JobStatus::to_json() const {
  nlohmann::json j = {
      {"id", id},
      {"layer", layer},
      {"state", to_string(state)},
      {"progress",
       {{"phase", progress.phase},
        {"done", progress.done},
        {"total", progress.total},
        {"unit", progress.unit},
        {"fraction", progress.total > 0
                         ? static_cast<double>(progress.done) / static_cast<double>(progress.total)
                         : 0.0}}},
      {"reports", reports},
      {"sources", sources},
      {"created_unix", created_unix},
      {"started_unix", started_unix},
      {"finished_unix", finished_unix},
  };
  j["errors"] = error.empty() ? nlohmann::json::array() : nlohmann::json::array({error});
  return j;
}

JobManager::JobManager(IngestRunner runner, std::uint32_t max_pending)
    : runner_(std::move(runner)), max_pending_(max_pending), worker_([this] { work(); }) {
  // spdlog's registry is a function-local static. Made here, before any job can run (and log),
  // it is destroyed after a JobManager that is itself static (a fuzz target's world): made by the
  // worker's first log line instead, it was destroyed first at exit while the worker still
  // logged a finishing job (ASan: SEGV in spdlog::sinks::sink::should_log).
  spdlog::default_logger_raw();
}

JobManager::~JobManager() { shutdown(); }

Result<std::string> JobManager::submit(IngestJobSpec spec,
                                       std::vector<std::filesystem::path> delete_after) {
  std::lock_guard lock(mutex_);
  if (stopping_) return Error(ErrorCode::unsupported, "server is shutting down");
  std::uint32_t pending = 0;
  for (const auto& [id, job] : jobs_) {
    pending += job->status.state == JobState::queued || job->status.state == JobState::running;
  }
  if (pending >= max_pending_) {
    return Error(ErrorCode::unsupported, "too many ingest jobs pending (max_queued_jobs = " +
                                             std::to_string(max_pending_) + ")");
  }
  auto job = std::make_shared<Job>();
  const std::uint64_t id = next_id_++;
  job->status.id = std::to_string(id);
  spec.job_id = job->status.id;
  job->status.layer = spec.layer;
  job->status.created_unix = now_unix();
  if (!spec.source_names.empty()) {
    job->status.sources = spec.source_names;
  } else {
    for (const auto& s : spec.sources) job->status.sources.push_back(s.filename().string());
  }
  job->spec = std::move(spec);
  job->delete_after = std::move(delete_after);
  jobs_[id] = job;
  queue_.push_back(job);
  // Keep the table bounded: forget the oldest finished jobs beyond kKeptJobs.
  while (jobs_.size() > kKeptJobs) {
    auto oldest = jobs_.end();
    for (auto it = jobs_.begin(); it != jobs_.end(); ++it) {
      const auto st = it->second->status.state;
      if (st != JobState::queued && st != JobState::running) {
        oldest = it;
        break;
      }
    }
    if (oldest == jobs_.end()) break;
    jobs_.erase(oldest);
  }
  wake_.notify_one();
  return job->status.id;
}

std::optional<JobStatus> JobManager::get(const std::string& id) const {
  std::uint64_t number = 0;
  const auto [end, ec] = std::from_chars(id.data(), id.data() + id.size(), number);
  if (ec != std::errc() || end != id.data() + id.size()) return std::nullopt;
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(number);
  if (it == jobs_.end() || it->second->status.id != id) return std::nullopt;  // "012" is no id
  return it->second->status;
}

std::vector<JobStatus> JobManager::list() const {
  std::lock_guard lock(mutex_);
  std::vector<JobStatus> out;
  for (const auto& [id, job] : jobs_) out.push_back(job->status);
  return out;
}

JobCounts JobManager::counts() const {
  std::lock_guard lock(mutex_);
  JobCounts c;
  for (const auto& [id, job] : jobs_) {
    switch (job->status.state) {
      case JobState::queued:
        ++c.queued;
        break;
      case JobState::running:
        ++c.running;
        break;
      case JobState::succeeded:
        ++c.succeeded;
        break;
      case JobState::failed:
        ++c.failed;
        break;
      case JobState::cancelled:
        ++c.cancelled;
        break;
    }
  }
  return c;
}

void JobManager::shutdown() {
  {
    std::lock_guard lock(mutex_);
    if (stopping_ && !worker_.joinable()) return;
    stopping_ = true;
    for (auto& job : queue_) {
      job->spec.held.clear();
      job->status.state = JobState::cancelled;
      job->status.error = "server shut down before the job started";
      job->status.finished_unix = now_unix();
      for (const auto& p : job->delete_after) {
        std::error_code ec;
        std::filesystem::remove(p, ec);
      }
    }
    queue_.clear();
  }
  wake_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void JobManager::work() {
  while (true) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping
      job = queue_.front();
      queue_.pop_front();
      job->status.state = JobState::running;
      job->status.started_unix = now_unix();
    }
    spdlog::info("ingest job {} started: layer {}", job->status.id, job->spec.layer);
    ProgressSink sink = [this, job](const Progress& p) {
      std::lock_guard lock(mutex_);
      job->status.progress = p;
      ++job->status.reports;
      return !stopping_;
    };
    Status result = [&]() -> Status {
      if (!runner_) return Error(ErrorCode::unsupported, "no ingest runner configured");
      try {
        return runner_(job->spec, sink);
      } catch (const std::exception& e) {
        return Error(ErrorCode::internal, std::string("ingest threw: ") + e.what());
      }
    }();
    for (const auto& p : job->delete_after) {
      std::error_code ec;
      std::filesystem::remove(p, ec);
    }
    std::lock_guard lock(mutex_);
    job->spec.held.clear();  // the sources' descriptors: the finished job stays in the list
    job->status.finished_unix = now_unix();
    if (result.ok()) {
      job->status.state = JobState::succeeded;
      spdlog::info("ingest job {} succeeded: layer {}", job->status.id, job->spec.layer);
    } else {
      job->status.state =
          result.error().code == ErrorCode::cancelled ? JobState::cancelled : JobState::failed;
      job->status.error = result.error().message;
      spdlog::warn("ingest job {} {}: {}", job->status.id, to_string(job->status.state),
                   result.error().message);
    }
  }
}

}  // namespace tinstream::server
