#include "lattice.hpp"

#include "tinstream/kernel/mesh.hpp"

namespace tinstream::lod::detail {

std::optional<Lattice> find_lattice(std::span<const tile::Vertex> points) {
  if (points.empty()) return std::nullopt;
  double min_x = std::numeric_limits<double>::infinity(), min_y = min_x;
  for (const auto& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return std::nullopt;
    min_x = std::min(min_x, p.x), min_y = std::min(min_y, p.y);
  }
  // The lowest row gives the columns, the leftmost column the rows.
  Lattice l;
  bool weighted = false;
  for (const auto& p : points) {
    if (p.y == min_y) l.xs.push_back(p.x);
    if (p.x == min_x) l.ys.push_back(p.y);
    weighted = weighted || p.weight != 0;
  }
  std::sort(l.xs.begin(), l.xs.end());
  std::sort(l.ys.begin(), l.ys.end());
  if (std::adjacent_find(l.xs.begin(), l.xs.end()) != l.xs.end() ||
      std::adjacent_find(l.ys.begin(), l.ys.end()) != l.ys.end()) {
    return std::nullopt;
  }
  const std::size_t w = l.xs.size(), h = l.ys.size();
  if (w * h != points.size() || points.size() >= kernel::kNone) return std::nullopt;
  l.finish();
  l.point.assign(points.size(), kernel::kNone);
  l.z.resize(points.size());
  if (weighted) l.weight.resize(points.size());
  // (Gridded input usually comes row by row: the cell after the previous one is tried first.)
  std::size_t i = w, j = h;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto& p = points[k];
    if (i + 1 < w && j < h && l.xs[i + 1] == p.x && l.ys[j] == p.y) {
      ++i;
    } else {
      i = l.first_column_at_or_after(p.x);
      j = l.first_row_at_or_after(p.y);
    }
    if (i == w || j == h || l.xs[i] != p.x || l.ys[j] != p.y) return std::nullopt;
    const std::size_t cell = j * w + i;
    if (l.point[cell] != kernel::kNone) return std::nullopt;  // a duplicate (then one is missing)
    l.point[cell] = static_cast<std::uint32_t>(k);
    l.z[cell] = p.z;
    if (weighted) l.weight[cell] = p.weight;
  }
  return l;
}

}  // namespace tinstream::lod::detail
