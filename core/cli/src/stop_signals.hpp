// SIGINT/SIGTERM as a request to stop: while a StopOnSignals is alive, the first signal is
// recorded (stop_signal() turns non-zero) and the handlers reset themselves, so a second signal
// kills at once. A long command checks stop_signal() from its progress sink and exits with
// 128 + the signal once the operation has cleaned up. Main thread only.
#pragma once

#include <atomic>
#include <csignal>

namespace tinstream::cli {

// Constant-initialised (no guard variable), lock-free: safe to store from a signal handler.
inline std::atomic<int> g_stop_signal_flag{0};
static_assert(std::atomic<int>::is_always_lock_free);

extern "C" inline void tinstream_cli_request_stop(int signo) { g_stop_signal_flag.store(signo); }

inline int stop_signal() { return g_stop_signal_flag.load(); }

class StopOnSignals {
 public:
  StopOnSignals() {
    struct sigaction sa {};
    sa.sa_handler = tinstream_cli_request_stop;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = static_cast<int>(SA_RESETHAND);
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~StopOnSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

}  // namespace tinstream::cli
