// tinstream/base/worker_threads.hpp — the exception barrier of worker threads, and a group of
// threads that is always joined.
//
// Contract (STYLE.md: nothing a job does may terminate a serving process):
// - guarded(what, body) runs body and turns any exception escaping it into an internal Error
//   "<what>: <exception text>"; a body returning Status gives that Status.
// - WorkerThreads starts threads whose bodies run inside guarded(): an exception in a body is
//   kept as the group's first failure instead of reaching std::terminate. start() reports a
//   thread that cannot be created as an Error (what std::thread throws then) instead of letting it
//   unwind through running threads; the threads already started keep running, and the caller
//   tells them to stop the way it usually does, then join()s. The destructor joins whatever is
//   still running, so a WorkerThreads is never destroyed with a joinable thread.
// - Fault points (fault.hpp): "<point>.spawn" before each thread is created.
// Threads: start() and join() from one owning thread; bodies run on the workers.
#pragma once

#include <exception>
#include <functional>
#include <mutex>
#include <new>
#include <string>
#include <string_view>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "tinstream/base/fault.hpp"
#include "tinstream/base/result.hpp"

namespace tinstream {

// Runs body() (returning void or Status) and returns its Status, or an internal Error naming
// `what` and the exception that escaped it.
template <typename F>
Status guarded(std::string_view what, F&& body) noexcept {
  try {
    if constexpr (std::is_same_v<std::invoke_result_t<F&>, Status>) {
      return body();
    } else {
      body();
      return {};
    }
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::internal, std::string(what) + ": out of memory");
  } catch (const std::exception& e) {
    return Error(ErrorCode::internal, std::string(what) + ": " + e.what());
  } catch (...) {
    return Error(ErrorCode::internal, std::string(what) + ": unknown exception");
  }
}

class WorkerThreads {
 public:
  // `name` names the group in errors ("pass 3 worker: …"); `point` is the group's fault point,
  // "<point>.spawn" the one passed before each thread is created.
  WorkerThreads(std::string name, std::string point)
      : name_(std::move(name)), spawn_point_(std::move(point) + ".spawn") {}
  ~WorkerThreads() { (void)join(); }
  WorkerThreads(const WorkerThreads&) = delete;
  WorkerThreads& operator=(const WorkerThreads&) = delete;

  // Starts one thread running body() (void or Status) inside guarded(); a failure it returns or
  // throws becomes the group's first failure (join()). An Error when the thread cannot be
  // created; nothing was started then.
  template <typename F>
  Status start(F body) {
    Status created = guarded(name_ + ": cannot start a thread", [&] {
      fault::point(spawn_point_);
      threads_.emplace_back([this, body = std::move(body)]() mutable {
        Status s = guarded(name_, body);
        if (!s.ok()) record(std::move(s));
      });
    });
    return created;
  }
  // Joins every started thread; the first failure of a body, if any. Idempotent.
  Status join() {
    for (auto& t : threads_) {
      if (t.joinable()) t.join();
    }
    threads_.clear();
    std::lock_guard lock(mutex_);
    return failure_;
  }
  std::size_t started() const { return threads_.size(); }

 private:
  void record(Status s) {
    std::lock_guard lock(mutex_);
    if (failure_.ok()) failure_ = std::move(s);
  }

  std::string name_;
  std::string spawn_point_;
  std::mutex mutex_;  // guards failure_
  Status failure_;
  std::vector<std::thread> threads_;
};

}  // namespace tinstream
