// libFuzzer target for the triangulation kernel: adversarial sequences of insertions, removals and
// constraints, each followed by the validity checker (Triangulation::check_valid).
//   scripts/fuzz.sh --only kernel_fuzzer        (cmake/TinstreamFuzz.cmake builds it)
// The input is a program, one operation per step (first byte: the operation):
//   0 lattice point   (x, y) on a 16 × 16 integer lattice, far from it or 1 ulp off it: every four
//                     neighbours cocircular, rows collinear, near-duplicates 1 ulp apart
//   1 raw point       two doubles from 16 bytes as they are (NaN, inf; finite ones within the
//                     predicates' exact range, magnitudes 1e-20 to 1e20 or zero)
//   2 remove          a live vertex by index; a vertex that cannot go says so
//   3 constraint      between two live vertices by index, crossing whatever is there
//   4 bulk            up to 8 lattice points through insert_bulk
//   5 preview+remove  removal_preview, then remove_vertex: the star must become the preview
// Byte 0 chooses perturbed ties (bit 0), a domain rectangle (bit 1), and (bit 2) lattice points
// 1 ulp off instead of constraints.
// Properties: nothing crashes or hangs; after every 4 operations the cheap check holds, and the
// expensive one (empty circles with exact predicates, hull, constraint chains) after every 16
// operations and at the end; an insertion answers "inserted" or "duplicate" exactly when it
// should; a removal's new triangles are the preview's.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <span>
#include <vector>

#include "tinstream/kernel/triangulation.hpp"

namespace {

using tinstream::kernel::CheckLevel;
using tinstream::kernel::InsertOutcome;
using tinstream::kernel::Point3;
using tinstream::kernel::Rect;
using tinstream::kernel::Triangulation;
using tinstream::kernel::VertexId;
using tinstream::kernel::VertexTriple;

// A broken property: says which, then aborts (libFuzzer saves the input).
[[noreturn]] void broken(const char* what) {
  std::fprintf(stderr, "kernel_fuzzer: %s\n", what);
  std::abort();
}

class Program {
 public:
  explicit Program(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  bool done() const { return pos_ >= bytes_.size(); }
  std::uint8_t byte() { return pos_ < bytes_.size() ? bytes_[pos_++] : 0; }
  double raw_double() {
    std::uint64_t bits = 0;
    for (int i = 0; i < 8; ++i) bits = bits << 8 | byte();
    return std::bit_cast<double>(bits);
  }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
};

// `near`: the 1-ulp variants are allowed (see LLVMFuzzerTestOneInput: not with constraints).
Point3 lattice_point(Program& p, bool near) {
  const std::uint8_t a = p.byte(), b = p.byte();
  double x = a & 15, y = b & 15;
  int variant = a >> 4 & 3;
  if (!near && (variant == 1 || variant == 2)) variant = 0;
  switch (variant) {
    // 1 ulp off the lattice; not off 0, where one ulp is subnormal, outside the predicates'
    // exact range (predicates.hpp)
    case 1:
      if (x != 0) x = std::nextafter(x, 100.0);
      break;
    case 2:
      if (y != 0) y = std::nextafter(y, -100.0);
      break;
    case 3:
      x = x * 1e6 + 1e9;  // far away: huge coordinates beside small ones
      break;
    default:
      break;
  }
  return {x, y, static_cast<double>(b >> 4), 0.0};
}

// KERNEL_FUZZER_TRACE set: every operation is printed and the expensive check runs after each
// (to read a crash's program); KERNEL_FUZZER_DUMP adds every vertex's constrained neighbours.
const bool trace = std::getenv("KERNEL_FUZZER_TRACE") != nullptr;
const bool dump = trace && std::getenv("KERNEL_FUZZER_DUMP") != nullptr;

void check(const Triangulation& t, CheckLevel level) {
  const auto valid = t.check_valid(level);
  if (!valid.ok()) {
    if (trace) {
      for (VertexId v = 1; v < t.vertex_id_bound(); ++v) {
        if (!t.is_vertex(v)) continue;
        std::fprintf(stderr, "  v%u (%.17g, %.17g) constrained to", v, t.xy(v).x, t.xy(v).y);
        for (VertexId w : t.adjacent_vertices(v)) {
          if (t.is_constrained_edge(v, w)) std::fprintf(stderr, " %u", w);
        }
        std::fprintf(stderr, "\n");
      }
      for (const auto& seg : t.constraint_segments()) {
        std::fprintf(stderr, "  segment %u-%u\n", seg[0], seg[1]);
      }
    }
    std::fprintf(stderr, "kernel_fuzzer: check_valid: %s\n", valid.error().message.c_str());
    std::abort();
  }
}

// The live vertices, into `out` (one buffer for the whole program: an allocation per operation
// cost more under ASan than the operation).
void live(const Triangulation& t, std::vector<VertexId>& out) {
  out.clear();
  for (VertexId v = 1; v < t.vertex_id_bound(); ++v) {
    if (t.is_vertex(v)) out.push_back(v);
  }
}

std::set<std::array<VertexId, 3>> canonical(const std::vector<VertexTriple>& tris) {
  std::set<std::array<VertexId, 3>> out;
  for (auto tri : tris) {
    std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end());
    out.insert(tri);
  }
  return out;
}

// The insertion's outcome against what the triangulation held before: a point equal to a live
// vertex is that vertex's duplicate; a finite point inside the domain is otherwise inserted.
void insert_checked(Triangulation& t, const Point3& p) {
  if (trace) {
    std::fprintf(stderr, "  insert (%.17g, %.17g)\n", p.x, p.y);
  }
  const auto existing =
      std::isfinite(p.x) && std::isfinite(p.y) ? t.find_vertex(p.x, p.y) : std::nullopt;
  const bool inside = !t.domain() || t.domain()->contains(p.x, p.y);
  const bool triangulated = t.dimension() == 2;  // find_vertex sees triangulated vertices only
  const auto r = t.insert(p);
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
    if (r.outcome != InsertOutcome::rejected && r.outcome != InsertOutcome::outside_domain) {
      broken("a non-finite point was not rejected");
    }
  } else if (!triangulated) {
    return;
  } else if (existing) {
    if (r.outcome != InsertOutcome::duplicate || r.vertex != *existing) {
      broken("a point on a vertex was not its duplicate");
    }
  } else if (inside && !t.is_cut()) {
    if (r.outcome != InsertOutcome::inserted)
      broken("a new point inside the domain was not inserted");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0 || size > 1024) return 0;
  Program program({data, size});
  const std::uint8_t setup = program.byte();
  Triangulation t =
      (setup & 2) != 0 ? Triangulation(Rect{-1.0, -1.0, 17.0, 17.0}) : Triangulation();
  t.set_perturbed_ties((setup & 1) != 0);
  // Either points 1 ulp off the lattice or constraints, not both: a constraint routed through a
  // vertex 1 ulp off its line, then the removal of its end, leaves a segment that is no chain
  // (an open kernel finding, docs/SECURITY.md); each alone is fuzzed.
  const bool near = (setup & 4) != 0;
  int ops = 0;
  std::vector<VertexId> vertices;
  while (!program.done() && ops < 200 && t.vertex_id_bound() < 96) {
    ++ops;
    const int op = program.byte() % 6;
    if (trace) std::fprintf(stderr, "op %d: %d (vertices %zu)\n", ops, op, t.num_vertices());
    live(t, vertices);
    switch (op) {
      case 0:
        insert_checked(t, lattice_point(program, near));
        break;
      case 1: {
        const double x = program.raw_double(), y = program.raw_double();
        // The predicates are exact only without overflow or underflow (predicates.hpp: magnitudes
        // and differences within about [1e-60, 1e60]); finite raw values outside [1e-20, 1e20]
        // (but zero) are outside that contract and skipped. NaN and infinities go in: rejected.
        auto in_contract = [](double v) {
          const double a = std::abs(v);
          return !std::isfinite(v) || a == 0.0 || (a >= 1e-20 && a <= 1e20);
        };
        if (in_contract(x) && in_contract(y)) insert_checked(t, {x, y, 0.0, 0.0});
        break;
      }
      case 2:
        if (!vertices.empty()) {
          const VertexId v = vertices[program.byte() % vertices.size()];
          const auto r = t.remove_vertex(v);
          if (trace) {
            std::fprintf(stderr, "  remove %u: %s\n", v, r.ok() ? "ok" : r.error().message.c_str());
          }
        }
        break;
      case 3:
        if (!near && vertices.size() >= 2) {
          const VertexId a = vertices[program.byte() % vertices.size()];
          const VertexId b = vertices[program.byte() % vertices.size()];
          const auto c = t.insert_constraint(a, b);  // a == b, dimension < 2: refused, no crash
          if (trace) {
            std::fprintf(stderr, "  constraint %u (%.17g, %.17g) - %u (%.17g, %.17g): %s\n", a,
                         t.xy(a).x, t.xy(a).y, b, t.xy(b).x, t.xy(b).y,
                         c.ok() ? "ok" : c.error().message.c_str());
          }
        }
        break;
      case 4: {
        std::vector<Point3> bulk(program.byte() % 8 + 1);
        for (auto& p : bulk) p = lattice_point(program, near);
        const auto results = t.insert_bulk(bulk);
        if (trace) {
          for (std::size_t i = 0; i < bulk.size(); ++i) {
            std::fprintf(stderr, "  bulk (%.17g, %.17g): vertex %u\n", bulk[i].x, bulk[i].y,
                         results[i].vertex);
          }
        }
        if (results.size() != bulk.size()) broken("insert_bulk: one result per point");
        break;
      }
      case 5:
        if (!vertices.empty()) {
          const VertexId v = vertices[program.byte() % vertices.size()];
          auto preview = t.removal_preview(v);
          const auto before = canonical(t.finite_triangles());
          const tinstream::Status removed = t.remove_vertex(v);
          if (trace) {
            std::fprintf(stderr, "  preview+remove %u: %s\n", v,
                         removed.ok() ? "ok" : removed.error().message.c_str());
          }
          if (preview.ok() != removed.ok()) {
            std::fprintf(stderr, "kernel_fuzzer: vertex %u: preview %s, removal %s\n", v,
                         preview.ok() ? "ok" : preview.error().message.c_str(),
                         removed.ok() ? "ok" : removed.error().message.c_str());
            broken("removal_preview and remove_vertex disagree");
          }
          if (removed.ok()) {
            // What is new after the removal is exactly the preview.
            std::set<std::array<VertexId, 3>> added;
            for (const auto& tri : canonical(t.finite_triangles())) {
              if (!before.contains(tri)) added.insert(tri);
            }
            if (added != canonical(*preview))
              broken("the removal's new triangles are not the preview");
          }
        }
        break;
      default:
        break;
    }
    if (dump) {
      for (VertexId v = 1; v < t.vertex_id_bound(); ++v) {
        if (!t.is_vertex(v)) continue;
        std::fprintf(stderr, "    v%u:", v);
        for (VertexId w : t.adjacent_vertices(v)) {
          if (t.is_constrained_edge(v, w)) std::fprintf(stderr, " %u", w);
        }
        std::fprintf(stderr, "\n");
      }
    }
    // The expensive check runs the cheap one first: never both on the same state.
    if (ops % 16 == 0 || trace) {
      check(t, CheckLevel::expensive);
    } else if (ops % 4 == 0) {
      check(t, CheckLevel::cheap);
    }
  }
  // At the end, unless the last operation's check was already the expensive one.
  const bool checked_last = ops > 0 && (ops % 16 == 0 || trace);
  if (!checked_last) check(t, CheckLevel::expensive);
  return 0;
}
