// libFuzzer target for the admin API's JSON: the input is the body of POST /admin/ingest with
// the right token (a data root with one source, a job runner that succeeds at once), then the
// same bytes as ingest options and as a server configuration file. Invariants checked: no crash,
// no sanitizer report; the ingest answer is a 202 with a job id, or a 4xx/503 JSON error with a
// message, never a 500; an answer never names the data root; options that validate_ingest_options
// accepts have threads (0-64) and memory_mb (16-16384) within their documented ranges; a
// configuration that parses has positive timeouts and both or neither of tls_cert and tls_key.
//   scripts/fuzz.sh (build-fuzz/bin/admin_fuzzer server/fuzz/corpus/admin)
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tinstream/server/config.hpp"
#include "tinstream/server/handler.hpp"
#include "tinstream/server/ingest_options.hpp"

using namespace tinstream;
using namespace tinstream::server;
using nlohmann::json;

namespace {

void require(bool ok) {
  if (!ok) std::abort();
}

struct World {
  World() {
    root = std::filesystem::temp_directory_path() /
           ("tinstream-admin-fuzzer-" + std::to_string(::getpid()));
    std::filesystem::create_directories(root / "data" / "sub");
    std::ofstream(root / "data" / "sub" / "points.xyz") << "6.1 49.6 300\n";
    ctx.config.store = root / "store.db";
    ctx.config.data_root = root / "data";
    ctx.admin_token = "tok";
    ctx.store = []() -> Result<store::TileStore*> { return io_error("no store in this target"); };
    ctx.metrics = &metrics;
    ctx.jobs = &jobs;
    ctx.path_redactions = server_path_redactions(ctx.config);
  }
  ~World() {
    jobs.shutdown();
    std::error_code ec;
    std::filesystem::remove_all(root, ec);
  }
  std::filesystem::path root;
  Metrics metrics;
  JobManager jobs{[](const IngestJobSpec&, const ProgressSink&) { return Status{}; }, 1000000};
  Context ctx;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static World world;
  const std::string text(reinterpret_cast<const char*>(data), size);

  Request req;
  req.method = "POST";
  req.target = "/admin/ingest";
  req.authorization = "Bearer tok";
  req.content_type = "application/json";
  req.body = text;
  req.remote = "127.0.0.1";
  Response res = handle(req, world.ctx);
  if (res.deferred) res = res.deferred();
  require(res.status == 202 || (res.status >= 400 && res.status < 500) || res.status == 503);
  const std::string_view body = res.payload();
  require(!body.empty());
  require(body.find(world.root.string()) == std::string_view::npos);
  if (res.status == 202) require(json::parse(body, nullptr, false).contains("job"));

  const json options = json::parse(text, nullptr, false, true);
  if (options.is_object() && validate_ingest_options(options).ok()) {
    // Integers ("-0" included), in range.
    const auto in = [&](const char* key, std::int64_t lo, std::int64_t hi) {
      if (!options.contains(key)) return true;
      const json& v = options[key];
      if (!v.is_number_integer()) return false;
      if (v.is_number_unsigned()) {
        const std::uint64_t n = v.get<std::uint64_t>();
        return n >= static_cast<std::uint64_t>(lo) && n <= static_cast<std::uint64_t>(hi);
      }
      return v.get<std::int64_t>() >= lo && v.get<std::int64_t>() <= hi;
    };
    require(in("threads", 0, kMaxIngestThreads) && in("memory_mb", 16, 16384));
  }

  auto config = config_from_json(text);
  if (config.ok()) {
    require(config->read_timeout_ms > 0 && config->write_timeout_ms > 0);
    require(config->tls_cert.empty() == config->tls_key.empty());
  }
  return 0;
}
