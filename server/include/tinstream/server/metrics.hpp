// tinstream/server/metrics.hpp — counters for `GET /metrics` (Prometheus text format 0.0.4).
// Thread-safe: every member may be called from any io thread (atomics, no locks on the hot path).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include "tinstream/server/routes.hpp"

namespace tinstream::server {

struct JobCounts {
  std::uint64_t queued = 0, running = 0, succeeded = 0, failed = 0, cancelled = 0;
};

class Metrics {
 public:
  // Route labels known to the server (every route's kName, routes.hpp); anything else is
  // counted as "other".
  static constexpr auto kRoutes = kRouteLabels;
  static constexpr std::array<int, 19> kStatuses = {
      200, 202, 204, 304, 400, 401, 403, 404, 405, 409, 411, 413, 415, 431, 500, 503, 507, 408, 0};
  // Latency histogram upper bounds, seconds.
  static constexpr std::array<double, 12> kBuckets = {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005,
                                                      0.01,   0.025,   0.05,   0.1,   0.5,    2.5};

  void record(std::string_view route, int status, std::uint64_t bytes_sent, double seconds);
  void connection_opened() { open_connections_.fetch_add(1, std::memory_order_relaxed); }
  void connection_closed() { open_connections_.fetch_sub(1, std::memory_order_relaxed); }
  std::int64_t open_connections() const {
    return open_connections_.load(std::memory_order_relaxed);
  }
  void connection_rejected() { rejected_connections_.fetch_add(1, std::memory_order_relaxed); }
  void accept_failed() { accept_errors_.fetch_add(1, std::memory_order_relaxed); }

  std::string render(const JobCounts& jobs) const;

 private:
  static std::size_t route_index(std::string_view route);
  static std::size_t status_index(int status);

  std::array<std::array<std::atomic<std::uint64_t>, kStatuses.size()>, kRoutes.size()> requests_{};
  std::array<std::atomic<std::uint64_t>, kBuckets.size() + 1> latency_buckets_{};
  std::atomic<std::uint64_t> latency_sum_us_{0};
  std::atomic<std::uint64_t> latency_count_{0};
  std::atomic<std::uint64_t> bytes_sent_{0};
  std::atomic<std::int64_t> open_connections_{0};
  std::atomic<std::uint64_t> rejected_connections_{0};
  std::atomic<std::uint64_t> accept_errors_{0};
};

}  // namespace tinstream::server
