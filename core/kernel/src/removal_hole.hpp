// The scratch structure of vertex removal (remove.cpp): the star of the vertex being removed and
// the new triangles that fill its hole, in local indices. Private to the kernel.
//
// The star of v, degree k (ring vertices counter-clockwise around v, indices mod k):
//
//              ring[i+1]
//               /    \       star[i]  = (v, ring[i], ring[i+1]), the old triangle
//              /      \      ring edge i = ring[i] -> ring[i+1]
//             / star[i]\     outer[i] = the old triangle across ring edge i, outside the star
//            /          \    .
//           v --------- ring[i]
//
// When v is on the hull, the ghost vertex is in the ring once (at ring[ghost_pos]) and the two
// star triangles at it are ghosts. Removing v re-triangulates the polygon ring[0..k-1] (the
// "hole") into ntri new triangles tris[0..ntri-1], each with its three links in adj (edge codes,
// below) and its constrained edges in fixed. remove_vertex then writes them into the star's
// triangle slots and links them to the outer triangles.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "tinstream/kernel/mesh.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::kernel::detail {

// ---- edge codes --------------------------------------------------------------------------------
// Each edge of a new triangle records what lies across it in one int:
//   >= 0         local_edge(L, i) = L * 3 + i: edge i of new triangle L
//   < 0          ring_edge(r) = -(r + 1): ring edge r, across which lies outer[r]
//   kUnsetEdge   an edge whose other side is created later (an ear's new diagonal)
inline constexpr int kUnsetEdge = -0x7FFFFFFF;
constexpr int local_edge(int triangle, int edge) { return triangle * 3 + edge; }
constexpr int ring_edge(std::size_t r) { return -static_cast<int>(r) - 1; }
constexpr bool is_local(int code) { return code >= 0; }
// Requires: is_local(code).
constexpr std::size_t local_triangle(int code) { return static_cast<unsigned>(code) / 3u; }
constexpr std::size_t local_index(int code) { return static_cast<unsigned>(code) % 3u; }
// Requires: !is_local(code), code != kUnsetEdge.
constexpr std::size_t ring_index(int code) { return static_cast<std::size_t>(-code - 1); }

struct RemovalHole {
  // The star: the first `degree` entries of ring, star and outer (buffers that only grow).
  std::size_t degree = 0;
  std::vector<VertexId> ring;          // link vertices, counter-clockwise around v
  std::vector<TriangleId> star;        // star[i] = (v, ring[i], ring[i + 1])
  std::vector<TriangleId> outer;       // neighbour across ring edge i
  std::vector<TriangleId> star_back;   // scratch: the star collected clockwise
  std::vector<VertexId> ring_back;     // scratch: its ring vertices
  std::vector<TriangleId> outer_back;  // scratch: its outer neighbours
  std::vector<int> outer_index;        // its edge index (filled by remove_vertex)
  bool hull = false;                   // the ghost vertex is in the link, at ring[ghost_pos]
  std::size_t ghost_pos = 0;
  // A vertex splitting a straight constraint: the two far ends, re-joined by one constrained edge.
  VertexId join_a = kNone, join_b = kNone;
  // The segment-record ends at v (2 * record index + end), found while planning: remove_vertex
  // re-ends exactly these at join_a or join_b (only with join_a set).
  std::vector<std::size_t> segment_ends;
  // Removing v leaves no triangle (v was the only vertex off a line): the mesh drops to
  // dimension 1 and nothing below is filled.
  bool degenerate = false;

  // New triangles: the first ntri entries of tris, adj and fixed (buffers that only grow, so
  // that adding a triangle is a few stores).
  std::size_t ntri = 0;
  std::vector<VertexTriple> tris;
  std::vector<std::array<int, 3>> adj;  // edge codes
  std::vector<std::uint8_t> fixed;      // per new triangle: bit i = edge i constrained
  // Working lists of the planners: the ring as a circular list (nxt, prv) with the edge code of
  // each current polygon edge (owner), an open chain, a stack, and the Lawson flip stack.
  std::vector<int> nxt, prv, owner, stack;
  std::vector<VertexId> chain;
  std::vector<std::pair<int, int>> flips;
  // Set by delaunay_apexes (stars of at most kApexMax triangles): the hole was built from ring
  // edge 0 inwards, and ring_tri[r] = the local edge code of ring edge r.
  static constexpr std::size_t kApexMax = 32;
  bool apexes = false;
  std::array<int, kApexMax> ring_tri{};

  // The plan in this hole was made for planned_vertex at the triangulation's planned_revision
  // (removal_preview leaves it for remove_vertex); kNone: none.
  VertexId planned_vertex = kNone;
  std::uint64_t planned_revision = 0;

  void clear();
  // Adds local triangle (a, b, c) whose edges opposite a, b, c have edge codes oa, ob, oc; a
  // local code gets its back link. Returns the new triangle's local index.
  int add(VertexId a, VertexId b, VertexId c, int oa, int ob, int oc);
  void grow();
  void grow_star(std::size_t n);  // room for a star of n triangles
  // Open chain: chain[0..m-1] (closed by an edge chain[m-1] -> chain[0] on v's side) made convex
  // as seen from v by clipping ears; owner[k] is the code of the edge chain[k] -> chain[k+1].
  // Leaves the positions of the remaining chain in stack.
  void convexify(const Mesh& mesh);
  // Closed link polygon (interior vertex): the ring as a circular list, one ear at a time.
  void start_ring();
  void clip_ear(int c);    // adds the ear (prv[c], c, nxt[c]) and unlinks c
  void close_ring(int c);  // adds the last triangle (prv[c], c, nxt[c])
  bool triangulate_quad(const Mesh& mesh);
  bool clip_delaunay_ears(const Mesh& mesh, const XY& pv);
  bool delaunay_apexes(const Mesh& mesh);
  // The Lawson flip of the diagonal across edge i of new triangle L (same as Mesh::flip).
  // Returns the other triangle's index.
  int flip(int L, int i);
};

}  // namespace tinstream::kernel::detail
