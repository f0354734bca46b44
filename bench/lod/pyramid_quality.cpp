// bench/lod: what a stored pyramid says at the data's edge and how good its levels are (#20).
// Not a test: a measurement over a real store, level by level, the way a client sees the tiles.
//
//   pyramid_quality STORE LAYER [--tiles]
//
// For every level: the recorded geometric error (the level's largest) against the error
// *measured* at the finest level's data — every vertex of a finest data triangle (for a DEM or
// LiDAR ingested without --epsilon: the input points, plus the edge points and corners on the
// data) located in the level's tile above it and compared with that tile's surface (any of its
// triangles, NODATA ones included: what Cesium draws), once in doubles and once through the tile's
// quantized-mesh encoding as CesiumJS interpolates it (QuantizedMeshTerrainData.interpolateHeight:
// the triangle holding the point in quantised (u, v), barycentric weights, the quantised height
// scaled by the header's range). It also counts what issue #20 found: tile vertices below the
// data's lowest height (walls), quantized-mesh height ranges that start below the data, pairs of
// a tile's vertices closer than 1e-12, and zero-area triangles and repeated (u, v) positions in the
// quantized-mesh encoding (decoded with the tests' independent decoder), and the finest data points
// that fall outside a tile's data footprint (under its NODATA fans: what a client drawing the
// footprint only does not show), with how many of them lie farther than one quantized-mesh step
// (the tile's width / 32767: the thinning's outline tolerance) from the footprint and the farthest
// in steps. --tiles adds one line per
// tile. Everything is evaluated by code of this file and the independent decoder, not by the
// library's error bookkeeping.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "../../core/terrain/tests/qm_decoder.hpp"
#include "store_data.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/terrain/quantized_mesh.hpp"

namespace {

using tinstream::bench::finest_data;
using tinstream::bench::FinestData;
using tinstream::bench::Locator;
using tinstream::bench::Point3;
using tinstream::bench::tile_locator;
using tinstream::geo::TileId;
using tinstream::tile::TinTile;

// The tile as CesiumJS reconstructs it from the quantized mesh: (u, v) in 0…32767, heights from
// the header's range; lookups in the same quantised (u, v) space.
struct QmView {
  tinstream::testing::DecodedMesh mesh;
  tinstream::geo::LonLatRect rect{};
  std::optional<Locator> locator;
  std::size_t zero_area = 0, repeated_uv = 0;
};

QmView qm_view(const TinTile& t, const tinstream::geo::NormalisedMercator& merc) {
  QmView q;
  auto bytes = tinstream::terrain::encode_quantized_mesh(t, tinstream::geo::Projection::spherical);
  if (!bytes) {
    std::fprintf(stderr, "quantized-mesh of %s: %s\n", t.id.to_string().c_str(),
                 bytes.error().message.c_str());
    std::exit(1);
  }
  q.mesh = tinstream::testing::decode_quantized_mesh(*bytes);
  q.rect = t.id.lonlat_bounds(merc);
  std::vector<Point3> p;
  const double lo = q.mesh.min_height, hi = q.mesh.max_height;
  for (std::size_t i = 0; i < q.mesh.u.size(); ++i) {
    p.push_back({double(q.mesh.u[i]), double(q.mesh.v[i]), lo + (hi - lo) * q.mesh.h[i] / 32767.0});
  }
  std::vector<std::array<std::uint32_t, 3>> tris;
  for (std::size_t k = 0; k + 2 < q.mesh.indices.size(); k += 3) {
    const auto a = q.mesh.indices[k], b = q.mesh.indices[k + 1], c = q.mesh.indices[k + 2];
    const long long area = (long long)(p[b].x - p[a].x) * (long long)(p[c].y - p[a].y) -
                           (long long)(p[b].y - p[a].y) * (long long)(p[c].x - p[a].x);
    if (area == 0) ++q.zero_area;
    tris.push_back({a, b, c});
  }
  std::map<std::pair<int, int>, int> uv;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (++uv[{int(p[i].x), int(p[i].y)}] == 2) ++q.repeated_uv;
  }
  q.locator.emplace(std::move(p), std::move(tris));
  return q;
}

double qm_height(const QmView& q, const tinstream::geo::NormalisedMercator& merc, double x,
                 double y) {
  const double lon = tinstream::geo::NormalisedMercator::lon_from_x(x), lat = merc.lat_from_y(y);
  const double u = (lon - q.rect.west) / (q.rect.east - q.rect.west) * 32767.0;
  const double v = (lat - q.rect.south) / (q.rect.north - q.rect.south) * 32767.0;
  double w;
  return q.locator->height(u, v, &w);
}

std::size_t close_pairs(const TinTile& t, double limit) {
  auto v = t.vertices();
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.x < b.x; });
  std::size_t n = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    for (std::size_t j = i + 1; j < v.size() && v[j].x - v[i].x < limit; ++j) {
      if (std::hypot(v[j].x - v[i].x, v[j].y - v[i].y) < limit) ++n;
    }
  }
  return n;
}

// The distance from (x, y) to the nearest data triangle of `t` (data[k] set), normalised units;
// infinity when it has none. Used for the few points outside the footprint only (brute force).
double footprint_distance(const TinTile& t, const std::vector<bool>& data, double x, double y) {
  auto segment = [&](const auto& a, const auto& b) {
    const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
    const double s =
        len2 > 0 ? std::clamp(((x - a.x) * dx + (y - a.y) * dy) / len2, 0.0, 1.0) : 0.0;
    return std::hypot(x - (a.x + s * dx), y - (a.y + s * dy));
  };
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < t.triangles.size(); ++k) {
    if (!data[k]) continue;
    const auto &a = t.vertex(t.triangles[k][0]), &b = t.vertex(t.triangles[k][1]),
               &c = t.vertex(t.triangles[k][2]);
    best = std::min({best, segment(a, b), segment(b, c), segment(c, a)});
  }
  return best;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  const double n = static_cast<double>(v.size());
  const auto k = static_cast<std::size_t>(std::min(n - 1, p * n));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s STORE LAYER [--tiles]\n", argv[0]);
    return 2;
  }
  const bool per_tile = argc > 3 && std::strcmp(argv[3], "--tiles") == 0;
  auto store =
      tinstream::store::TileStore::open(argv[1], tinstream::store::TileStore::Mode::read_only);
  if (!store) return std::fprintf(stderr, "%s\n", store.error().message.c_str()), 1;
  auto info = store->layer(argv[2]);
  if (!info) return std::fprintf(stderr, "%s\n", info.error().message.c_str()), 1;
  const tinstream::geo::NormalisedMercator merc(info->projection);
  const bool spherical = info->projection == tinstream::geo::Projection::spherical;
  auto read = [&](const TileId& id) {
    auto t = store->read_tile(argv[2], id);
    if (!t || !*t) {
      std::fprintf(stderr, "cannot read %s\n", id.to_string().c_str());
      std::exit(1);
    }
    return std::move(**t);
  };

  // The finest level's data: the vertices of its data triangles, by finest tile.
  const std::uint32_t finest = info->max_level;
  const FinestData fd = finest_data(*store, argv[2], finest);
  const auto& data = fd.points;
  const double data_lo = fd.lo, data_hi = fd.hi;
  const std::size_t finest_tiles = data.size();
  std::printf("%s layer %s: finest level %u, %zu finest tiles, data heights %.3f … %.3f m\n",
              argv[1], argv[2], finest, finest_tiles, data_lo, data_hi);
  std::printf(
      "| level | tiles | vertices/tile | recorded max (m) | measured max (m) | recorded / measured "
      "| "
      "per-tile ratio min–max | lowest vertex (m) | QM lowest height (m) | Cesium max (m) | "
      "Cesium p99 (m) | tiles with pairs < 1e-12 | QM zero-area triangles | QM repeated (u,v) | "
      "data points outside the footprint | of those beyond a QM step | farthest (QM steps) |\n");
  std::printf(
      "|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (std::uint32_t z = finest + 1; z-- > info->min_level;) {
    auto ids = store->tile_ids(argv[2], z);
    double recorded = 0, measured = 0, lowest = std::numeric_limits<double>::infinity();
    double qm_lowest = lowest, ratio_lo = lowest, ratio_hi = 0, cesium_max = 0;
    std::vector<double> cesium_errors;
    std::size_t vertices = 0, pair_tiles = 0, zero_area = 0, repeated = 0, uncovered = 0;
    std::size_t beyond_step = 0;
    double farthest = 0;
    for (const auto& id : *ids) {
      const TinTile t = read(id);
      vertices += t.vertex_count();
      recorded = std::max(recorded, t.geometric_error);
      for (const auto& v : t.vertices()) lowest = std::min(lowest, v.z);
      if (close_pairs(t, 1e-12) > 0) ++pair_tiles;
      const Locator here = tile_locator(t);
      const auto footprint = t.footprint_mask();
      const std::vector<bool> data_triangle(footprint.begin(), footprint.end());
      std::optional<QmView> qm;
      if (spherical) {
        qm = qm_view(t, merc);
        qm_lowest = std::min<double>(qm_lowest, qm->mesh.min_height);
        zero_area += qm->zero_area, repeated += qm->repeated_uv;
      }
      double tile_measured = 0;
      const std::uint32_t shift = finest - z;
      for (const auto& [fid, pts] : data) {
        if ((fid.x >> shift) != id.x || (fid.y >> shift) != id.y) continue;
        for (const Point3& p : pts) {
          double w;
          const double h = here.height(p.x, p.y, &w);
          tile_measured = std::max(tile_measured, std::abs(h - p.z));
          if (!here.covered(p.x, p.y, data_triangle)) {
            ++uncovered;
            // One quantized-mesh step of this tile (its width / 32767): what a client can show.
            const double steps =
                footprint_distance(t, data_triangle, p.x, p.y) / (id.bounds().width() / 32767.0);
            if (steps > 1) ++beyond_step;
            farthest = std::max(farthest, steps);
          }
          if (qm) {
            const double e = std::abs(qm_height(*qm, merc, p.x, p.y) - p.z);
            cesium_errors.push_back(e);
            cesium_max = std::max(cesium_max, e);
          }
        }
      }
      measured = std::max(measured, tile_measured);
      if (z < finest && tile_measured > 0) {
        const double r = t.geometric_error / tile_measured;
        ratio_lo = std::min(ratio_lo, r), ratio_hi = std::max(ratio_hi, r);
      }
      if (per_tile) {
        std::printf(
            "  tile %s: %zu vertices, recorded %.4f m, measured %.4f m, nodata corners %d%d%d%d\n",
            id.to_string().c_str(), t.vertex_count(), t.geometric_error, tile_measured,
            t.corner_nodata[0], t.corner_nodata[1], t.corner_nodata[2], t.corner_nodata[3]);
      }
    }
    char ratios[64] = "—";
    if (ratio_hi > 0) std::snprintf(ratios, sizeof ratios, "%.2f–%.2f", ratio_lo, ratio_hi);
    std::printf(
        "| %u | %zu | %.0f | %.4f | %.4f | %s | %s | %.3f | %.3f | %.4f | %.4f | %zu | %zu | %zu "
        "| %zu | %zu | %.2f |\n",
        z, ids->size(), double(vertices) / double(ids->size()), recorded, measured,
        z < finest && measured > 0 ? std::to_string(recorded / measured).substr(0, 5).c_str() : "—",
        ratios, lowest, qm_lowest, cesium_max, percentile(cesium_errors, 0.99), pair_tiles,
        zero_area, repeated, uncovered, beyond_step, farthest);
    std::fflush(stdout);
  }
  return 0;
}
