// bench/lod: our thinning (Lee's drop heuristic, core/lod) against greedy insertion (Delatin,
// Garland–Heckbert style) on a real DEM, at equal vertex counts: max and RMS vertical error over
// every grid cell, and time. Not a test. Driven by run.sh:
//
//   lod_vs_greedy dump    <dem.tif> <grid.f32>              writes the heights, prints "W H"
//   lod_vs_greedy compare <dem.tif> <dir> <N,N,...>          reads <dir>/delatin_<N>.txt and
//                                                            <dir>/delatin_times.txt, prints a
//                                                            table
//
// The grid is used in its own (metric) coordinates: pixel centres, no reprojection. Both meshes
// are evaluated by the same code here (linear interpolation in the containing triangle at every
// grid cell), so the comparison does not depend on either library's own error bookkeeping.
#include <gdal_priv.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "grid_input.hpp"
#include "tinstream/lod/thinning.hpp"

namespace {

struct Grid {
  int w = 0, h = 0;
  double gt[6]{};
  std::vector<float> z;
  double x(int col) const { return gt[0] + (col + 0.5) * gt[1]; }
  double y(int row) const { return gt[3] + (row + 0.5) * gt[5]; }
  float at(int col, int row) const {
    return z[static_cast<std::size_t>(row) * static_cast<std::size_t>(w) +
             static_cast<std::size_t>(col)];
  }
};

bool read_grid(const char* path, Grid& g) {
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path, GA_ReadOnly));
  if (!ds) {
    std::fprintf(stderr, "cannot open %s\n", path);
    return false;
  }
  g.w = ds->GetRasterXSize();
  g.h = ds->GetRasterYSize();
  ds->GetGeoTransform(g.gt);
  GDALRasterBand* b = ds->GetRasterBand(1);
  g.z.resize(static_cast<std::size_t>(g.w) * static_cast<std::size_t>(g.h));
  const CPLErr e = b->RasterIO(GF_Read, 0, 0, g.w, g.h, g.z.data(), g.w, g.h, GDT_Float32, 0, 0);
  int has_nodata = 0;
  const double nodata = b->GetNoDataValue(&has_nodata);
  GDALClose(ds);
  if (e != CE_None) return false;
  std::size_t bad = 0;
  for (float v : g.z)
    bad += (!std::isfinite(v) || (has_nodata && v == static_cast<float>(nodata))) ? 1 : 0;
  if (bad) {
    std::fprintf(stderr, "%s has %zu NODATA cells; this benchmark needs a full grid\n", path, bad);
    return false;
  }
  return true;
}

// A mesh in pixel coordinates (col, row) with vertex heights taken from the grid.
struct PixelMesh {
  std::vector<int> col, row;
  std::vector<std::array<std::uint32_t, 3>> tris;
};

struct Errors {
  double max = 0, rms = 0;
  std::size_t cells = 0;
  double border_max = 0;  // over the grid's outer rows and columns
};

// Max and RMS of |mesh − grid| over every grid cell (each cell counted once).
Errors evaluate(const Grid& g, const PixelMesh& m) {
  std::vector<std::uint8_t> seen(g.z.size(), 0);
  double sum = 0, worst = 0, border_worst = 0;
  std::size_t n = 0;
  for (const auto& t : m.tris) {
    const double ax = m.col[t[0]], ay = m.row[t[0]], bx = m.col[t[1]], by = m.row[t[1]],
                 cx = m.col[t[2]], cy = m.row[t[2]];
    const double za = g.at(m.col[t[0]], m.row[t[0]]), zb = g.at(m.col[t[1]], m.row[t[1]]),
                 zc = g.at(m.col[t[2]], m.row[t[2]]);
    const double det = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if (det == 0) continue;
    const int x0 = static_cast<int>(std::min({ax, bx, cx})),
              x1 = static_cast<int>(std::max({ax, bx, cx}));
    const int y0 = static_cast<int>(std::min({ay, by, cy})),
              y1 = static_cast<int>(std::max({ay, by, cy}));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double wa = ((bx - x) * (cy - y) - (by - y) * (cx - x)) / det;
        const double wb = ((cx - x) * (ay - y) - (cy - y) * (ax - x)) / det;
        const double wc = 1.0 - wa - wb;
        if (wa < -1e-12 || wb < -1e-12 || wc < -1e-12) continue;
        const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(g.w) +
                              static_cast<std::size_t>(x);
        if (seen[k]) continue;
        seen[k] = 1;
        const double d = std::abs(wa * za + wb * zb + wc * zc - g.z[k]);
        worst = std::max(worst, d);
        if (x == 0 || y == 0 || x == g.w - 1 || y == g.h - 1)
          border_worst = std::max(border_worst, d);
        sum += d * d;
        ++n;
      }
    }
  }
  Errors e;
  e.max = worst;
  e.rms = n ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  e.cells = n;
  e.border_max = border_worst;
  if (n != g.z.size())
    std::fprintf(stderr, "warning: mesh covers %zu of %zu cells\n", n, g.z.size());
  return e;
}

tinstream::lod::ThinInput grid_input(const Grid& g) {
  return tinstream::bench::grid_thin_input(g.w, g.h, [&](int c, int r) {
    return tinstream::tile::Vertex{g.x(c), g.y(r), g.at(c, r), 0.0};
  });
}

PixelMesh to_pixels(const Grid& g, const tinstream::tile::TinTile& t) {
  PixelMesh m;
  for (const auto& p : t.vertices()) {
    m.col.push_back(static_cast<int>(std::lround((p.x - g.x(0)) / g.gt[1])));
    m.row.push_back(static_cast<int>(std::lround((p.y - g.y(0)) / g.gt[5])));
  }
  for (const auto& tr : t.triangles) m.tris.push_back({tr[0], tr[1], tr[2]});
  return m;
}

bool read_delatin(const std::string& path, PixelMesh& m) {
  std::ifstream f(path);
  std::size_t nv = 0, nt = 0;
  if (!(f >> nv >> nt)) return false;
  m.col.resize(nv), m.row.resize(nv), m.tris.resize(nt);
  for (std::size_t i = 0; i < nv; ++i) f >> m.col[i] >> m.row[i];
  for (std::size_t i = 0; i < nt; ++i) f >> m.tris[i][0] >> m.tris[i][1] >> m.tris[i][2];
  return static_cast<bool>(f);
}

std::vector<std::size_t> parse_counts(const std::string& s) {
  std::vector<std::size_t> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stoul(item));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s dump <dem> <grid.f32> | compare <dem> <dir> <N,N,...>\n",
                 argv[0]);
    return 2;
  }
  const std::string mode = argv[1];
  Grid g;
  if (!read_grid(argv[2], g)) return 1;
  if (mode == "dump") {
    std::ofstream out(argv[3], std::ios::binary);
    out.write(reinterpret_cast<const char*>(g.z.data()),
              static_cast<std::streamsize>(g.z.size() * sizeof(float)));
    std::printf("%d %d\n", g.w, g.h);
    return out ? 0 : 1;
  }
  if (mode != "compare" || argc < 5) return 2;
  const std::string dir = argv[3];
  std::map<std::size_t, double> delatin_ms, delatin_cpu_ms;
  {
    std::ifstream f(dir + "/delatin_times.txt");
    std::size_t n;
    double ms;
    std::string line;
    while (std::getline(f, line)) {
      std::istringstream l(line);
      double cpu = NAN;
      if (!(l >> n >> ms)) continue;
      l >> cpu;
      delatin_ms[n] = ms;
      delatin_cpu_ms[n] = cpu;
    }
  }
  const tinstream::lod::ThinInput input = grid_input(g);
  std::printf(
      "| vertices | Delatin max (m) | ours max (m) | max ratio | Delatin RMS (m) | ours RMS (m) | "
      "RMS ratio | Delatin time (s) | ours time (s) | time ratio | Delatin CPU (s) | ours CPU (s) "
      "| "
      "CPU ratio |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (std::size_t n : parse_counts(argv[4])) {
    PixelMesh dm;
    if (!read_delatin(dir + "/delatin_" + std::to_string(n) + ".txt", dm)) {
      std::fprintf(stderr, "missing Delatin mesh for %zu\n", n);
      return 1;
    }
    tinstream::lod::LodOptions o;
    o.max_points = dm.col.size();  // equal vertex count
    o.epsilon = 0;
    // LOD_BORDER_PER_SIDE overrides the per-side border budget (default: LodOptions' automatic
    // one).
    if (const char* b = std::getenv("LOD_BORDER_PER_SIDE"))
      o.border_points_per_side = std::stoul(b);
    // LOD_GREEDY_FACTOR overrides LodOptions::greedy_factor (0 = drop heuristic from all points).
    if (const char* k = std::getenv("LOD_GREEDY_FACTOR")) o.greedy_factor = std::stod(k);
    // LOD_LATTICE_SCAN=0 turns LodOptions::lattice_scan off (every point filed under its
    // triangle, the general path used for scattered points).
    if (const char* l = std::getenv("LOD_LATTICE_SCAN")) o.lattice_scan = std::string(l) != "0";
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    auto ours = tinstream::lod::thin_tile(input, o);
    const double ours_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double ours_cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    if (!ours.ok()) {
      std::fprintf(stderr, "thin_tile: %s\n", ours.error().message.c_str());
      return 1;
    }
    const PixelMesh om = to_pixels(g, *ours);
    const Errors de = evaluate(g, dm), oe = evaluate(g, om);
    const double dt = delatin_ms.count(n) ? delatin_ms[n] / 1000.0 : NAN;
    const double dc = delatin_cpu_ms.count(n) ? delatin_cpu_ms[n] / 1000.0 : NAN;
    std::printf(
        "| %zu / %zu | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.2f | %.3f | %.3f "
        "| "
        "%.2f |\n",
        dm.col.size(), ours->vertex_count(), de.max, oe.max, oe.max / de.max, de.rms, oe.rms,
        oe.rms / de.rms, dt, ours_s, ours_s / dt, dc, ours_cpu, ours_cpu / dc);
    std::fprintf(stderr, "%zu vertices: border max Delatin %.3f m, ours %.3f m\n", n, de.border_max,
                 oe.border_max);
    std::fflush(stdout);
  }
  return 0;
}
