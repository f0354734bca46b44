// Stand-alone driver for the kernel's build and removal (no CGAL, no Google Benchmark): the same
// points and victims as kernel_bench's remove_half cases, for instruction counts under callgrind,
// for A/B timing of two builds, and for checking that a change keeps the triangulations.
//
//   removal_driver KIND N [MODE] [REPS]
//     KIND 0 uniform, 1 LiDAR-like, 2 autzen (N ignored), 3 lattice (all ties); MODE:
//     remove   (default) build, remove the victims in input order; prints the removal CPU time,
//              a hash of the final triangulation and one of the whole mesh state (slots, links)
//     preview  the same, calling removal_preview(v) before each removal: also hashes every
//              preview, i.e. the exact triangles each removal creates (and tie resolution)
//     build    insert_bulk only; prints its CPU time and the triangulation's hash
//   Under valgrind --tool=callgrind --instr-atstart=no only the timed part is counted.
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#else  // without valgrind's headers the driver still builds; callgrind then counts everything
#define CALLGRIND_START_INSTRUMENTATION
#define CALLGRIND_STOP_INSTRUMENTATION
#endif

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

#include "datasets.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace {

using tinstream::kernel::Triangulation;
using tinstream::kernel::VertexId;
using tinstream::kernel::VertexTriple;

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

// Anonymous memory backed by transparent huge pages, from /proc/self/smaps_rollup (Linux), in MiB.
long huge_mib() {
  std::FILE* f = std::fopen("/proc/self/smaps_rollup", "r");
  if (!f) return -1;
  char line[256];
  long kb = -1;
  while (std::fgets(line, sizeof line, f)) {
    if (std::sscanf(line, "AnonHugePages: %ld kB", &kb) == 1) break;
  }
  std::fclose(f);
  return kb < 0 ? -1 : kb / 1024;
}

std::uint64_t mix(std::uint64_t h, std::uint64_t x) {
  h ^= x + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
  h *= 0xBF58476D1CE4E5B9ull;
  return h ^ (h >> 31);
}

// Order-independent description of a set of triangles: each rotated to start at its smallest
// vertex (orientation kept), the list sorted, then hashed.
std::uint64_t hash_triangles(std::vector<VertexTriple> tris) {
  for (auto& t : tris) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  std::sort(tris.begin(), tris.end());
  std::uint64_t h = tris.size();
  for (const auto& t : tris) h = mix(mix(mix(h, t[0]), t[1]), t[2]);
  return h;
}

// The whole mesh as stored: every triangle slot (vertices and neighbours, in slot order) and every
// vertex's triangle. Equal hashes mean the same state, not only the same triangles: the same
// output order of finite_triangles() and the same starting points for later edits.
std::uint64_t hash_state(const Triangulation& t) {
  const auto& m = t.mesh();
  std::uint64_t h = m.triangle_slots();
  for (tinstream::kernel::TriangleId i = 0; i < m.triangle_slots(); ++i) {
    const auto& T = m.tri(i);
    for (int j = 0; j < 3; ++j) h = mix(mix(h, T.v[j]), T.n[j]);
  }
  for (VertexId v = 0; v < m.vertex_slots(); ++v) h = mix(h, m.vertex_triangle(v));
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: removal_driver KIND N [remove|preview|build] [REPS]\n");
    return 2;
  }
  const int kind = std::atoi(argv[1]);
  const auto n = static_cast<std::size_t>(std::atof(argv[2]));
  const std::string mode = argc > 3 ? argv[3] : "remove";
  const int reps = argc > 4 ? std::atoi(argv[4]) : 1;
  const auto& pts = tinstream::bench::dataset(kind, n);
  const auto victims = tinstream::bench::removal_victims(pts.size());
  for (int rep = 0; rep < reps; ++rep) {
    Triangulation t;
    double t0 = cpu_ms();
    if (mode == "build") CALLGRIND_START_INSTRUMENTATION;
    const auto ids = t.insert_bulk(pts);
    if (mode == "build") {
      CALLGRIND_STOP_INSTRUMENTATION;
      const double ms = cpu_ms() - t0;
      std::printf("build kind %d n %zu: %.1f ms cpu, hash %016llx\n", kind, pts.size(), ms,
                  static_cast<unsigned long long>(hash_triangles(t.finite_triangles())));
      continue;
    }
    std::vector<VertexId> handles;
    std::vector<std::uint8_t> taken(t.vertex_id_bound(), 0);
    for (std::size_t i : victims) {
      const VertexId v = ids[i].vertex;
      if (!taken[v]) handles.push_back(v);
      taken[v] = 1;
    }
    std::uint64_t preview_hash = 0;
    const bool preview = mode == "preview";
    t0 = cpu_ms();
    CALLGRIND_START_INSTRUMENTATION;
    for (VertexId v : handles) {
      if (preview) {
        auto p = t.removal_preview(v);
        if (!p.ok()) return 1;
        preview_hash = mix(preview_hash, hash_triangles(std::move(p).value()));
      }
      if (!t.remove_vertex(v).ok()) {
        std::fprintf(stderr, "removal of %u failed\n", v);
        return 1;
      }
    }
    CALLGRIND_STOP_INSTRUMENTATION;
    const double ms = cpu_ms() - t0;
    std::printf(
        "remove kind %d n %zu: %zu removals, %.1f ms cpu (%.0f ns each), %ld MiB THP, "
        "hash %016llx",
        kind, pts.size(), handles.size(), ms, ms * 1e6 / double(handles.size()), huge_mib(),
        static_cast<unsigned long long>(hash_triangles(t.finite_triangles())));
    std::printf(", state %016llx", static_cast<unsigned long long>(hash_state(t)));
    if (preview) std::printf(", previews %016llx", static_cast<unsigned long long>(preview_hash));
    std::printf("\n");
  }
  return 0;
}
