// libFuzzer target for the whole request path: raw bytes as they arrive on a connection, through
// the session's HTTP/1 parser (request_parser.hpp, with the server's default header and body
// limits) and, for each request it completes (pipelined ones too), handle() on a real SQLite
// store holding the server tests' layer "lux" (admin API off: no token). Invariants checked: no
// crash, no sanitizer report; every answer has a status from 200 to 599 and is never a 500 (the
// store is sound), no header name or value holds CR, LF or NUL (header injection), a 304 has no
// body, and an answer's Content-Length (when it states one, HEAD aside) is its body's.
//   scripts/fuzz.sh (build-fuzz/bin/request_fuzzer server/fuzz/corpus/request)
#include <boost/asio/buffer.hpp>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string_view>

#include "request_parser.hpp"
#include "test_support.hpp"
#include "tinstream/server/handler.hpp"

using namespace tinstream;
using namespace tinstream::server;

namespace {

void require(bool ok) {
  if (!ok) std::abort();
}

struct World {
  World() {
    testing::write_test_layer(dir.path / "store.db", "lux");
    auto opened = store::TileStore::open(dir.path / "store.db", store::TileStore::Mode::read_only);
    require(opened.ok());
    store = std::make_unique<store::TileStore>(std::move(*opened));
    ctx.config.store = dir.path / "store.db";
    ctx.store = [this]() -> Result<store::TileStore*> { return store.get(); };
    ctx.metrics = &metrics;
    ctx.jobs = &jobs;
    ctx.terrain_cache = &cache;
    ctx.layer_cache = &layers;
    ctx.path_redactions = server_path_redactions(ctx.config);
  }
  testing::TempDir dir{"request-fuzzer"};
  std::unique_ptr<store::TileStore> store;
  Metrics metrics;
  TerrainCache cache{4u << 20};
  LayerCache layers{/*ttl_ms=*/1000};
  JobManager jobs{[](const IngestJobSpec&, const ProgressSink&) { return Status{}; }, 4};
  Context ctx;
};

bool clean(std::string_view s) { return s.find_first_of(std::string_view("\r\n\0", 3)) == s.npos; }

void check(const Request& req, const Response& res) {
  require(res.status >= 200 && res.status < 600 && res.status != 500);
  for (const auto& [name, value] : res.headers) require(clean(name) && clean(value));
  if (res.prebuilt) {
    for (const auto& [name, value] : res.prebuilt->fields) require(clean(name) && clean(value));
  }
  if (res.status == 304) require(res.payload().empty());
  if (const std::string* length = res.header("Content-Length"); length && req.method != "HEAD") {
    require(*length == std::to_string(res.payload().size()));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static World world;
  const ServerConfig defaults;
  std::string_view rest(reinterpret_cast<const char*>(data), size);
  for (int n = 0; n < 8 && !rest.empty(); ++n) {  // up to 8 pipelined requests
    Request req;
    RequestParser parser(req);
    parser.eager(true);
    parser.header_limit(defaults.max_header_bytes);
    parser.body_limit(defaults.max_body_bytes);
    beast::error_code ec;
    while (!rest.empty() && !parser.is_done()) {
      const std::size_t used = parser.put(boost::asio::buffer(rest.data(), rest.size()), ec);
      if (ec) break;
      if (used == 0) break;  // needs more bytes than there are
      rest.remove_prefix(used);
    }
    if (ec || !parser.is_done()) break;
    req.remote = "127.0.0.1";
    Response res = handle(req, world.ctx);
    if (res.deferred) res = res.deferred();
    check(req, res);
  }
  return 0;
}
