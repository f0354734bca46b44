// Raster-DEM tiles from a TIN tile: each triangle is scanned over the pixel centres of its
// bounding box, each centre claimed by the first triangle that contains it (exact orientation
// tests), so the work is O(pixels + triangles) and every centre is decided exactly.
#include "tinstream/terrain/raster_dem.hpp"

#include <algorithm>
#include <cmath>

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::terrain {

namespace {

struct Encoding {
  double offset;  // h + offset ≥ 0 over the range
  double scale;   // counts per metre
};

constexpr Encoding encoding_of(DemEncoding e) {
  return e == DemEncoding::terrarium ? Encoding{32768.0, 256.0} : Encoding{10000.0, 10.0};
}

// The interpolation weights of p in triangle (a, b, c), CCW: barycentric coordinates computed
// relative to a (small differences, so little cancellation).
std::array<double, 3> barycentric(const tile::Vertex& a, const tile::Vertex& b,
                                  const tile::Vertex& c, double px, double py) {
  const double bx = b.x - a.x, by = b.y - a.y, cx = c.x - a.x, cy = c.y - a.y;
  const double qx = px - a.x, qy = py - a.y;
  const double det = bx * cy - by * cx;
  if (!(det != 0)) return {1.0 / 3, 1.0 / 3, 1.0 / 3};  // degenerate: cannot happen in a valid tile
  const double wb = (qx * cy - qy * cx) / det;
  const double wc = (bx * qy - by * qx) / det;
  return {1.0 - wb - wc, wb, wc};
}

// The height at a pixel centre of a NODATA triangle. A NODATA corner whose height lies within the
// tile's data range carries a height continued from the data (docs/tile-format.md §2.1): the
// triangle's own plane then holds, as CesiumJS draws it from the quantized-mesh, with no crease
// inside the triangle (a renormalised interpolation over the data vertices alone curves, and
// hillshading showed its creases as ridges). A corner outside that range (tiles written when
// NODATA corners sat at height 0) is left out and the weights of the others renormalised, so no
// wall comes back; their mean when those weights vanish, the tile's lowest height when nothing
// is left.
double nodata_height(const tile::TinTile& t, const tile::Triangle& tri,
                     const std::array<const tile::Vertex*, 3>& v, const std::array<double, 3>& w) {
  double sum = 0, weight = 0, plain = 0;
  int count = 0;
  for (std::size_t k = 0; k < 3; ++k) {
    const bool continued = v[k]->z >= t.min_z && v[k]->z <= t.max_z;
    if (t.is_nodata_vertex(tri[k]) && !continued) continue;
    const double wk = std::max(0.0, w[k]);
    sum += wk * v[k]->z;
    weight += wk;
    plain += v[k]->z;
    ++count;
  }
  if (count == 3) return w[0] * v[0]->z + w[1] * v[1]->z + w[2] * v[2]->z;
  if (count == 0) return t.min_z;
  return weight > 0 ? sum / weight : plain / count;
}

}  // namespace

std::string_view to_string(DemEncoding e) {
  return e == DemEncoding::terrarium ? "terrarium" : "mapbox";
}

Result<DemEncoding> parse_dem_encoding(std::string_view text) {
  if (text == "terrarium") return DemEncoding::terrarium;
  if (text == "mapbox") return DemEncoding::mapbox;
  return invalid_argument("raster-DEM encoding '" + std::string(text) +
                          "' is not terrarium or mapbox");
}

std::string_view to_string(DemNodata n) {
  return n == DemNodata::opaque ? "opaque" : "transparent";
}

Result<DemNodata> parse_dem_nodata(std::string_view text) {
  if (text == "opaque") return DemNodata::opaque;
  if (text == "transparent") return DemNodata::transparent;
  return invalid_argument("raster-DEM nodata '" + std::string(text) +
                          "' is not opaque or transparent");
}

double dem_step(DemEncoding e) { return 1.0 / encoding_of(e).scale; }

std::array<std::uint8_t, 3> encode_dem_height(DemEncoding e, double height) {
  const Encoding enc = encoding_of(e);
  double counts = std::nearbyint((height + enc.offset) * enc.scale);
  if (!(counts >= 0)) counts = 0;  // NaN too
  counts = std::min(counts, 16777215.0);
  const auto n = static_cast<std::uint32_t>(counts);
  return {static_cast<std::uint8_t>(n >> 16), static_cast<std::uint8_t>((n >> 8) & 0xFF),
          static_cast<std::uint8_t>(n & 0xFF)};
}

double decode_dem_height(DemEncoding e, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  const Encoding enc = encoding_of(e);
  const double counts = r * 65536.0 + g * 256.0 + b;
  return counts / enc.scale - enc.offset;
}

Result<DemRaster> render_raster_dem(const tile::TinTile& t, DemEncoding encoding,
                                    std::uint32_t size, DemNodata nodata_mode) {
  if (size < 1 || size > 4096) {
    return invalid_argument("raster-DEM size " + std::to_string(size) + " is outside 1–4096");
  }
  const geo::MercatorRect r = t.id.bounds();
  const double dx = r.width() / size, dy = r.height() / size;
  const std::vector<tile::Vertex> vertices = t.vertices();
  for (const tile::Vertex& v : vertices) {
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
      return corrupt_data("tile " + t.id.to_string() + ": a vertex is not finite");
    }
  }
  // Pixel visits over all triangles' bounding boxes: a valid tile needs a few times the pixel
  // count (long border fans included); a corrupt one of overlapping whole-tile triangles is cut
  // off here instead of costing triangles × pixels.
  const std::uint64_t visit_budget = 256ull * size * size;
  std::uint64_t visits = 0;
  std::vector<double> height(static_cast<std::size_t>(size) * size, 0.0);
  // 0: not yet claimed, 1: data, 2: NODATA.
  std::vector<std::uint8_t> state(height.size(), 0);
  const auto column_of = [&](double x) { return (x - r.min_x) / dx - 0.5; };
  const auto row_of = [&](double y) { return (r.max_y - y) / dy - 0.5; };
  const auto clamp_index = [&](double v) {
    return static_cast<std::int64_t>(std::clamp(v, -1.0, static_cast<double>(size)));
  };

  for (std::size_t ti = 0; ti < t.triangles.size(); ++ti) {
    const tile::Triangle& tri = t.triangles[ti];
    if (tri[0] >= vertices.size() || tri[1] >= vertices.size() || tri[2] >= vertices.size()) {
      return corrupt_data("tile " + t.id.to_string() + ": a triangle index is out of range");
    }
    const std::array<const tile::Vertex*, 3> v = {&vertices[tri[0]], &vertices[tri[1]],
                                                  &vertices[tri[2]]};
    const double min_x = std::min({v[0]->x, v[1]->x, v[2]->x});
    const double max_x = std::max({v[0]->x, v[1]->x, v[2]->x});
    const double min_y = std::min({v[0]->y, v[1]->y, v[2]->y});
    const double max_y = std::max({v[0]->y, v[1]->y, v[2]->y});
    // One pixel of slack on each side: the exact tests below decide.
    const std::int64_t i0 = std::max<std::int64_t>(0, clamp_index(std::floor(column_of(min_x))));
    const std::int64_t i1 =
        std::min<std::int64_t>(size - 1, clamp_index(std::ceil(column_of(max_x))));
    const std::int64_t j0 = std::max<std::int64_t>(0, clamp_index(std::floor(row_of(max_y))));
    const std::int64_t j1 = std::min<std::int64_t>(size - 1, clamp_index(std::ceil(row_of(min_y))));
    const kernel::XY a{v[0]->x, v[0]->y}, b{v[1]->x, v[1]->y}, c{v[2]->x, v[2]->y};
    const bool nodata = t.is_nodata_triangle(ti);
    if (j1 >= j0 && i1 >= i0) {
      visits += static_cast<std::uint64_t>(j1 - j0 + 1) * static_cast<std::uint64_t>(i1 - i0 + 1);
    }
    if (visits > visit_budget) {
      return corrupt_data("tile " + t.id.to_string() +
                          ": its triangles overlap (they cover the raster hundreds of times)");
    }
    for (std::int64_t j = j0; j <= j1; ++j) {
      const double py = r.max_y - (static_cast<double>(j) + 0.5) * dy;
      for (std::int64_t i = i0; i <= i1; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * size + static_cast<std::size_t>(i);
        if (state[k] != 0) continue;
        const double px = r.min_x + (static_cast<double>(i) + 0.5) * dx;
        const kernel::XY p{px, py};
        if (kernel::orient2d(a, b, p) < 0 || kernel::orient2d(b, c, p) < 0 ||
            kernel::orient2d(c, a, p) < 0) {
          continue;
        }
        const auto w = barycentric(*v[0], *v[1], *v[2], px, py);
        height[k] =
            nodata ? nodata_height(t, tri, v, w) : w[0] * v[0]->z + w[1] * v[1]->z + w[2] * v[2]->z;
        state[k] = nodata ? 2 : 1;
      }
    }
  }

  DemRaster out;
  out.size = size;
  out.rgba.resize(height.size() * 4);
  for (std::size_t k = 0; k < height.size(); ++k) {
    if (state[k] == 0) {
      return corrupt_data("tile " + t.id.to_string() + ": no triangle covers pixel " +
                          std::to_string(k % size) + "," + std::to_string(k / size));
    }
    const auto rgb = encode_dem_height(encoding, height[k]);
    std::copy(rgb.begin(), rgb.end(), out.rgba.begin() + static_cast<std::ptrdiff_t>(k * 4));
    out.rgba[k * 4 + 3] = state[k] == 2 && nodata_mode == DemNodata::transparent ? 0 : 255;
    out.nodata_pixels += state[k] == 2 ? 1 : 0;
  }
  return out;
}

}  // namespace tinstream::terrain
