// blocking_worker.hpp — one thread for the work an io thread must not wait for (a layer delete
// waiting for the store's write lock). Private to the server.
//
// post() from any thread; tasks run in order on the worker thread. stop() lets the queued tasks
// finish and joins (also from the destructor). A task must not throw (the handler's deferred
// answers have their own barrier, handler.cpp).
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace tinstream::server {

class BlockingWorker {
 public:
  BlockingWorker();
  ~BlockingWorker();
  BlockingWorker(const BlockingWorker&) = delete;
  BlockingWorker& operator=(const BlockingWorker&) = delete;

  void post(std::function<void()> task);
  void stop();

 private:
  void run();

  std::mutex mutex_;  // guards tasks_ and stopping_
  std::condition_variable wake_;
  std::deque<std::function<void()>> tasks_;
  bool stopping_ = false;
  std::thread thread_;  // last: started once the members above exist
};

}  // namespace tinstream::server
