// A cheap lower bound of the vertical error that removing a vertex makes at the vertex itself,
// from its ring alone (no kernel removal preview): the drop stage's first key for a vertex
// (thinning.cpp). Internal to core/lod.
//
// Why it holds. Removing v re-triangulates its star as the constrained Delaunay triangulation
// (CDT) of its ring polygon. The ring is star-shaped around v, so every ring vertex is visible
// from the replacement triangle T that contains v (from the points of T next to v); a CDT
// triangle has no vertex visible from it inside its circumcircle, so T's circumcircle holds no
// ring vertex and T is the triangle at v of the plain Delaunay triangulation of the ring points.
// Lifted to the paraboloid (x, y, x² + y²), Delaunay triangles are the lower convex hull: among
// all ring triangles that contain v, T is one whose lifted plane is lowest at v (several tie when
// ring points are cocircular, e.g. on a lattice, and the kernel picks one of them). So
//
//   error at v after the removal = |z(v) − plane_T(v)|
//                                ≥ min over ring triangles (i, j, k) ∋ v with lift_ijk(v) within
//                                  rounding of the lowest lift of |z(v) − plane_ijk(v)|
//
// less a margin for rounding (relative 1e-9 × the triangle's conditioning: many orders of
// magnitude above the rounding of either this evaluation or thinning.cpp's Plane). Everything
// uncertain is decided towards a smaller bound: a triangle counts as containing v up to
// rounding, and every triangle within the rounding window of the lowest lift counts.
//
//          r2 ─────── r1          ring r0 … r5 counter-clockwise around v, coordinates relative
//         ╱ ╲       ╱   ╲         to v; triangle (i < j < k) contains v when r_i → r_j, r_j →
//       r3    ╲   ╱      r0       r_k and r_k → r_i each turn at most half a turn around v
//         ╲    ╲╱   v   ╱
//          r4 ─────── r5
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include "tinstream/kernel/triangulation.hpp"

namespace tinstream::lod::detail {

// A lower bound (≥ 0) of |z(v) − the surface at v| once v is removed from `tri`, the surface
// being any replacement triangle containing v, evaluated in double. nullopt when not computed: v
// not an interior vertex with a closed fan of finite triangles, more than 12 ring vertices, an
// ill-conditioned ring triangle around v.
// Requires: v a live vertex of tri (dimension 2).
inline std::optional<double> removal_error_bound(const kernel::Triangulation& tri,
                                                 kernel::VertexId v) {
  constexpr std::size_t kMax = 12;
  const kernel::Mesh& m = tri.mesh();
  const kernel::TriangleId t0 = m.vertex_triangle(v);
  const kernel::XY c = tri.xy(v);
  const double zv = tri.z(v);
  // The ring counter-clockwise: x, y relative to v, z, and x² + y² (the lift).
  double ax[kMax], ay[kMax], az[kMax], al[kMax];
  std::size_t d = 0;
  double zmax = std::abs(zv), lmax = 0;
  kernel::TriangleId t = t0;
  do {
    if (m.is_ghost(t) || d == kMax) return std::nullopt;
    const int k = m.index_of(t, v);
    const kernel::Triangle& T = m.tri(t);
    const kernel::VertexId r = T.v[static_cast<std::size_t>(k == 2 ? 0 : k + 1)];
    const kernel::XY& p = tri.xy(r);
    ax[d] = p.x - c.x, ay[d] = p.y - c.y, az[d] = tri.z(r);
    al[d] = ax[d] * ax[d] + ay[d] * ay[d];
    zmax = std::max(zmax, std::abs(az[d]));
    lmax = std::max(lmax, al[d]);
    ++d;
    t = T.n[static_cast<std::size_t>(k == 2 ? 0 : k + 1)];  // the next triangle counter-clockwise
    if (t == kernel::kNone) return std::nullopt;            // a cut mesh
  } while (t != t0);
  // cr[i][j] (i < j): twice the signed area of (v, r_i, r_j); its terms are below lmax, so
  // rounding decides its sign only within ± 1e-9 × lmax. As bit sets by j: ccw[i], r_j at most
  // half a turn counter-clockwise from r_i (cr ≥ 0 up to rounding), cw[i] at least (cr ≤ 0).
  double cr[kMax][kMax];
  std::uint32_t ccw[kMax], cw[kMax];
  const double tol = 1e-9 * lmax;
  for (std::size_t i = 0; i < d; ++i) {
    std::uint32_t fwd = 0, back = 0;
    for (std::size_t j = i + 1; j < d; ++j) {
      const double a = ax[i] * ay[j] - ay[i] * ax[j];
      cr[i][j] = a;
      fwd |= static_cast<std::uint32_t>(a >= -tol) << j;
      back |= static_cast<std::uint32_t>(a <= tol) << j;
    }
    ccw[i] = fwd, cw[i] = back;
  }
  // Triangles (i < j < k) containing v: k in ccw[j] & cw[i]. Their rounding grows with span /
  // (twice the area), every span below 4 × lmax.
  const double span = 4 * lmax;
  struct Candidate {
    double lift, error, cond;
  };
  Candidate cand[kMax * (kMax - 1) * (kMax - 2) / 6];
  std::size_t n = 0;
  double lowest = std::numeric_limits<double>::infinity(), lowest_cond = 0;
  for (std::size_t i = 0; i < d; ++i) {
    for (std::uint32_t js = ccw[i]; js != 0; js &= js - 1) {
      const auto j = static_cast<std::size_t>(std::countr_zero(js));
      for (std::uint32_t ks = ccw[j] & cw[i]; ks != 0; ks &= ks - 1) {
        const auto k = static_cast<std::size_t>(std::countr_zero(ks));
        // Barycentric weights of v (at the origin) are the areas opposite each corner.
        const double cij = cr[i][j], cjk = cr[j][k], cki = -cr[i][k];
        const double den = cij + cjk + cki;
        if (!(den > 1e-6 * span)) return std::nullopt;  // ill-conditioned (or degenerate)
        const double inv = 1 / den;
        const double lift = (cjk * al[i] + cki * al[j] + cij * al[k]) * inv;
        const double zh = (cjk * az[i] + cki * az[j] + cij * az[k]) * inv;
        const double cond = 1 + span * inv;
        cand[n++] = {lift, std::abs(zv - zh), cond};
        if (lift < lowest) lowest = lift, lowest_cond = cond;
      }
    }
  }
  // The kernel's triangle T: lift_T ≤ lift_lowest exactly, so computed within both roundings.
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t q = 0; q < n; ++q) {
    if (cand[q].lift <= lowest + 1e-9 * lmax * (cand[q].cond + lowest_cond))
      best = std::min(best, cand[q].error - 1e-9 * zmax * cand[q].cond);
  }
  if (!(best < std::numeric_limits<double>::infinity())) return std::nullopt;
  return std::max(best, 0.0);
}

}  // namespace tinstream::lod::detail
