// Exchange steps after the drop stage (exchange.hpp has the contract).
//
// Bookkeeping: every point that is not a vertex is filed under the live triangle slot holding it
// (by_slot_) with its vertical error (err_). After an edit, the slots whose vertex triple changed
// are dirty and their points are located again; a removal's candidates are judged on the kernel's
// removal preview, at the points of the vertex's star, against the largest error outside it.
#include "exchange.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include "plane.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::lod::detail {
namespace {

using kernel::kNone;
using kernel::TriangleId;
using kernel::VertexId;
using kernel::VertexTriple;
using kernel::XY;

constexpr VertexTriple kDead = {kNone, kNone, kNone};

// Whether (x, y), lying in the triangle t of `tri` (or of a removal preview there), is outside the
// data footprint beyond `tolerance` (normalised units): t has two or three of `nodata_corners`,
// or one and (x, y) is off the line of t's data edge (exact orient2d) by more than the tolerance
// (greedy.hpp: coverage first).
bool uncovered(const kernel::Triangulation& tri, const VertexTriple& t,
               std::span<const VertexId> nodata_corners, double tolerance, double x, double y) {
  int nodata = 0, k_nodata = 0;
  for (int k = 0; k < 3; ++k) {
    const VertexId v = t[static_cast<std::size_t>(k)];
    if (std::find(nodata_corners.begin(), nodata_corners.end(), v) != nodata_corners.end()) {
      ++nodata, k_nodata = k;
    }
  }
  if (nodata == 0) return false;
  if (nodata > 1) return true;
  const XY& a = tri.xy(t[static_cast<std::size_t>((k_nodata + 1) % 3)]);
  const XY& b = tri.xy(t[static_cast<std::size_t>((k_nodata + 2) % 3)]);
  if (kernel::orient2d(a, b, XY{x, y}) == 0) return false;
  const double c = (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
  return !(std::abs(c) <= tolerance * std::hypot(b.x - a.x, b.y - a.y));
}

class Exchanger {
 public:
  Exchanger(kernel::Triangulation& tri, const ExchangeInput& in) : tri_(tri), in_(in) {
    auto add = [&](const tile::Vertex& v) {
      x_.push_back(v.x), y_.push_back(v.y), z_.push_back(v.z);
    };
    for (const auto& v : in.candidates) add(v);
    for (const auto& list : in.others) {
      for (const auto& v : list) add(v);
    }
    state_.assign(x_.size(), kLocate);
    err_.assign(x_.size(), 0.0);
    const auto& cv = *in.candidate_vertex;
    for (std::size_t j = 0; j < in.candidates.size(); ++j) {
      if (cv[j] != kNone && tri_.is_vertex(cv[j])) set_vertex(j, true);
    }
    for (std::size_t i = 0; i < x_.size(); ++i) {
      if (state_[i] == kLocate) pending_.push_back(static_cast<std::uint32_t>(i));
    }
  }

  Result<ExchangeResult> run(std::size_t max_steps) {
    ExchangeResult res;
    refile();
    double e_max = worst().second;
    res.before = e_max;
    // Removals tried in all (a bound on the work of failed exchanges).
    std::size_t work = 0;
    const std::size_t max_work = 8 * max_steps;
    while (res.steps < max_steps && work < max_work) {
      bool lowered = false;
      for (std::size_t k = 1; k <= kMaxExchanged && !lowered && work < max_work; ++k) {
        touched_.clear();
        auto made = exchange(k, &work);
        if (!made) return made.error();
        const double now = worst().second;
        if (*made && now < e_max) {
          e_max = now;
          lowered = true;
          ++res.steps;
        } else if (Status s = revert(); !s) {
          return s.error();
        }
      }
      if (!lowered) break;
    }
    res.after = e_max;
    return res;
  }

 private:
  // At most this many points go in (and as many vertices out) in one exchange.
  static constexpr std::size_t kMaxExchanged = 8;

  // The filed point of largest error (kNone when none) and its error.
  std::pair<std::size_t, double> worst() const {
    if (slot_max_.empty()) return {kNone, 0.0};
    std::size_t at = kNone;
    double e = -1;
    for (const std::uint32_t i : by_slot_[slot_max_.front().slot]) {
      if (err_[i] > e) e = err_[i], at = i;
    }
    return {at, e};
  }

  // Whether candidate j is a vertex now.
  bool is_vertex(std::size_t j) const { return state_[j] == kVertex; }
  // Candidate j becomes a vertex (kVertex) or a point to locate (kLocate), and vertices_ follows.
  void set_vertex(std::size_t j, bool vertex) {
    const auto c = static_cast<std::uint32_t>(j);
    const auto at = std::lower_bound(vertices_.begin(), vertices_.end(), c);
    if (vertex) {
      state_[j] = kVertex;
      if (at == vertices_.end() || *at != c) vertices_.insert(at, c);
    } else {
      state_[j] = kLocate;
      if (at != vertices_.end() && *at == c) vertices_.erase(at);
    }
  }
  void touch(std::size_t j) {
    for (const auto& t : touched_) {
      if (t.first == j) return;
    }
    touched_.emplace_back(j, is_vertex(j));
  }

  // Candidate j in; false when the kernel takes it for a duplicate of a vertex (a candidate at
  // exactly the position of another point: thin_tile counts it as a duplicate).
  bool insert(std::size_t j) {
    touch(j);
    const tile::Vertex& p = in_.candidates[j];
    const kernel::InsertResult r = tri_.insert({p.x, p.y, p.z, p.weight});
    if (r.outcome != kernel::InsertOutcome::inserted) return false;
    (*in_.candidate_vertex)[j] = r.vertex;
    set_vertex(j, true);
    refile();
    return true;
  }
  Status remove(std::size_t j) {
    touch(j);
    if (Status s = tri_.remove_vertex((*in_.candidate_vertex)[j]); !s) return s;
    (*in_.candidate_vertex)[j] = kNone;
    set_vertex(j, false);
    pending_.push_back(static_cast<std::uint32_t>(j));
    refile();
    return {};
  }

  // The k points of largest error in (one at a time, each against the surface with the ones
  // before), then k vertices out, each the one whose removal leaves the smallest largest error.
  // false: it could not (a point of largest error that is not a candidate or is a duplicate,
  // nothing removable).
  Result<bool> exchange(std::size_t k, std::size_t* work) {
    for (std::size_t n = 0; n < k; ++n) {
      const auto [at, e] = worst();
      if (at == kNone || at >= in_.candidates.size() || !(e > 0) || !insert(at)) return false;
    }
    for (std::size_t n = 0; n < k; ++n) {
      ++*work;
      double best = std::numeric_limits<double>::infinity();
      std::size_t out = kNone;
      for (const std::uint32_t j : vertices_) {  // (in candidate order, as a scan of state_)
        if (const auto e = removal_error((*in_.candidate_vertex)[j], best)) best = *e, out = j;
      }
      if (out == kNone) return false;
      if (Status s = remove(out); !s) return s.error();
    }
    return true;
  }

  // Undoes the last exchange: the points it put in go out, the vertices it took out go back.
  Status revert() {
    for (const auto& [j, was] : touched_) {
      if (!was && is_vertex(j)) {
        if (Status s = tri_.remove_vertex((*in_.candidate_vertex)[j]); !s) return s;
        (*in_.candidate_vertex)[j] = kNone;
        set_vertex(j, false);
        pending_.push_back(static_cast<std::uint32_t>(j));
      }
    }
    for (const auto& [j, was] : touched_) {
      if (was && !is_vertex(j)) {
        const tile::Vertex& p = in_.candidates[j];
        const kernel::InsertResult r = tri_.insert({p.x, p.y, p.z, p.weight});
        if (r.outcome != kernel::InsertOutcome::inserted) {
          return Error(ErrorCode::internal, "lod: exchange step: a vertex could not go back");
        }
        (*in_.candidate_vertex)[j] = r.vertex;
        set_vertex(j, true);
      }
    }
    touched_.clear();
    refile();
    return {};
  }

  enum State : std::uint8_t { kFiled, kVertex, kOutside, kLocate };

  bool is_nodata(VertexId v) const {
    return std::find(in_.nodata_corners.begin(), in_.nodata_corners.end(), v) !=
           in_.nodata_corners.end();
  }

  // Files every point again whose slot changed since the last call, and the points that stopped
  // being vertices (pending_); then orders the slots by their largest error.
  void refile() {
    const kernel::Mesh& m = tri_.mesh();
    const std::size_t slots = m.triangle_slots();
    if (cache_.size() < slots) {
      cache_.resize(slots, kDead);
      planes_.resize(slots, Plane(XY{0, 0}, XY{1, 0}, XY{0, 1}, 0, 0, 0));
      by_slot_.resize(slots);
      max_of_.resize(slots, -1.0);
    }
    moving_.swap(pending_);
    pending_.clear();
    for (TriangleId t = 0; t < slots; ++t) {
      const VertexTriple now = m.is_live(t) && !m.is_ghost(t)
                                   ? VertexTriple{m.tri(t).v[0], m.tri(t).v[1], m.tri(t).v[2]}
                                   : kDead;
      if (now == cache_[t]) continue;
      cache_[t] = now;
      if (now != kDead) {
        planes_[t] = Plane(tri_.xy(now[0]), tri_.xy(now[1]), tri_.xy(now[2]), tri_.z(now[0]),
                           tri_.z(now[1]), tri_.z(now[2]));
      }
      moving_.insert(moving_.end(), by_slot_[t].begin(), by_slot_[t].end());
      by_slot_[t].clear();
      max_of_[t] = -1.0;
    }
    for (const std::uint32_t i : moving_) {
      if (state_[i] == kVertex) continue;  // it went in: its slot changed
      const TriangleId t = tri_.locate_triangle(x_[i], y_[i]);
      if (t == kNone) {
        state_[i] = kOutside;
        continue;
      }
      state_[i] = kFiled;
      double w;
      err_[i] = std::abs(z_[i] - planes_[t].at(x_[i], y_[i], &w));
      by_slot_[t].push_back(i);
      max_of_[t] = std::max(max_of_[t], err_[i]);
    }
    moving_.clear();
    slot_max_.clear();
    for (TriangleId t = 0; t < slots; ++t) {
      if (max_of_[t] >= 0) slot_max_.push_back({max_of_[t], t});
    }
    std::sort(slot_max_.begin(), slot_max_.end(), [](const SlotMax& a, const SlotMax& b) {
      return a.error > b.error || (a.error == b.error && a.slot < b.slot);
    });
  }

  // The largest error over all points once v is removed, when it is below `bound` and v's removal
  // uncovers no point (coverage); else nullopt.
  std::optional<double> removal_error(VertexId v, double bound) const {
    auto preview = tri_.removal_preview(v);
    if (!preview.ok() || preview->empty()) return std::nullopt;
    const std::vector<TriangleId> star = tri_.incident_triangles(v);
    double err = 0;  // the largest error outside v's star
    for (const SlotMax& s : slot_max_) {
      if (std::find(star.begin(), star.end(), s.slot) == star.end()) {
        err = s.error;
        break;
      }
    }
    if (!(err < bound)) return std::nullopt;
    bool check_coverage = false;
    for (const VertexId w : tri_.adjacent_vertices(v)) check_coverage |= is_nodata(w);
    std::vector<Plane> planes;
    planes.reserve(preview->size());
    for (const auto& t : *preview) {
      planes.emplace_back(tri_.xy(t[0]), tri_.xy(t[1]), tri_.xy(t[2]), tri_.z(t[0]), tri_.z(t[1]),
                          tri_.z(t[2]));
    }
    // Error at (x, y, z) against the preview; false when it ends up uncovered or at the bound.
    // (The first plane that contains (x, y) by Plane::contains — the same weights and height as
    // at(), stopping at the first negative weight —, else the first of largest smallest weight.)
    auto judge = [&](double x, double y, double z) {
      double best_w = -1e300, zs = 0;
      std::size_t which = 0;
      bool found = false;
      for (std::size_t k = 0; k < planes.size() && !found; ++k) {
        found = planes[k].contains(x, y, &zs);
        which = k;
      }
      for (std::size_t k = 0; k < planes.size() && !found; ++k) {
        double w;
        const double at = planes[k].at(x, y, &w);
        if (w > best_w) best_w = w, zs = at, which = k;
      }
      err = std::max(err, std::abs(z - zs));
      if (!(err < bound)) return false;
      return !(check_coverage &&
               uncovered(tri_, (*preview)[which], in_.nodata_corners, in_.outline_tolerance, x, y));
    };
    const XY& pv = tri_.xy(v);
    if (!judge(pv.x, pv.y, tri_.z(v))) return std::nullopt;
    for (const TriangleId t : star) {
      for (const std::uint32_t i : by_slot_[t]) {
        if (!judge(x_[i], y_[i], z_[i])) return std::nullopt;
      }
    }
    return err;
  }

  struct SlotMax {
    double error;
    TriangleId slot;
  };

  kernel::Triangulation& tri_;
  const ExchangeInput& in_;
  std::vector<double> x_, y_, z_;  // candidates first, then the others
  std::vector<std::uint8_t> state_;
  // The candidates that are vertices (state_ kVertex), ascending: exchange() tries their removal
  // without scanning state_ (every candidate of the tile: ~800k at Big Tujunga's level 5).
  std::vector<std::uint32_t> vertices_;
  std::vector<double> err_;
  std::vector<VertexTriple> cache_;  // by slot: its triangle when last filed (kDead: none)
  std::vector<Plane> planes_;        // by slot: its plane (valid where cache_ is live)
  std::vector<std::vector<std::uint32_t>> by_slot_;    // the filed points, by slot
  std::vector<double> max_of_;                         // by slot: their largest error (-1: none)
  std::vector<std::uint32_t> pending_, moving_;        // points to locate (refile)
  std::vector<SlotMax> slot_max_;                      // non-empty slots, the largest error first
  std::vector<std::pair<std::size_t, bool>> touched_;  // the exchange's candidates: were vertices
};

}  // namespace

Result<ExchangeResult> exchange_steps(kernel::Triangulation& tri, const ExchangeInput& in,
                                      std::size_t max_steps) {
  return Exchanger(tri, in).run(max_steps);
}

}  // namespace tinstream::lod::detail
