#include "tinstream/server/metrics.hpp"

#include <fmt/format.h>

namespace tinstream::server {

std::size_t Metrics::route_index(std::string_view route) {
  for (std::size_t i = 0; i < kRoutes.size(); ++i) {
    if (kRoutes[i] == route) return i;
  }
  return kRoutes.size() - 1;  // "other"
}

std::size_t Metrics::status_index(int status) {
  for (std::size_t i = 0; i + 1 < kStatuses.size(); ++i) {
    if (kStatuses[i] == status) return i;
  }
  return kStatuses.size() - 1;  // "other"
}

void Metrics::record(std::string_view route, int status, std::uint64_t bytes_sent, double seconds) {
  requests_[route_index(route)][status_index(status)].fetch_add(1, std::memory_order_relaxed);
  bytes_sent_.fetch_add(bytes_sent, std::memory_order_relaxed);
  std::size_t b = 0;
  while (b < kBuckets.size() && seconds > kBuckets[b]) ++b;
  latency_buckets_[b].fetch_add(1, std::memory_order_relaxed);
  latency_sum_us_.fetch_add(static_cast<std::uint64_t>(seconds * 1e6), std::memory_order_relaxed);
  latency_count_.fetch_add(1, std::memory_order_relaxed);
}

std::string Metrics::render(const JobCounts& jobs) const {
  std::string out;
  out += "# HELP tinstream_http_requests_total HTTP requests by route and status.\n";
  out += "# TYPE tinstream_http_requests_total counter\n";
  for (std::size_t r = 0; r < kRoutes.size(); ++r) {
    for (std::size_t s = 0; s < kStatuses.size(); ++s) {
      const auto v = requests_[r][s].load(std::memory_order_relaxed);
      if (v == 0) continue;
      const std::string status = kStatuses[s] == 0 ? "other" : std::to_string(kStatuses[s]);
      out += fmt::format("tinstream_http_requests_total{{route=\"{}\",status=\"{}\"}} {}\n",
                         kRoutes[r], status, v);
    }
  }
  out +=
      "# HELP tinstream_http_request_duration_seconds Time from request parsed to response handed "
      "to the socket.\n";
  out += "# TYPE tinstream_http_request_duration_seconds histogram\n";
  std::uint64_t cumulative = 0;
  for (std::size_t b = 0; b < kBuckets.size(); ++b) {
    cumulative += latency_buckets_[b].load(std::memory_order_relaxed);
    out += fmt::format("tinstream_http_request_duration_seconds_bucket{{le=\"{}\"}} {}\n",
                       kBuckets[b], cumulative);
  }
  cumulative += latency_buckets_[kBuckets.size()].load(std::memory_order_relaxed);
  out +=
      fmt::format("tinstream_http_request_duration_seconds_bucket{{le=\"+Inf\"}} {}\n", cumulative);
  out += fmt::format("tinstream_http_request_duration_seconds_sum {}\n",
                     static_cast<double>(latency_sum_us_.load(std::memory_order_relaxed)) / 1e6);
  out += fmt::format("tinstream_http_request_duration_seconds_count {}\n",
                     latency_count_.load(std::memory_order_relaxed));
  out += "# HELP tinstream_http_response_bytes_total Response body bytes sent.\n";
  out += "# TYPE tinstream_http_response_bytes_total counter\n";
  out += fmt::format("tinstream_http_response_bytes_total {}\n",
                     bytes_sent_.load(std::memory_order_relaxed));
  out += "# HELP tinstream_http_open_connections Connections currently open.\n";
  out += "# TYPE tinstream_http_open_connections gauge\n";
  out += fmt::format("tinstream_http_open_connections {}\n", open_connections());
  out +=
      "# HELP tinstream_http_rejected_connections_total Connections refused at max_connections.\n";
  out += "# TYPE tinstream_http_rejected_connections_total counter\n";
  out += fmt::format("tinstream_http_rejected_connections_total {}\n",
                     rejected_connections_.load(std::memory_order_relaxed));
  out +=
      "# HELP tinstream_accept_errors_total Failed accept() calls (out of descriptors: retried "
      "after a pause).\n";
  out += "# TYPE tinstream_accept_errors_total counter\n";
  out += fmt::format("tinstream_accept_errors_total {}\n",
                     accept_errors_.load(std::memory_order_relaxed));
  out += "# HELP tinstream_ingest_jobs Ingest jobs by state.\n";
  out += "# TYPE tinstream_ingest_jobs gauge\n";
  out += fmt::format("tinstream_ingest_jobs{{state=\"queued\"}} {}\n", jobs.queued);
  out += fmt::format("tinstream_ingest_jobs{{state=\"running\"}} {}\n", jobs.running);
  out += fmt::format("tinstream_ingest_jobs{{state=\"succeeded\"}} {}\n", jobs.succeeded);
  out += fmt::format("tinstream_ingest_jobs{{state=\"failed\"}} {}\n", jobs.failed);
  out += fmt::format("tinstream_ingest_jobs{{state=\"cancelled\"}} {}\n", jobs.cancelled);
  return out;
}

}  // namespace tinstream::server
