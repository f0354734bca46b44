// The exception barrier, the always-joined thread group and the fault points they are tested with.
#include "tinstream/base/worker_threads.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <csignal>
#include <cstdlib>

namespace tinstream {
namespace {

TEST(Guarded, ExceptionsBecomeInternalErrorsNamingTheWorker) {
  Status s = guarded("pass 9 worker", [] { throw std::runtime_error("boom"); });
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::internal);
  EXPECT_EQ(s.error().message, "pass 9 worker: boom");
  s = guarded("w", [] { throw std::bad_alloc(); });
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message, "w: out of memory");
  s = guarded("w", [] { throw 42; });
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message, "w: unknown exception");
  // A body's own Status passes through unchanged; a void body that returns is ok.
  s = guarded("w", []() -> Status { return io_error("disk full"); });
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::io_error);
  EXPECT_EQ(s.error().message, "disk full");
  EXPECT_TRUE(guarded("w", [] {}).ok());
}

TEST(WorkerThreads, AThrowingBodyIsTheGroupsFailureNotTerminate) {
  WorkerThreads group("pool", "pool");
  std::atomic<int> ran{0};
  ASSERT_TRUE(group.start([&] { ++ran; }).ok());
  ASSERT_TRUE(group
                  .start([&]() -> Status {
                    ++ran;
                    throw std::runtime_error("bad tile");
                  })
                  .ok());
  const Status s = group.join();
  EXPECT_EQ(ran.load(), 2);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message, "pool: bad tile");
  EXPECT_EQ(group.started(), 0u);   // joined
  EXPECT_FALSE(group.join().ok());  // idempotent: the failure stays
}

TEST(WorkerThreads, ABodysReturnedErrorIsKeptFirstComeFirst) {
  WorkerThreads group("pool", "pool");
  ASSERT_TRUE(group.start([]() -> Status { return corrupt_data("first"); }).ok());
  ASSERT_TRUE(group.join().error().message == "first");
}

// Waits until released; for threads that must still run while the test does something.
struct Gate {
  std::mutex mutex;
  std::condition_variable cv;
  bool open = false;
  void wait() {
    std::unique_lock lock(mutex);
    cv.wait(lock, [&] { return open; });
  }
  void release() {
    {
      std::lock_guard lock(mutex);
      open = true;
    }
    cv.notify_all();
  }
};

TEST(WorkerThreads, AThreadThatCannotBeCreatedIsAnErrorAndTheRunningOnesAreJoined) {
  if (!fault::enabled()) GTEST_FAIL() << "fault points are not compiled into this test build";
  const fault::Arm arm("pool.spawn", 1, fault::Kind::no_thread);  // the second start fails
  Gate gate;
  std::atomic<int> ran{0};
  Status second;
  {
    WorkerThreads group("pool", "pool");
    ASSERT_TRUE(group
                    .start([&] {
                      gate.wait();
                      ++ran;
                    })
                    .ok());
    second = group.start([&] { ++ran; });
    EXPECT_EQ(group.started(), 1u);
    gate.release();  // the caller tells the running thread to stop, then the group joins
  }                  // before the fix (a vector of std::thread unwound here), std::terminate
  EXPECT_TRUE(arm.fired());
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.error().code, ErrorCode::internal);
  EXPECT_NE(second.error().message.find("pool: cannot start a thread"), std::string::npos)
      << second.error().message;
  EXPECT_EQ(ran.load(), 1);
}

TEST(FaultPoints, AnArmedPointFailsOnceAfterItsSkipAndOnlyWhileArmed) {
  if (!fault::enabled()) GTEST_FAIL() << "fault points are not compiled into this test build";
  fault::point("test.point");  // nothing armed: nothing happens
  {
    const fault::Arm arm("test.point", 2);
    fault::point("test.point");
    fault::point("test.other");
    fault::point("test.point");
    EXPECT_FALSE(arm.fired());
    EXPECT_THROW(fault::point("test.point"), std::runtime_error);
    EXPECT_TRUE(arm.fired());
    fault::point("test.point");  // once
  }
  fault::point("test.point");
  const fault::Arm oom("test.oom", 0, fault::Kind::out_of_memory);
  EXPECT_THROW(fault::point("test.oom"), std::bad_alloc);
  const fault::Arm thread("test.thread", 0, fault::Kind::no_thread);
  try {
    fault::point("test.thread");
    ADD_FAILURE() << "no exception";
  } catch (const std::system_error& e) {
    EXPECT_EQ(e.code().value(), EAGAIN);
  }
}

TEST(FaultPoints, ErrorKindFailsTimesPassesThroughErrorAtNamingEachPass) {
  if (!fault::enabled()) GTEST_FAIL() << "fault points are not compiled into this test build";
  EXPECT_FALSE(fault::error_at("test.read").has_value());
  const fault::Arm arm("test.read", 1, fault::Kind::error, 2);
  EXPECT_FALSE(fault::error_at("test.read").has_value());
  EXPECT_EQ(fault::error_at("test.read"), "injected error at test.read (pass 2)");
  EXPECT_EQ(fault::error_at("test.read"), "injected error at test.read (pass 3)");
  EXPECT_FALSE(fault::error_at("test.read").has_value());
  EXPECT_EQ(arm.fired_times(), 2u);
}

TEST(FaultPoints, PauseHoldsTheThreadAtThePointUntilReleased) {
  if (!fault::enabled()) GTEST_FAIL() << "fault points are not compiled into this test build";
  fault::Arm hold("test.pause", 1, fault::Kind::pause);
  std::atomic<int> passed{0};
  std::jthread worker([&] {
    fault::point("test.pause");  // skipped
    ++passed;
    fault::point("test.pause");  // held here
    ++passed;
  });
  ASSERT_TRUE(hold.wait_paused());
  EXPECT_EQ(passed.load(), 1);  // held: it cannot have gone on
  hold.release();
  worker.join();
  EXPECT_EQ(passed.load(), 2);
}

// A child process armed through TINSTREAM_FAULT: the stop kind stops it at the point (the parent
// sees it stopped), and it continues from there when resumed.
TEST(FaultPoints, TheEnvironmentArmsAChildProcessAndStopStopsItThere) {
  if (!fault::enabled()) GTEST_FAIL() << "fault points are not compiled into this test build";
  const std::string child = std::string(TINSTREAM_BINARY_DIR) + "/bin/fault_point_child";
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::setenv("TINSTREAM_FAULT", "child.bad:nonsense,child.step@1:stop,child.throw:oom", 1);
    ::execl(child.c_str(), child.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, WUNTRACED), pid);
  const bool stopped = WIFSTOPPED(status);
  if (stopped) ::kill(pid, SIGCONT);
  if (!WIFEXITED(status) && !WIFSIGNALED(status)) {
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  }
  EXPECT_TRUE(stopped);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 7);
}

}  // namespace
}  // namespace tinstream
