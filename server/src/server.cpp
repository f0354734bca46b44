// The listener side of the server: N shards (one io_context and one thread each), the acceptor
// that hands connections to them, the shards' deadline sweeps, and graceful shutdown. A
// connection's own life is session.cpp; the request logic is handler.cpp and its families.
//
//   acceptor (shard 0) ──round robin──▶ shard k: io_context k, run by thread k
//                                        └─ its sessions, its timeout sweep, its TileStore
//
// A session lives on one shard from accept to close: no strands, no lock and no thread hand-off
// per request (the acceptor hands each connection over once). Timeouts are deadlines that the
// shard's sweep timer checks every `every` interval (no timer operation per read or write).
//
// Shutdown (stop(), or SIGINT/SIGTERM): the acceptor closes; every shard tells its sessions
// (Session::shutdown: idle ones close, busy ones answer with `Connection: close`) and drops its
// work guard, so its run() returns once its last session is gone; shard 0 watches the count of
// live sessions and stops every shard when shutdown_grace_ms has passed.
#include "tinstream/server/server.hpp"

#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <csignal>
#include <map>
#include <thread>

#include "server_state.hpp"
#include "session.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tls.hpp"

namespace tinstream::server {

namespace beast = boost::beast;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {

// Layer rows of the terrain hot path are cached for this long: a layer changed by another
// process (the CLI publishing into the served store) is seen within it. Admin ingests and
// deletes clear the cache at once.
constexpr std::uint32_t kLayerRowTtlMs = 1000;

// How long the listener waits before accepting again when accept() found no descriptor (or
// memory) left.
constexpr auto kAcceptBackoff = std::chrono::milliseconds(100);

// Raises the open-files soft limit to the hard one, and returns max_connections as the server
// can keep it: `per_connection` descriptors each (a TLS connection holds three: the TCP socket and
// the socket pair to its session, tls.hpp), below that limit by an eighth of it (at least 128
// descriptors), for the stores, the body files, the listeners, the logs and the ingest's files.
std::uint32_t connection_limit(std::uint32_t configured, unsigned per_connection) {
  rlimit files{};
  if (::getrlimit(RLIMIT_NOFILE, &files) != 0) return configured;
  const rlim_t most = std::min<rlim_t>(files.rlim_max, rlim_t{1} << 20);
  if (files.rlim_cur < most) {
    rlimit raised = files;
    raised.rlim_cur = most;
    if (::setrlimit(RLIMIT_NOFILE, &raised) == 0) files = raised;
  }
  const rlim_t reserve = std::max<rlim_t>(128, files.rlim_cur / 8);
  const rlim_t room = std::max<rlim_t>(
      files.rlim_cur > reserve + 1 ? (files.rlim_cur - reserve) / per_connection : 1, 1);
  if (configured <= room) return configured;
  spdlog::warn("max_connections {} lowered to {}: the open-files limit is {}{}", configured, room,
               static_cast<std::uint64_t>(files.rlim_cur),
               per_connection > 1 ? " and a TLS connection holds 3 descriptors" : "");
  return static_cast<std::uint32_t>(room);
}

// Upload files of an earlier run (a crash mid-upload or mid-job): the server's own names,
// upload-<16 hex> with or without "-<name>".
void remove_orphan_uploads(const std::filesystem::path& folder) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    const bool ours = name.size() >= 23 && name.rfind("upload-", 0) == 0 &&
                      name.find_first_not_of("0123456789abcdef", 7) >= 23 &&
                      (name.size() == 23 || name[23] == '-');
    std::error_code type_ec;
    if (!ours || !e.is_regular_file(type_ec)) continue;
    std::error_code rm;
    std::filesystem::remove(e.path(), rm);
    if (!rm) spdlog::info("removed an upload left by an earlier run: {}", name);
  }
}

// The folder for ingest jobs' temporary files: .tinstream-scratch beside the store, 0700 (the
// system temp folder is shared with every user of the machine).
std::filesystem::path private_scratch_dir(const std::filesystem::path& store) {
  const auto dir = (store.has_parent_path() ? store.parent_path() : std::filesystem::path(".")) /
                   ".tinstream-scratch";
  ::mkdir(dir.c_str(), 0700);
  ::chmod(dir.c_str(), 0700);
  std::error_code ec;
  return std::filesystem::is_directory(dir, ec) ? dir : std::filesystem::path();
}

// Each io thread's own read-only store, opened on first use, keyed by the server's serial number
// (unique per process, unlike its address) and released when the thread leaves run().
std::map<std::uint64_t, std::unique_ptr<store::TileStore>>& thread_stores() {
  thread_local std::map<std::uint64_t, std::unique_ptr<store::TileStore>> stores;
  return stores;
}

Result<store::TileStore*> thread_store(std::uint64_t serial, const std::filesystem::path& path) {
  auto& slot = thread_stores()[serial];
  if (!slot) {
    auto opened = store::TileStore::open(path, store::TileStore::Mode::read_only);
    if (!opened) return opened.error();
    slot = std::make_unique<store::TileStore>(std::move(*opened));
  }
  return slot.get();
}

// Opens, binds and listens; errors name the address and port.
Status listen(tcp::acceptor& acceptor, const std::string& address_text, std::uint16_t port) {
  beast::error_code ec;
  const auto address = net::ip::make_address(address_text, ec);
  if (ec) return invalid_argument("address \"" + address_text + "\": " + ec.message());
  const tcp::endpoint endpoint{address, port};
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) {
    return io_error("cannot listen on " + address_text + ":" + std::to_string(port) + ": " +
                    ec.message());
  }
  return {};
}

}  // namespace

bool AddressCounts::acquire(const std::string& address, std::uint32_t limit) {
  std::lock_guard lock(mutex_);
  std::uint32_t& n = counts_[address];
  if (n >= limit) {
    if (n == 0) counts_.erase(address);
    return false;
  }
  ++n;
  return true;
}

void AddressCounts::release(const std::string& address) {
  std::lock_guard lock(mutex_);
  auto it = counts_.find(address);
  if (it != counts_.end() && --it->second == 0) counts_.erase(it);
}

struct Server::Impl {
  ~Impl();
  Impl(const ServerConfig& c, unsigned n_shards)
      : serial(next_serial.fetch_add(1)),
        state(c),
        shards(make_shards(c, n_shards)),
        acceptor(shards.front()->ioc),
        admin_acceptor(shards.front()->ioc),
        signals(shards.front()->ioc, SIGINT, SIGTERM),
        grace(shards.front()->ioc) {}

  static std::vector<std::unique_ptr<Shard>> make_shards(const ServerConfig& c, unsigned n) {
    // Timeouts fire up to one sweep interval late: an eighth of the shortest one, 5-250 ms.
    const auto every = std::chrono::milliseconds(
        std::clamp<std::uint32_t>(std::min(c.read_timeout_ms, c.write_timeout_ms) / 8, 5, 250));
    std::vector<std::unique_ptr<Shard>> out;
    // Room for the whole terrain cache plus the bodies still in flight after their eviction.
    const std::uint64_t body_file = 2 * c.terrain_cache_bytes + (64u << 20);
    for (unsigned i = 0; i < std::max(1u, n); ++i)
      out.push_back(std::make_unique<Shard>(every, body_file));
    return out;
  }

  static inline std::atomic<std::uint64_t> next_serial{1};
  std::uint64_t serial;
  ServerState state;
  std::unique_ptr<JobManager> jobs;
  std::unique_ptr<TerrainCache> cache;
  LayerCache layers{kLayerRowTtlMs};
  Clock::time_point stop_deadline;
  std::vector<std::unique_ptr<Shard>> shards;  // at least one; shard 0 also runs what follows
  tcp::acceptor acceptor;
  tcp::acceptor admin_acceptor;            // open when config.admin_address is set
  std::shared_ptr<net::ssl::context> tls;  // set when config.tls_cert is: every listener is HTTPS
  net::signal_set signals;
  net::steady_timer grace;
  std::size_t next_shard = 0;  // round robin; the accept handlers only (shard 0's thread)
  // Deferred answers (layer deletes). Declared after the shards: stopped first (~Impl).
  BlockingWorker blocking;

  Clock::time_point last_accept_warning;  // accept failures are logged once a second at most

  void do_accept(tcp::acceptor& from);
  void on_accept(tcp::acceptor& from, Shard& target, beast::error_code ec, tcp::socket socket);
  void admit(tcp::acceptor& from, Shard& target, tcp::socket socket);
  void sweep(Shard& shard);
  void stop();
  void watch_drain();
};

Server::Impl::~Impl() {
  // Handlers still pending after a forced stop (grace period over) own sessions that refer to
  // this object. No thread runs the shards any more: close the sessions' sockets from here and
  // let those handlers finish before any member goes away.
  beast::error_code ec;
  acceptor.close(ec);
  admin_acceptor.close(ec);
  signals.cancel(ec);
  grace.cancel();
  blocking.stop();  // a deferred answer still running finishes first
  for (auto& shard : shards) {
    shard->work.reset();
    shard->sweep.cancel();
    for (Session* s : shard->sessions) s->close_now();
    shard->ioc.restart();
    shard->ioc.run_for(std::chrono::seconds(5));
  }
}

void Server::Impl::do_accept(tcp::acceptor& from) {
  Shard& target = *shards[next_shard];
  next_shard = (next_shard + 1) % shards.size();
  from.async_accept(target.ioc, [this, &from, &target](beast::error_code ec, tcp::socket socket) {
    on_accept(from, target, ec, std::move(socket));
  });
}

// True for accept errors that say "no resources now" (descriptors, kernel memory): retrying at
// once would fail again, at 100 % CPU.
bool out_of_resources(const beast::error_code& ec) {
  return ec == net::error::no_descriptors || ec == beast::errc::too_many_files_open_in_system ||
         ec == net::error::no_buffer_space || ec == net::error::no_memory;
}

void Server::Impl::on_accept(tcp::acceptor& from, Shard& target, beast::error_code ec,
                             tcp::socket socket) {
  if (ec) {
    if (!from.is_open() || state.stopping) return;
    state.metrics.accept_failed();
    const auto now = Clock::now();
    if (now - last_accept_warning >= std::chrono::seconds(1)) {
      last_accept_warning = now;
      spdlog::warn("accept failed: {}", ec.message());
    }
    if (out_of_resources(ec)) {
      // The connection stays in the backlog; try again once something may have been freed.
      auto retry = std::make_shared<net::steady_timer>(from.get_executor(), kAcceptBackoff);
      retry->async_wait([this, &from, retry](beast::error_code wait_ec) {
        if (!wait_ec && !state.stopping) do_accept(from);
      });
      return;
    }
  } else if (!state.stopping) {
    admit(from, target, std::move(socket));
  }
  if (!state.stopping) do_accept(from);
}

// Over max_connections (or its address's share) a connection gets a 503 and is closed; when
// refusals pile up (another quarter of max_connections, at least 16) it is closed at once,
// without an answer.
void Server::Impl::admit(tcp::acceptor& from, Shard& target, tcp::socket socket) {
  beast::error_code ec;
  socket.set_option(tcp::no_delay(true), ec);  // responses go out in one write; no Nagle wait
  const ServerConfig& c = state.config;
  const std::int64_t open = state.metrics.open_connections();
  if (open >= static_cast<std::int64_t>(c.max_connections) +
                  std::max<std::int64_t>(c.max_connections / 4, 16)) {
    state.metrics.connection_rejected();
    socket.close(ec);
    return;
  }
  std::string refusal;
  bool counted = false;
  if (open >= static_cast<std::int64_t>(c.max_connections)) {
    refusal = "too many connections";
  } else if (c.max_connections_per_ip > 0) {
    const auto peer = socket.remote_endpoint(ec);
    counted = !ec && state.addresses.acquire(peer.address().to_string(), c.max_connections_per_ip);
    if (!counted) refusal = "too many connections from this address (max_connections_per_ip)";
  }
  std::string peer;
  if (tls) {
    // The session serves the plain end of a socket pair; TLS is terminated beside it (tls.hpp).
    const auto endpoint = socket.remote_endpoint(ec);
    if (!ec) peer = endpoint.address().to_string();
    auto plain = start_tls_pump(std::move(socket), tls, target.ioc,
                                std::chrono::milliseconds(c.read_timeout_ms));
    if (!plain) {
      state.metrics.connection_rejected();
      if (counted) state.addresses.release(peer);
      spdlog::warn("connection refused: {}", plain.error().message);
      return;
    }
    socket = std::move(*plain);
  }
  if (!refusal.empty()) state.metrics.connection_rejected();
  auto session = std::make_shared<Session>(std::move(socket), state, target,
                                           &from == &admin_acceptor, counted, std::move(peer));
  net::post(target.ioc, [session = std::move(session), refusal = std::move(refusal)] {
    session->start(refusal);
  });
}

void Server::Impl::sweep(Shard& shard) {
  const auto now = Clock::now();
  for (Session* s : shard.sessions) s->check_deadline(now);  // closing erases nothing here
  shard.bodies.collect();
  if (state.stopping && shard.sessions.empty()) return;  // lets run() return
  shard.sweep.expires_after(shard.every);
  shard.sweep.async_wait([this, &shard](beast::error_code ec) {
    if (!ec) sweep(shard);
  });
}

void Server::Impl::stop() {
  if (state.stopping.exchange(true)) return;
  spdlog::info("shutting down: finishing in-flight requests (grace {} ms)",
               state.config.shutdown_grace_ms);
  stop_deadline = Clock::now() + std::chrono::milliseconds(state.config.shutdown_grace_ms);
  net::post(acceptor.get_executor(), [this] {
    beast::error_code ec;
    acceptor.close(ec);
    admin_acceptor.close(ec);
    signals.cancel(ec);
  });
  for (auto& shard : shards) {
    net::post(shard->ioc, [s = shard.get()] {
      for (Session* session : s->sessions) session->shutdown();
    });
    shard->work.reset();
  }
  net::post(shards.front()->ioc, [this] { watch_drain(); });
}

void Server::Impl::watch_drain() {
  if (state.live_sessions.load() == 0) return;  // nothing left: run() returns once idle
  if (Clock::now() >= stop_deadline) {
    spdlog::warn("shutdown grace period over; closing remaining connections");
    for (auto& shard : shards) shard->ioc.stop();
    return;
  }
  grace.expires_after(std::chrono::milliseconds(20));
  grace.async_wait([this](beast::error_code) { watch_drain(); });
}

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() {
  stop();
  if (impl_->jobs) impl_->jobs->shutdown();
}

Result<std::unique_ptr<Server>> Server::create(const ServerConfig& config, IngestRunner runner) {
  // Create the store file and schema when absent, so the server can start empty and be filled
  // through the admin API.
  {
    auto rw = store::TileStore::open(config.store, store::TileStore::Mode::read_write);
    if (!rw)
      return Error(rw.error().code, "store " + config.store.string() + ": " + rw.error().message);
  }
  const unsigned threads =
      config.threads > 0 ? config.threads : std::max(1u, std::thread::hardware_concurrency());
  ServerConfig applied = config;
  applied.max_connections =
      connection_limit(config.max_connections, config.tls_cert.empty() ? 1u : 3u);
  auto impl = std::make_unique<Impl>(applied, threads);
  Impl* raw = impl.get();
  // A finished job may have published or replaced a layer: forget cached layer rows.
  IngestRunner wrapped = [runner = std::move(runner), raw](const IngestJobSpec& job,
                                                           const ProgressSink& progress) {
    Status s =
        runner ? runner(job, progress) : Status(Error(ErrorCode::unsupported, "no ingest runner"));
    raw->layers.clear();
    return s;
  };
  impl->jobs = std::make_unique<JobManager>(std::move(wrapped), config.max_queued_jobs);
  if (config.terrain_cache_bytes > 0)
    impl->cache = std::make_unique<TerrainCache>(config.terrain_cache_bytes);
  Context& ctx = impl->state.ctx;
  ctx.config = applied;
  ctx.admin_token = resolve_admin_token(config);
  ctx.metrics = &impl->state.metrics;
  ctx.jobs = impl->jobs.get();
  ctx.terrain_cache = impl->cache.get();
  ctx.layer_cache = &impl->layers;
  ctx.store = [raw] { return thread_store(raw->serial, raw->state.config.store); };
  ctx.path_redactions = server_path_redactions(config);
  ctx.scratch_dir = private_scratch_dir(config.store);
  if (!config.upload_dir.empty()) remove_orphan_uploads(config.upload_dir);
  impl->state.blocking = &impl->blocking;

  if (!config.tls_cert.empty()) {
    auto tls = make_tls_context(config);
    if (!tls) return tls.error();
    impl->tls = std::move(*tls);
  }
  if (Status listening = listen(impl->acceptor, config.address, config.port); !listening)
    return listening.error();
  if (!config.admin_address.empty()) {
    if (Status listening = listen(impl->admin_acceptor, config.admin_address, config.admin_port);
        !listening)
      return listening.error();
  }
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

std::uint16_t Server::port() const {
  beast::error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

std::uint32_t Server::max_connections() const { return impl_->state.config.max_connections; }

std::uint16_t Server::admin_port() const {
  if (!impl_->admin_acceptor.is_open()) return 0;
  beast::error_code ec;
  return impl_->admin_acceptor.local_endpoint(ec).port();
}

void Server::run(bool handle_signals) {
  Impl& s = *impl_;
  // sendfile(2) has no MSG_NOSIGNAL: a peer gone mid-response must be an EPIPE, not a signal
  // that ends the process.
  std::signal(SIGPIPE, SIG_IGN);
  if (handle_signals) {
    s.signals.async_wait([&s](beast::error_code ec, int signo) {
      if (ec) return;
      spdlog::info("signal {} received", signo);
      s.stop();
    });
  }
  if (!s.state.stopping) {
    s.do_accept(s.acceptor);
    if (s.admin_acceptor.is_open()) s.do_accept(s.admin_acceptor);
    for (auto& shard : s.shards) {
      net::post(shard->ioc, [&s, sh = shard.get()] { s.sweep(*sh); });
    }
  }
  spdlog::info("tinstream-server listening on {}:{} ({}) with {} threads, store {}",
               s.state.config.address, port(), s.tls ? "HTTPS" : "HTTP", s.shards.size(),
               s.state.config.store.string());
  std::vector<std::thread> threads;
  auto serve_shard = [&s](Shard& shard) {
    shard.ioc.run();
    thread_stores().erase(s.serial);
  };
  for (std::size_t i = 1; i < s.shards.size(); ++i)
    threads.emplace_back(serve_shard, std::ref(*s.shards[i]));
  serve_shard(*s.shards.front());
  for (auto& t : threads) t.join();
  s.blocking.stop();
  s.jobs->shutdown();
  spdlog::info("tinstream-server stopped");
}

void Server::stop() { impl_->stop(); }

}  // namespace tinstream::server
