#include "progress_printer.hpp"

#include <unistd.h>

#include <cstdio>

namespace tinstream::cli {
namespace {

std::string human(double v) {
  char buf[32];
  if (v >= 1e9) {
    std::snprintf(buf, sizeof buf, "%.2fG", v / 1e9);
  } else if (v >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.2fM", v / 1e6);
  } else if (v >= 1e4) {
    std::snprintf(buf, sizeof buf, "%.1fk", v / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f", v);
  }
  return buf;
}

std::string duration(double s) {
  char buf[32];
  if (s >= 3600) {
    std::snprintf(buf, sizeof buf, "%dh%02dm", static_cast<int>(s / 3600),
                  static_cast<int>(s / 60) % 60);
  } else if (s >= 60) {
    std::snprintf(buf, sizeof buf, "%dm%02ds", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%.0fs", s);
  }
  return buf;
}

}  // namespace

ProgressPrinter::ProgressPrinter(bool quiet) : quiet_(quiet), tty_(::isatty(STDERR_FILENO) != 0) {}

ProgressPrinter::~ProgressPrinter() { finish(); }

ProgressSink ProgressPrinter::sink() {
  return [this](const Progress& p) { return report(p); };
}

void ProgressPrinter::finish() {
  std::lock_guard lock(mutex_);
  if (line_open_) std::fputc('\n', stderr);
  line_open_ = false;
}

bool ProgressPrinter::report(const Progress& p) {
  if (quiet_) return true;
  std::lock_guard lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  const bool new_phase = p.phase != phase_;
  if (new_phase) {
    if (line_open_) std::fputc('\n', stderr);
    line_open_ = false;
    phase_ = p.phase;
    phase_start_ = now;
  }
  const bool last = p.total != 0 && p.done >= p.total;
  const auto since = std::chrono::duration<double>(now - last_print_).count();
  if (!new_phase && !last && since < (tty_ ? 0.2 : 5.0)) return true;
  last_print_ = now;
  const double elapsed = std::chrono::duration<double>(now - phase_start_).count();
  const double rate = elapsed > 0 ? static_cast<double>(p.done) / elapsed : 0.0;
  std::string line = p.phase + ": " + human(static_cast<double>(p.done));
  if (p.total != 0) {
    char pct[16];
    std::snprintf(pct, sizeof pct, " (%.1f%%)",
                  100.0 * static_cast<double>(p.done) / static_cast<double>(p.total));
    line += "/" + human(static_cast<double>(p.total)) + " " + p.unit + pct;
  } else {
    line += " " + p.unit;
  }
  if (elapsed > 0.5) line += ", " + human(rate) + " " + p.unit + "/s";
  if (p.total != 0 && rate > 0 && !last) {
    line += ", ETA " + duration(static_cast<double>(p.total - std::min(p.done, p.total)) / rate);
  }
  if (tty_) {
    std::fprintf(stderr, "\r\033[K%s", line.c_str());
    line_open_ = true;
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  std::fflush(stderr);
  return true;
}

}  // namespace tinstream::cli
