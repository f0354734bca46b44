// bench/laz: decode throughput of our LAZ decoder (core/sources/laz) on one file: every record
// of the file decoded RUNS times (a fresh reader each run), on THREADS decoding threads.
// Prints one JSON line with each run's wall and process-CPU seconds and the records' sha256
// (the first run), to compare with laz-perf's line from lazperf_decode.mjs.
//   laz_bench FILE [THREADS] [RUNS] [all|geometry]
#include <openssl/evp.h>
#include <time.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "tinstream/sources/las_records.hpp"

namespace {

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: laz_bench FILE [THREADS] [RUNS] [all|geometry]\n");
    return 2;
  }
  const std::string file = argv[1];
  const unsigned threads = argc > 2 ? static_cast<unsigned>(std::atoi(argv[2])) : 1;
  const int runs = argc > 3 ? std::atoi(argv[3]) : 3;
  const bool geometry = argc > 4 && std::string(argv[4]) == "geometry";
  std::string sha, walls, cpus;
  std::uint64_t records = 0;
  unsigned used_threads = 0;
  for (int run = 0; run < runs; ++run) {
    const double cpu0 = cpu_seconds();
    const auto wall0 = std::chrono::steady_clock::now();
    tinstream::sources::RecordOptions options;
    options.threads = threads;
    options.geometry_and_class_only = geometry;
    auto reader = tinstream::sources::LasRecordReader::open(file, options);
    if (!reader.ok()) {
      std::fprintf(stderr, "%s\n", reader.error().message.c_str());
      return 1;
    }
    used_threads = (*reader)->laz() ? (*reader)->laz()->threads() : 0;
    const std::size_t rl = (*reader)->summary().record_length;
    std::vector<std::uint8_t> buf(65536 * rl);
    EVP_MD_CTX* ctx = run == 0 ? EVP_MD_CTX_new() : nullptr;
    if (ctx) EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
    records = 0;
    for (;;) {
      auto n = (*reader)->read(buf.data(), 65536);
      if (!n.ok()) {
        std::fprintf(stderr, "%s\n", n.error().message.c_str());
        return 1;
      }
      if (*n == 0) break;
      if (ctx) EVP_DigestUpdate(ctx, buf.data(), *n * rl);
      records += *n;
    }
    reader->reset();
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    const double cpu = cpu_seconds() - cpu0;
    if (ctx) {
      unsigned char md[EVP_MAX_MD_SIZE];
      unsigned len = 0;
      EVP_DigestFinal_ex(ctx, md, &len);
      EVP_MD_CTX_free(ctx);
      for (unsigned i = 0; i < len; ++i) {
        char h[3];
        std::snprintf(h, sizeof h, "%02x", md[i]);
        sha += h;
      }
    }
    char w[64], c[64];
    std::snprintf(w, sizeof w, "%s%.4f", run ? "," : "", wall * 1e3);
    std::snprintf(c, sizeof c, "%s%.4f", run ? "," : "", cpu * 1e3);
    walls += w;
    cpus += c;
  }
  std::printf(
      "{\"decoder\":\"tinstream\",\"file\":\"%s\",\"threads\":%u,\"layers\":\"%s\","
      "\"records\":%llu,\"sha256\":\"%s\",\"decodeMs\":[%s],\"cpuMs\":[%s]}\n",
      file.c_str(), used_threads, geometry ? "geometry" : "all",
      static_cast<unsigned long long>(records), sha.c_str(), walls.c_str(), cpus.c_str());
  return 0;
}
