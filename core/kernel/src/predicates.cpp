// Exact slow paths of orient2d / incircle: floating-point expansion arithmetic after Shewchuk,
// "Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates" (1996).
//
// An expansion is a sum of doubles ordered by increasing magnitude whose components do not
// overlap; its sign is the sign of its largest (last) nonzero component. Every operation below
// is error-free (its result represents the exact real value) as long as nothing overflows or
// underflows, given IEEE-754 round-to-nearest double arithmetic (no x87, no FMA contraction:
// the kernel target compiles with -ffp-contract=off).
#include "tinstream/kernel/predicates.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstddef>

namespace tinstream::kernel::detail {
namespace {

// a + b = x + y exactly, |y| <= ulp(x)/2.
inline void two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  const double bv = x - a;
  const double av = x - bv;
  y = (a - av) + (b - bv);
}

// Requires |a| >= |b| (or a == 0).
inline void fast_two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  y = b - (x - a);
}

inline void two_diff(double a, double b, double& x, double& y) {
  x = a - b;
  const double bv = a - x;
  const double av = x + bv;
  y = (a - av) + (bv - b);
}

// Dekker split: a = hi + lo, each with at most 26 significant bits.
inline void split(double a, double& hi, double& lo) {
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1
  const double c = kSplitter * a;
  const double big = c - a;
  hi = c - big;
  lo = a - hi;
}

// a * b = x + y exactly.
inline void two_product(double a, double b, double& x, double& y) {
  x = a * b;
  double ahi, alo, bhi, blo;
  split(a, ahi, alo);
  split(b, bhi, blo);
  const double err1 = x - ahi * bhi;
  const double err2 = err1 - alo * bhi;
  const double err3 = err2 - ahi * blo;
  y = alo * blo - err3;
}

constexpr std::size_t kCap = 512;

struct Expansion {
  std::array<double, kCap> c;
  std::size_t n = 0;

  double sign_value() const { return n == 0 ? 0.0 : c[n - 1]; }
};

// h = e + b, zero components removed (Shewchuk's Grow-Expansion).
void grow(const Expansion& e, double b, Expansion& h) {
  double q = b;
  std::size_t k = 0;
  for (std::size_t i = 0; i < e.n; ++i) {
    double sum, err;
    two_sum(q, e.c[i], sum, err);
    q = sum;
    if (err != 0.0) h.c[k++] = err;
  }
  if (q != 0.0 || k == 0) h.c[k++] = q;
  h.n = (k == 1 && h.c[0] == 0.0) ? 0 : k;
  assert(h.n <= kCap);
}

std::size_t scale_short(std::size_t n, const double* e, double b, double* h);

// h = e * b (Shewchuk's Scale-Expansion), zero components removed.
void scale(const Expansion& e, double b, Expansion& h) {
  h.n = scale_short(e.n, e.c.data(), b, h.c.data());
  assert(h.n <= kCap);
}

// Renormalises e in place into an equivalent, usually much shorter, expansion
// (Shewchuk's Compress). Keeps later sums cheap.
void compress(Expansion& e) {
  if (e.n < 2) return;
  std::array<double, kCap> g;
  std::size_t bottom = e.n - 1;
  double q = e.c[e.n - 1];
  for (std::size_t i = e.n - 1; i-- > 0;) {
    double big, small;
    fast_two_sum(q, e.c[i], big, small);
    if (small != 0.0) {
      g[bottom--] = big;
      q = small;
    } else {
      q = big;
    }
  }
  g[bottom] = q;
  std::size_t top = 0;
  for (std::size_t i = bottom + 1; i < e.n; ++i) {
    double big, small;
    fast_two_sum(g[i], q, big, small);
    q = big;
    if (small != 0.0) e.c[top++] = small;
  }
  e.c[top++] = q;
  e.n = (top == 1 && e.c[0] == 0.0) ? 0 : top;
}

// h = e + f.
void add(const Expansion& e, const Expansion& f, Expansion& h) {
  Expansion tmp;
  const Expansion* small = &e;
  const Expansion* large = &f;
  if (e.n > f.n) std::swap(small, large);
  h.n = large->n;
  std::copy_n(large->c.begin(), large->n, h.c.begin());
  for (std::size_t i = 0; i < small->n; ++i) {
    grow(h, small->c[i], tmp);
    h.n = tmp.n;
    std::copy_n(tmp.c.begin(), tmp.n, h.c.begin());
  }
  compress(h);
}

void negate(Expansion& e) {
  for (std::size_t i = 0; i < e.n; ++i) e.c[i] = -e.c[i];
}

// h = e * f.
void mul(const Expansion& e, const Expansion& f, Expansion& h) {
  h.n = 0;
  Expansion term, acc;
  for (std::size_t i = 0; i < f.n; ++i) {
    scale(e, f.c[i], term);
    compress(term);
    add(h, term, acc);
    h.n = acc.n;
    std::copy_n(acc.c.begin(), acc.n, h.c.begin());
  }
}

Expansion from_diff(double a, double b) {
  Expansion e;
  double x, y;
  two_diff(a, b, x, y);
  if (y != 0.0) e.c[e.n++] = y;
  if (x != 0.0) e.c[e.n++] = x;
  return e;
}

// e1*f1 - e2*f2 for expansions.
Expansion cross(const Expansion& e1, const Expansion& f1, const Expansion& e2,
                const Expansion& f2) {
  Expansion p, q, r;
  mul(e1, f1, p);
  mul(e2, f2, q);
  negate(q);
  add(p, q, r);
  return r;
}

Expansion lift(const Expansion& dx, const Expansion& dy) {
  Expansion p, q, r;
  mul(dx, dx, p);
  mul(dy, dy, q);
  add(p, q, r);
  return r;
}

// ── Short expansions on raw arrays, linear time ──────────────────────────────────────────────
// For the common degenerate case (lattices, nearby points): every coordinate difference is exact,
// so the determinants are short sums of exact products, evaluated without the general path's
// 512-component temporaries.

// h = e * b; returns h's length. e nonoverlapping, increasing magnitude, no zeros; same for h.
std::size_t scale_short(std::size_t n, const double* e, double b, double* h) {
  if (n == 0 || b == 0.0) return 0;
  std::size_t k = 0;
  double q, hh;
  two_product(e[0], b, q, hh);
  if (hh != 0.0) h[k++] = hh;
  for (std::size_t i = 1; i < n; ++i) {
    double p1, p0, sum, err;
    two_product(e[i], b, p1, p0);
    two_sum(q, p0, sum, err);
    if (err != 0.0) h[k++] = err;
    fast_two_sum(p1, sum, q, err);
    if (err != 0.0) h[k++] = err;
  }
  if (q != 0.0) h[k++] = q;
  return k;
}

// h = e + f by merging the components in order of magnitude and summing them in one pass
// (Shewchuk's Fast-Expansion-Sum with zero elimination; Two-Sum at every step). Returns h's length.
std::size_t sum_short(std::size_t en, const double* e, std::size_t fn, const double* f, double* h) {
  std::size_t i = 0, j = 0, k = 0;
  auto next = [&]() {
    if (j >= fn || (i < en && std::abs(e[i]) <= std::abs(f[j]))) return e[i++];
    return f[j++];
  };
  if (en + fn == 0) return 0;
  double q = next();
  while (i < en || j < fn) {
    double sum, err;
    two_sum(q, next(), sum, err);
    q = sum;
    if (err != 0.0) h[k++] = err;
  }
  if (q != 0.0 || k == 0) h[k++] = q;
  return (k == 1 && h[0] == 0.0) ? 0 : k;
}

// a*b - c*d exactly, for doubles; returns the length (≤ 4).
std::size_t cross_short(double a, double b, double c, double d, double* h) {
  double x1, y1, x0, y0;
  two_product(a, b, x1, y1);
  two_product(c, d, x0, y0);
  double p[2], m[2];
  std::size_t pn = 0, mn = 0;
  if (y1 != 0.0) p[pn++] = y1;
  if (x1 != 0.0) p[pn++] = x1;
  if (y0 != 0.0) m[mn++] = -y0;
  if (x0 != 0.0) m[mn++] = -x0;
  return sum_short(pn, p, mn, m, h);
}

// (dx² + dy²) · e exactly; returns the length (≤ 8·len(e)).
std::size_t lift_times(double dx, double dy, std::size_t n, const double* e, double* h) {
  double t1[8], t2[16], t3[8], t4[16];
  const std::size_t n1 = scale_short(n, e, dx, t1);
  const std::size_t n2 = scale_short(n1, t1, dx, t2);
  const std::size_t n3 = scale_short(n, e, dy, t3);
  const std::size_t n4 = scale_short(n3, t3, dy, t4);
  return sum_short(n2, t2, n4, t4, h);
}

double incircle_exact_differences(double adx, double ady, double bdx, double bdy, double cdx,
                                  double cdy) {
  double bc[4], ca[4], ab[4];
  const std::size_t bcn = cross_short(bdx, cdy, cdx, bdy, bc);
  const std::size_t can = cross_short(cdx, ady, adx, cdy, ca);
  const std::size_t abn = cross_short(adx, bdy, bdx, ady, ab);
  double at[32], bt[32], ct[32], s[64], det[96];
  const std::size_t an = lift_times(adx, ady, bcn, bc, at);
  const std::size_t bn = lift_times(bdx, bdy, can, ca, bt);
  const std::size_t cn = lift_times(cdx, cdy, abn, ab, ct);
  const std::size_t sn = sum_short(an, at, bn, bt, s);
  const std::size_t dn = sum_short(sn, s, cn, ct, det);
  return dn == 0 ? 0.0 : det[dn - 1];
}

// Whether the four points are the corners of one axis-parallel rectangle of nonzero size (in any
// order): then they are exactly cocircular. The commonest degenerate case by far — every cell of a
// DEM lattice (also in Mercator, where rows are unevenly spaced) — decided by comparisons alone.
bool axis_parallel_rectangle(const XY& a, const XY& b, const XY& c, const XY& d) {
  const XY* p[4] = {&a, &b, &c, &d};
  const double x0 = a.x, y0 = a.y;
  double x1 = x0, y1 = y0;
  for (const XY* q : p) {
    if (q->x != x0) x1 = q->x;
    if (q->y != y0) y1 = q->y;
  }
  if (x1 == x0 || y1 == y0) return false;
  bool seen[4] = {false, false, false, false};
  for (const XY* q : p) {
    if ((q->x != x0 && q->x != x1) || (q->y != y0 && q->y != y1)) return false;
    const int corner = (q->x == x1 ? 1 : 0) + (q->y == y1 ? 2 : 0);
    if (seen[corner]) return false;
    seen[corner] = true;
  }
  return true;
}

bool exact_difference(double a, double b, double& d) {
  double err;
  two_diff(a, b, d, err);
  return err == 0.0;
}

}  // namespace

double orient2d_exact(const XY& a, const XY& b, const XY& c) {
  if (double d[4]; exact_difference(a.x, c.x, d[0]) && exact_difference(a.y, c.y, d[1]) &&
                   exact_difference(b.x, c.x, d[2]) && exact_difference(b.y, c.y, d[3])) {
    double h[4];
    const std::size_t n = cross_short(d[0], d[3], d[1], d[2], h);
    return n == 0 ? 0.0 : h[n - 1];
  }
  const Expansion acx = from_diff(a.x, c.x), acy = from_diff(a.y, c.y);
  const Expansion bcx = from_diff(b.x, c.x), bcy = from_diff(b.y, c.y);
  return cross(acx, bcy, acy, bcx).sign_value();
}

double incircle_exact(const XY& a, const XY& b, const XY& c, const XY& d) {
  if (axis_parallel_rectangle(a, b, c, d)) return 0.0;
  if (double e[6]; exact_difference(a.x, d.x, e[0]) && exact_difference(a.y, d.y, e[1]) &&
                   exact_difference(b.x, d.x, e[2]) && exact_difference(b.y, d.y, e[3]) &&
                   exact_difference(c.x, d.x, e[4]) && exact_difference(c.y, d.y, e[5])) {
    return incircle_exact_differences(e[0], e[1], e[2], e[3], e[4], e[5]);
  }
  const Expansion adx = from_diff(a.x, d.x), ady = from_diff(a.y, d.y);
  const Expansion bdx = from_diff(b.x, d.x), bdy = from_diff(b.y, d.y);
  const Expansion cdx = from_diff(c.x, d.x), cdy = from_diff(c.y, d.y);
  // When the differences are exact (nearby points, lattices) every expansion below has one
  // component per difference and the products stay short; otherwise the tails are carried.
  const Expansion bc = cross(bdx, cdy, cdx, bdy);
  const Expansion ca = cross(cdx, ady, adx, cdy);
  const Expansion ab = cross(adx, bdy, bdx, ady);
  const Expansion al = lift(adx, ady), bl = lift(bdx, bdy), cl = lift(cdx, cdy);
  Expansion t1, t2, t3, s12, total;
  mul(al, bc, t1);
  mul(bl, ca, t2);
  mul(cl, ab, t3);
  add(t1, t2, s12);
  add(s12, t3, total);
  return total.sign_value();
}

int perturbed_tie(const XY& a, const XY& b, const XY& c, const XY& d) {
  // Cofactor of each point's lift (see perturbed_incircle), highest lexicographic rank first.
  const auto lex_greater = [](const XY* l, const XY* r) {
    return l->x > r->x || (l->x == r->x && l->y > r->y);
  };
  const XY* order[4] = {&a, &b, &c, &d};
  std::sort(std::begin(order), std::end(order), lex_greater);
  for (const XY* t : order) {
    double s;
    if (t == &d) {
      s = -orient2d(a, b, c);
    } else if (t == &a) {
      s = orient2d(d, b, c);
    } else if (t == &b) {
      s = orient2d(a, d, c);
    } else {
      s = orient2d(a, b, d);
    }
    if (s > 0.0) return 1;
    if (s < 0.0) return -1;
  }
  return -1;  // degenerate (a, b, c collinear): treat as outside
}

}  // namespace tinstream::kernel::detail
