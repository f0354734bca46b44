// tinstream/base/fault.hpp — named fault-injection points, for tests of failure paths.
//
// Code marks the places where production can fail in ways a test cannot otherwise provoke on
// demand — a worker's unit of work, the start of a thread — with fault::point("pass3.tile").
// A test arms a point; its (skip + 1)-th pass, and the times - 1 passes after it, fail as asked:
//   throw_error   throws std::runtime_error("injected fault at <point>")
//   out_of_memory throws std::bad_alloc
//   no_thread     throws std::system_error(EAGAIN), what std::thread's constructor throws when the
//                 system cannot create another thread (use it on the "<group>.spawn" points)
//   stop          raises SIGSTOP: the process stops at exactly that point, so that a parent that
//                 waits for it (waitpid with WUNTRACED) can inspect the files and SIGKILL it there
//   error         nothing at point(); error_at(point) returns a message instead, for code that
//                 reports failures as a Status (a read that fails without throwing)
//   pause         the thread waits at the point until the test releases it (Arm::release, or the
//                 Arm's end), so that a test can look at a state that is otherwise a race
// In-process with fault::Arm (RAII, disarmed at scope exit), or in a child process through the
// environment variable TINSTREAM_FAULT, read at the first point the process passes:
//   TINSTREAM_FAULT=<point>[@<skip>][:<kind>][,<point>…]
//   kind: throw (default), oom, no_thread, stop, error (pause only in-process)
// e.g. TINSTREAM_FAULT=lod.tile@3:stop stops the process at the fourth LOD job.
//
// Thread-safe. When nothing is armed a point costs one relaxed atomic load; the points sit at
// the granularity of batches, tiles, reads and thread starts, never per point. Without
// TINSTREAM_FAULT_INJECTION (defined in builds with tests; the Docker image has none) point()
// is empty and arming does nothing.
//
// The points (docs/SECURITY.md lists which test arms each):
//   pass1.read, pass1.transform              ingest pass 1: a read, a batch on a worker
//   pass2.spill, pass2.writer, pass2.merge   pass 2: a sorted spill, a background run write, the
//                                            second merge thread
//   pass3.cells, pass3.tile                  pass 3: the cell index readers, a tile
//   sorted_run.read                          a read of the sorted run (error kind)
//   store.queue                              the store queue's thread: one tile put
//   store.commit                             a batch of tiles committed (crash tests stop there)
//   lod.tile                                 pass 4: one parent tile job
//   <group>.spawn                            starting one thread of the groups above
#pragma once

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace tinstream::fault {

enum class Kind { throw_error, out_of_memory, no_thread, stop, error, pause };

namespace detail {

struct Armed {
  std::string point;
  std::uint64_t skip = 0;  // passes before the first that fails
  Kind kind = Kind::throw_error;
  std::uint64_t times = 1;  // passes that fail from then on
  std::uint64_t passes = 0;
  std::uint64_t fired = 0;  // passes that failed
  std::uint64_t id = 0;
  bool released = false;  // pause: the paused threads may go on
};

struct Registry {
  std::mutex mutex;                 // guards armed and next_id
  std::condition_variable changed;  // a pause began, or was released
  std::vector<Armed> armed;
  std::uint64_t next_id = 1;
  std::atomic<int> count{0};  // armed.size(), read without the lock on the fast path
};

inline Registry& registry() {
  static Registry r;
  return r;
}

inline std::uint64_t arm(std::string point, std::uint64_t skip, Kind kind,
                         std::uint64_t times = 1) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  const std::uint64_t id = r.next_id++;
  r.armed.push_back({std::move(point), skip, kind, times, 0, 0, id});
  r.count.store(static_cast<int>(r.armed.size()));
  return id;
}

// "<point>[@<skip>][:<kind>]" entries separated by commas; malformed entries are ignored.
inline void arm_from_environment() {
  const char* env = std::getenv("TINSTREAM_FAULT");
  if (env == nullptr) return;
  const std::string_view all(env);
  std::size_t begin = 0;
  while (begin <= all.size()) {
    std::size_t end = all.find(',', begin);
    if (end == std::string_view::npos) end = all.size();
    std::string_view entry = all.substr(begin, end - begin);
    begin = end + 1;
    Kind kind = Kind::throw_error;
    if (const auto colon = entry.find(':'); colon != std::string_view::npos) {
      const std::string_view k = entry.substr(colon + 1);
      entry = entry.substr(0, colon);
      if (k == "oom") {
        kind = Kind::out_of_memory;
      } else if (k == "no_thread") {
        kind = Kind::no_thread;
      } else if (k == "stop") {
        kind = Kind::stop;
      } else if (k == "error") {
        kind = Kind::error;
      } else if (k != "throw") {
        continue;
      }
    }
    std::uint64_t skip = 0;
    if (const auto at = entry.find('@'); at != std::string_view::npos) {
      skip = std::strtoull(std::string(entry.substr(at + 1)).c_str(), nullptr, 10);
      entry = entry.substr(0, at);
    }
    if (!entry.empty()) arm(std::string(entry), skip, kind);
  }
}

// Whether this pass through `point` fails: the armed entry's kind, the pass number, its id.
struct Hit {
  Kind kind;
  std::uint64_t pass;
  std::uint64_t id;
};
[[gnu::cold]] inline std::optional<Hit> due(std::string_view point) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  for (Armed& a : r.armed) {
    if (a.point != point || a.fired == a.times) continue;
    const std::uint64_t pass = ++a.passes;
    if (pass <= a.skip) return std::nullopt;
    ++a.fired;
    if (a.kind == Kind::pause) r.changed.notify_all();
    return Hit{a.kind, pass, a.id};
  }
  return std::nullopt;
}

[[gnu::cold]] inline void fire(std::string_view point) {
  const auto hit = due(point);
  if (!hit) return;
  switch (hit->kind) {
    case Kind::throw_error:
      throw std::runtime_error("injected fault at " + std::string(point));
    case Kind::out_of_memory:
      throw std::bad_alloc();
    case Kind::no_thread:
      throw std::system_error(EAGAIN, std::generic_category(),
                              "injected fault at " + std::string(point));
    case Kind::stop:
      std::raise(SIGSTOP);
      return;
    case Kind::error:
      return;  // error_at() reports these
    case Kind::pause: {
      Registry& r = registry();
      std::unique_lock lock(r.mutex);
      r.changed.wait(lock, [&] {
        for (const Armed& a : r.armed) {
          if (a.id == hit->id) return a.released;
        }
        return true;  // disarmed
      });
      return;
    }
  }
}

inline bool armed_anything() {
  static const bool from_environment = (arm_from_environment(), true);
  (void)from_environment;
  return registry().count.load(std::memory_order_relaxed) != 0;
}

}  // namespace detail

// A fault point (see the header comment). May throw what the armed kind says.
inline void point([[maybe_unused]] std::string_view name) {
#ifdef TINSTREAM_FAULT_INJECTION
  if (detail::armed_anything()) detail::fire(name);
#endif
}

// For points armed with Kind::error: "injected error at <point> (pass n)" when this pass is to
// fail, which the caller returns as its Error; nullopt otherwise.
inline std::optional<std::string> error_at([[maybe_unused]] std::string_view name) {
#ifdef TINSTREAM_FAULT_INJECTION
  if (!detail::armed_anything()) return std::nullopt;
  const auto hit = detail::due(name);
  if (hit && hit->kind == Kind::error) {
    return "injected error at " + std::string(name) + " (pass " + std::to_string(hit->pass) + ")";
  }
#endif
  return std::nullopt;
}

// Arms `point` while in scope: its (skip + 1)-th pass and the times - 1 after it fail as `kind`
// says.
class Arm {
 public:
  explicit Arm(std::string point, std::uint64_t skip = 0, Kind kind = Kind::throw_error,
               std::uint64_t times = 1)
      : id_(detail::arm(std::move(point), skip, kind, times)) {}
  ~Arm() {
    detail::Registry& r = detail::registry();
    std::lock_guard lock(r.mutex);
    std::erase_if(r.armed, [&](const detail::Armed& a) { return a.id == id_; });
    r.count.store(static_cast<int>(r.armed.size()));
    r.changed.notify_all();  // paused threads go on
  }
  Arm(const Arm&) = delete;
  Arm& operator=(const Arm&) = delete;
  // Kind::pause: waits until `passes` threads have reached the point (false after `timeout`).
  bool wait_paused(std::uint64_t passes = 1,
                   std::chrono::milliseconds timeout = std::chrono::minutes(2)) const {
    detail::Registry& r = detail::registry();
    std::unique_lock lock(r.mutex);
    return r.changed.wait_for(lock, timeout, [&] {
      for (const detail::Armed& a : r.armed) {
        if (a.id == id_) return a.fired >= passes;
      }
      return false;
    });
  }
  // Kind::pause: lets the paused threads (and those to come) go on.
  void release() {
    detail::Registry& r = detail::registry();
    std::lock_guard lock(r.mutex);
    for (detail::Armed& a : r.armed) {
      if (a.id == id_) a.released = true;
    }
    r.changed.notify_all();
  }
  // Whether the fault was injected (the point was passed skip + 1 times).
  bool fired() const { return fired_times() != 0; }
  // How many passes failed.
  std::uint64_t fired_times() const {
    detail::Registry& r = detail::registry();
    std::lock_guard lock(r.mutex);
    for (const detail::Armed& a : r.armed) {
      if (a.id == id_) return a.fired;
    }
    return 0;
  }

 private:
  std::uint64_t id_;
};

// Whether fault points are compiled into this build.
constexpr bool enabled() {
#ifdef TINSTREAM_FAULT_INJECTION
  return true;
#else
  return false;
#endif
}

}  // namespace tinstream::fault
