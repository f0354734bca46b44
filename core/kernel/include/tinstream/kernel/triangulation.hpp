// tinstream/kernel/triangulation.hpp — constrained Delaunay triangulation (layer 3: algorithms).
//
// Contract
//  * A Triangulation owns its Mesh (mesh.hpp) and keeps it a constrained Delaunay triangulation
//    of the inserted vertices covering exactly their convex hull: every edge that is not
//    constrained satisfies the empty-circle property, decided with the exact predicates of
//    predicates.hpp; constrained edges are never flipped. Ties (cocircular points) are resolved
//    by insertion order, like CGAL's Delaunay_triangulation_2, or — with set_perturbed_ties —
//    by perturbed_incircle, which makes the triangulation of unconstrained points the canonical
//    one whatever the insertion order.
//  * Vertex ids are stable: a vertex keeps its id until it is removed, and ids of removed
//    vertices are not reused. Id 0 is the infinite vertex. Triangle ids are *not* stable across
//    edits (slots are recycled through a free list); hold vertex ids, not triangle ids.
//  * Bad input (a duplicate point, a point outside the domain, a vertex that cannot be removed)
//    is reported through return values (InsertResult, Status, Result), never by throwing.
//  * Until three non-collinear points were inserted the triangulation has no triangles
//    (dimension < 2); the vertices are kept and triangulated when the first point off their
//    line arrives. Collinear-only input therefore yields zero triangles, as in CGAL.
//  * After remove_triangles_if / remove_triangles_outside the mesh is "cut" (islands, neighbour
//    kNone at the cut): queries keep working, insertions and removals return an error.
//  * Thread-safety: none. Use one Triangulation per thread; const queries also update the
//    location hint, so even they must not run concurrently on one object.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/kernel/mesh.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::kernel {

namespace detail {
struct RemovalHole;  // vertex removal's scratch (src/removal_hole.hpp)
struct SegmentWalk;  // one step of constraint insertion (src/constrain.cpp)
// Owns a RemovalHole, made on first use, so that removals reuse its buffers. A copy starts with
// none (scratch and a removal plan are not part of a triangulation's value).
class RemovalScratch {
 public:
  RemovalScratch() noexcept;
  RemovalScratch(const RemovalScratch&) noexcept;
  RemovalScratch& operator=(const RemovalScratch&) noexcept;
  RemovalScratch(RemovalScratch&&) noexcept;
  RemovalScratch& operator=(RemovalScratch&&) noexcept;
  ~RemovalScratch();
  RemovalHole& get();

 private:
  std::unique_ptr<RemovalHole> hole_;
};
}  // namespace detail

struct Point3 {
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;       // elevation
  double weight = 0.0;  // importance for thinning
};

// Closed axis-aligned rectangle.
struct Rect {
  double xmin, ymin, xmax, ymax;
  bool contains(double x, double y) const {
    return x >= xmin && x <= xmax && y >= ymin && y <= ymax;
  }
};

enum class InsertOutcome : std::uint8_t {
  inserted,        // vertex is the new vertex
  duplicate,       // same (x, y) as an existing vertex: vertex is that vertex, nothing changed
  outside_domain,  // outside the domain rectangle: vertex is kNone, nothing changed
  rejected,        // not a finite point, or the mesh is cut: vertex is kNone
};

struct InsertResult {
  InsertOutcome outcome;
  VertexId vertex;
};

using VertexTriple = std::array<VertexId, 3>;

enum class CheckLevel {
  cheap,      // references, neighbour symmetry, orientation, ghost structure: O(n)
  expensive,  // + empty circle (exact) across every unconstrained edge, convex hull,
              //   recorded constraint segments present as chains of constrained edges
};

class Triangulation {
 public:
  Triangulation() = default;
  // Points outside `domain` are rejected (InsertOutcome::outside_domain).
  explicit Triangulation(const Rect& domain) : domain_(domain) {}

  // ---- building -------------------------------------------------------------------------------
  // Removes every vertex, triangle and constraint but keeps the memory (the domain stays): the
  // triangulation then behaves exactly as a newly constructed one — the same insertions give the
  // same vertex and triangle ids — so one object can serve many builds without reallocating.
  void clear();
  // Insertions flip cocircular ties by perturbed_incircle (predicates.hpp) instead of keeping
  // the first diagonal found: a triangulation of points without constraints is then the
  // canonical Delaunay triangulation (triangle ids still depend on the insertion order). Set
  // before inserting; clear() keeps it.
  void set_perturbed_ties(bool on) { perturbed_ties_ = on; }
  InsertResult insert(const Point3& p);
  // Inserts all points in a spatially sorted order (BRIO rounds, each in Hilbert order); result
  // i belongs to points[i]. Among exact duplicates the first in `points` wins (its z and weight
  // are kept; the others are reported as duplicates of it).
  std::vector<InsertResult> insert_bulk(std::span<const Point3> points);

  // Makes the straight segment a-b a chain of constrained edges. Vertices lying exactly on it
  // split it; a crossing constrained edge gets a new vertex at the intersection (elevation
  // interpolated along a-b, weight the larger of a's and b's) and both segments are split there.
  // Requires: a, b live finite vertices. Errors: a == b, dimension < 2, mesh cut.
  Status insert_constraint(VertexId a, VertexId b);
  // Inserts the two points (or finds them when they exist) and then the segment.
  Result<std::array<VertexId, 2>> insert_constraint(const Point3& a, const Point3& b);

  // Removes v and re-triangulates its star as constrained Delaunay, O(degree) expected.
  // A vertex with incident constrained edges is removed only when exactly two are incident and
  // they are exactly collinear through v (v splits a straight constraint): the two pieces are
  // re-joined into one constrained edge. Otherwise the Status says why (invalid_argument).
  Status remove_vertex(VertexId v);
  // The finite triangles (counter-clockwise vertex triples) that would replace v's star if v
  // were removed, without changing anything. Same refusals as remove_vertex. Calling
  // remove_vertex(v) right after (no edit in between) reuses this work. remove_vertex writes
  // the new triangles into slots of the star's old triangles.
  Result<std::vector<VertexTriple>> removal_preview(VertexId v) const;

  // Deletes finite triangles for which `drop` is true, and all ghost triangles; the remaining
  // triangles keep their references, with neighbour kNone across the cut (the mesh becomes
  // "cut", see the contract). Vertices left without triangles are marked removed.
  // Returns the number of finite triangles deleted.
  std::size_t remove_triangles_if(const std::function<bool(const VertexTriple&)>& drop);
  // Deletes the finite triangles whose centroid lies outside `r`.
  std::size_t remove_triangles_outside(const Rect& r);

  // ---- queries --------------------------------------------------------------------------------
  // Elevation at (x, y) by linear interpolation in the containing triangle; nullopt outside the
  // triangulated area.
  std::optional<double> interpolate(double x, double y) const;
  // The live vertex at exactly (x, y), if any.
  std::optional<VertexId> find_vertex(double x, double y) const;
  // A finite triangle containing (x, y) (on its boundary included), or kNone.
  TriangleId locate_triangle(double x, double y) const;

  Status check_valid(CheckLevel level) const;

  std::size_t num_vertices() const { return live_vertices_; }  // finite, live
  std::size_t num_finite_triangles() const;
  bool is_cut() const { return cut_; }
  int dimension() const;  // -1 empty, 0 one point, 1 collinear, 2 triangulated

  bool is_vertex(VertexId v) const;  // live finite vertex
  const XY& xy(VertexId v) const { return mesh_.xy(v); }
  double z(VertexId v) const { return mesh_.z(v); }
  double weight(VertexId v) const { return mesh_.weight(v); }
  std::size_t vertex_id_bound() const { return mesh_.vertex_slots(); }  // ids are < this

  // Calls f(TriangleId, const Triangle&) for every live finite triangle.
  template <typename F>
  void for_each_finite_triangle(F&& f) const {
    for (TriangleId t = 0; t < mesh_.triangle_slots(); ++t) {
      if (mesh_.is_live(t) && !mesh_.is_ghost(t)) f(t, mesh_.tri(t));
    }
  }
  std::vector<VertexTriple> finite_triangles() const;
  // Live triangles around v in counter-clockwise order (ghost ones included unless finite_only).
  std::vector<TriangleId> incident_triangles(VertexId v, bool finite_only = true) const;
  // Vertices adjacent to v in counter-clockwise order (the infinite vertex included when v is
  // on the hull and include_infinite).
  std::vector<VertexId> adjacent_vertices(VertexId v, bool include_infinite = false) const;
  bool is_edge(VertexId a, VertexId b) const;
  bool is_constrained_edge(VertexId a, VertexId b) const;
  bool is_on_hull(VertexId v) const;
  // The constraint segments as requested (endpoint ids; re-joined on vertex removal).
  const std::vector<std::array<VertexId, 2>>& constraint_segments() const { return segments_; }

  const Mesh& mesh() const { return mesh_; }
  const std::optional<Rect>& domain() const { return domain_; }
  std::size_t memory_bytes() const { return mesh_.memory_bytes(); }

 private:
  enum class Where : std::uint8_t { inside, on_edge, on_vertex, outside_hull };
  struct Location {
    Where where;
    TriangleId t;
    int index;  // on_edge: edge index; on_vertex: vertex index
  };

  Location locate(const XY& p, TriangleId hint) const;
  InsertResult insert_vertex(VertexId v, TriangleId hint);
  InsertResult insert_at(VertexId v, const Location& loc);
  // Lawson flips from p; the first `top` entries of stack_ are the edges opposite p to test.
  void legalize(VertexId p, std::size_t top);
  void raise_dimension(VertexId off_line);
  bool pending_contains(const XY& p, VertexId* found) const;
  TriangleId start_triangle(TriangleId hint) const;

  // Constraint insertion (constrain.cpp): insert_segment splits a-b at vertices on it and at
  // crossed constraints into sub-segments; each is walked (walk_segment), its crossed edges are
  // flipped away (flip_crossed_away), and the flipped edges are made Delaunay again.
  Status insert_segment(VertexId a, VertexId b);
  Status walk_segment(detail::SegmentWalk& walk);
  Status flip_crossed_away(detail::SegmentWalk& walk, std::vector<std::array<VertexId, 2>>& fresh);
  void restore_delaunay(std::vector<std::array<VertexId, 2>>& edges);
  void restore_delaunay_everywhere();
  VertexId insert_intersection(VertexId a, VertexId b, TriangleId t, int edge);

  // Vertex removal (remove.cpp): plan_removal fills the hole (the re-triangulated star, in
  // src/removal_hole.hpp) in three cases: a vertex on the hull, one splitting a straight
  // constraint, an interior one.
  Status plan_removal(VertexId v, detail::RemovalHole& hole, bool any_order = false) const;
  TriangleId write_hole(detail::RemovalHole& hole);
  TriangleId write_apex_hole(detail::RemovalHole& hole);
  TriangleId write_hole_general(detail::RemovalHole& hole);
  void demote_to_collinear(VertexId removed);
  TriangleId find_edge(VertexId a, VertexId b, int* index) const;
  bool segment_chain_present(VertexId a, VertexId b) const;

  Mesh mesh_;
  std::optional<Rect> domain_;
  std::vector<VertexId> pending_;  // vertices while dimension < 2
  std::vector<std::array<VertexId, 2>> segments_;
  // Intersection vertices the current insert_constraint may still add: rounded intersection
  // points bend the crossed constraints, which can cross others near them again; this bounds
  // that cascade (set from the number of recorded segments).
  std::size_t intersections_left_ = 0;
  // Flip stack storage: its size is its capacity (grown by legalize, never shrunk); how much of
  // it is in use is legalize's local `top`.
  std::vector<std::pair<TriangleId, int>> stack_ = std::vector<std::pair<TriangleId, int>>(64);
  // Every edit bumps revision_; a removal_preview(v) leaves its plan in the removal scratch so
  // that remove_vertex(v) with no edit in between does not compute it again.
  mutable detail::RemovalScratch removal_;
  std::uint64_t revision_ = 0;
  mutable TriangleId hint_ = kNone;
  // Walks in a Delaunay triangulation cannot cycle; once constraints exist they can, and the
  // walk picks its first edge at random (remembering stochastic walk).
  bool randomize_walk_ = false;
  bool has_constraints_ = false;
  bool perturbed_ties_ = false;
  static constexpr std::uint32_t kRngSeed = 0x9E3779B9u;
  mutable std::uint32_t rng_ = kRngSeed;
  std::size_t live_vertices_ = 0;
  bool cut_ = false;
};

}  // namespace tinstream::kernel
