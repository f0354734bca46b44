// tinstream/base/fault.hpp — named fault-injection points, for tests of failure paths.
//
// Code marks the places where production can fail in ways a test cannot otherwise provoke on
// demand — a worker's unit of work, the start of a thread — with fault::point("pass3.tile").
// A test arms a point and its (skip + 1)-th pass fails as asked:
//   throw_error   throws std::runtime_error("injected fault at <point>")
//   out_of_memory throws std::bad_alloc
//   no_thread     throws std::system_error(EAGAIN), what std::thread's constructor throws when the
//                 system cannot create another thread (use it on the "<group>.spawn" points)
//   stop          raises SIGSTOP: the process stops at exactly that point, so that a parent that
//                 waits for it (waitpid with WUNTRACED) can inspect the files and SIGKILL it there
// In-process with fault::Arm (RAII, disarmed at scope exit), or in a child process through the
// environment variable TINSTREAM_FAULT, read at the first point the process passes:
//   TINSTREAM_FAULT=<point>[@<skip>][:<kind>][,<point>…]     kind: throw (default), oom, no_thread,
//   stop
// e.g. TINSTREAM_FAULT=lod.tile@3:stop stops the process at the fourth LOD job.
//
// Thread-safe. When nothing is armed a point costs one relaxed atomic load; the points sit at
// the granularity of batches, tiles and thread starts, never per point. Without
// TINSTREAM_FAULT_INJECTION (defined in builds with tests; the Docker image has none) point()
// is empty and arming does nothing.
//
// The points (docs/SECURITY.md lists which test arms each):
//   pass1.read, pass1.transform                 ingest pass 1: a read, a batch on a worker
//   pass2.spill, pass2.writer, pass2.merge      pass 2: a sorted spill, a background run write,
//                                               the second merge thread
//   pass3.cells, pass3.tile, store.queue        pass 3: the cell index readers, a tile, a store put
//   lod.tile                                    pass 4: one parent tile job
//   <any of the thread groups above>.spawn      starting one thread of that group
#pragma once

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace tinstream::fault {

enum class Kind { throw_error, out_of_memory, no_thread, stop };

namespace detail {

struct Armed {
  std::string point;
  std::uint64_t skip = 0;  // passes left before the one that fails
  Kind kind = Kind::throw_error;
  std::uint64_t fired = 0;  // 0 or 1: an armed point fails once
  std::uint64_t id = 0;
};

struct Registry {
  std::mutex mutex;  // guards armed and next_id
  std::vector<Armed> armed;
  std::uint64_t next_id = 1;
  std::atomic<int> count{0};  // armed.size(), read without the lock on the fast path
};

inline Registry& registry() {
  static Registry r;
  return r;
}

inline std::uint64_t arm(std::string point, std::uint64_t skip, Kind kind) {
  Registry& r = registry();
  std::lock_guard lock(r.mutex);
  const std::uint64_t id = r.next_id++;
  r.armed.push_back({std::move(point), skip, kind, 0, id});
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

[[gnu::cold]] inline void fire(std::string_view point) {
  Kind kind = Kind::throw_error;
  {
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    Armed* hit = nullptr;
    for (Armed& a : r.armed) {
      if (a.point == point && a.fired == 0) {
        hit = &a;
        break;
      }
    }
    if (hit == nullptr) return;
    if (hit->skip > 0) {
      --hit->skip;
      return;
    }
    hit->fired = 1;
    kind = hit->kind;
  }
  switch (kind) {
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
  }
}

}  // namespace detail

// A fault point (see the header comment). May throw what the armed kind says.
inline void point([[maybe_unused]] std::string_view name) {
#ifdef TINSTREAM_FAULT_INJECTION
  static const bool from_environment = (detail::arm_from_environment(), true);
  (void)from_environment;
  if (detail::registry().count.load(std::memory_order_relaxed) == 0) return;
  detail::fire(name);
#endif
}

// Arms `point` while in scope: its (skip + 1)-th pass fails as `kind` says, once.
class Arm {
 public:
  explicit Arm(std::string point, std::uint64_t skip = 0, Kind kind = Kind::throw_error)
      : id_(detail::arm(std::move(point), skip, kind)) {}
  ~Arm() {
    detail::Registry& r = detail::registry();
    std::lock_guard lock(r.mutex);
    std::erase_if(r.armed, [&](const detail::Armed& a) { return a.id == id_; });
    r.count.store(static_cast<int>(r.armed.size()));
  }
  Arm(const Arm&) = delete;
  Arm& operator=(const Arm&) = delete;
  // Whether the fault was injected (the point was passed skip + 1 times).
  bool fired() const {
    detail::Registry& r = detail::registry();
    std::lock_guard lock(r.mutex);
    for (const detail::Armed& a : r.armed) {
      if (a.id == id_) return a.fired != 0;
    }
    return false;
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
