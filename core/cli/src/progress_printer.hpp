// A ProgressSink for terminals: one self-overwriting line per phase with rate and ETA on a TTY,
// or one plain line every few seconds otherwise (logs, CI). Thread-safe (the sink may be called
// from worker threads).
#pragma once

#include <chrono>
#include <mutex>
#include <string>

#include "tinstream/base/progress.hpp"

namespace tinstream::cli {

class ProgressPrinter {
 public:
  explicit ProgressPrinter(bool quiet = false);
  ~ProgressPrinter();
  ProgressSink sink();
  void finish();  // ends the current line

 private:
  bool report(const Progress& p);
  std::mutex mutex_;
  bool quiet_;
  bool tty_;
  std::string phase_;
  std::chrono::steady_clock::time_point phase_start_, last_print_;
  bool line_open_ = false;
};

}  // namespace tinstream::cli
