// `tinstream triangulate`: points (and optional constraint segments) -> constrained Delaunay
// triangulation as an OFF mesh. A thin front end over tinstream::kernel; point loading is one
// function (load_points) so that the sources module can take over LAS and other formats.
#include <CLI/CLI.hpp>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/kernel/triangulation.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::cli {
namespace {

using kernel::Point3;

struct Options {
  std::string in;
  std::string out;
  std::string constraints;
};

bool ends_with(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  for (std::size_t i = 0; i < suffix.size(); ++i) {
    const char c = s[s.size() - suffix.size() + i];
    if (std::tolower(static_cast<unsigned char>(c)) != suffix[i]) return false;
  }
  return true;
}

// Parses up to `want` leading numbers of a line (separated by blanks or commas) into out.
// Returns how many were read; extra columns are ignored.
std::size_t parse_numbers(const std::string& line, double* out, std::size_t want) {
  const char* p = line.data();
  const char* end = p + line.size();
  std::size_t n = 0;
  while (n < want) {
    while (p < end && (*p == ' ' || *p == '\t' || *p == ',' || *p == '\r')) ++p;
    if (p == end) break;
    const auto [next, ec] = std::from_chars(p, end, out[n]);
    if (ec != std::errc() || !std::isfinite(out[n])) break;
    if (next < end && !(*next == ' ' || *next == '\t' || *next == ',' || *next == '\r')) break;
    p = next;
    ++n;
  }
  return n;
}

bool skippable(const std::string& line) {
  for (char c : line) {
    if (c == '#') return true;
    if (!(c == ' ' || c == '\t' || c == '\r')) return false;
  }
  return true;
}

// Reads lines of `columns` numbers; blank and '#' lines are skipped.
Result<std::vector<std::array<double, 6>>> read_rows(const std::string& path, std::size_t columns,
                                                     const char* what) {
  std::ifstream f(path);
  if (!f) return not_found(path + ": cannot open " + what + " file");
  std::vector<std::array<double, 6>> rows;
  std::string line;
  std::size_t lineno = 0;
  while (std::getline(f, line)) {
    ++lineno;
    if (skippable(line)) continue;
    std::array<double, 6> r{};
    if (parse_numbers(line, r.data(), columns) != columns) {
      return corrupt_data(path + ":" + std::to_string(lineno) + ": expected " +
                          std::to_string(columns) + " finite numbers (" + what + "), got \"" +
                          line.substr(0, 80) + "\"");
    }
    rows.push_back(r);
  }
  if (f.bad()) return io_error(path + ": read error");
  return rows;
}

// The one place that turns an input path into points.
Result<std::vector<Point3>> load_points(const std::string& path) {
  if (ends_with(path, ".las") || ends_with(path, ".laz")) {
    // LAS through the sources module: every class, coordinates as stored (scale/offset applied).
    sources::SourceOptions options;
    options.format = sources::SourceFormat::las;
    std::vector<std::uint8_t> all(256);
    for (int c = 0; c < 256; ++c) all[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(c);
    options.class_filter.classes = all;
    auto source = sources::open_source(path, options);
    if (!source) return source.error();
    std::vector<sources::SourcePoint> batch;
    std::vector<Point3> pts;
    for (;;) {
      batch.clear();
      auto n = (*source)->read(batch, 1 << 16);
      if (!n) return n.error();
      if (*n == 0) break;
      for (const auto& p : batch) pts.push_back({p.x, p.y, p.z, 0.0});
    }
    return pts;
  }
  auto rows = read_rows(path, 3, "x y z");
  if (!rows.ok()) return rows.error();
  std::vector<Point3> pts;
  pts.reserve(rows->size());
  for (const auto& r : *rows) pts.push_back({r[0], r[1], r[2], 0.0});
  return pts;
}

int fail(const Error& e) {
  std::cerr << "tinstream triangulate: " << e.message << "\n";
  return 1;
}

int run(const Options& o) {
  auto points = load_points(o.in);
  if (!points.ok()) return fail(points.error());
  std::vector<std::array<double, 6>> segments;
  if (!o.constraints.empty()) {
    auto rows = read_rows(o.constraints, 6, "x1 y1 z1 x2 y2 z2");
    if (!rows.ok()) return fail(rows.error());
    segments = std::move(*rows);
  }

  const auto start = std::chrono::steady_clock::now();
  kernel::Triangulation tri;
  const auto results = tri.insert_bulk(*points);
  std::size_t duplicates = 0;
  for (const auto& r : results) duplicates += r.outcome == kernel::InsertOutcome::duplicate;
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const auto& s = segments[i];
    auto r = tri.insert_constraint(Point3{s[0], s[1], s[2], 0.0}, Point3{s[3], s[4], s[5], 0.0});
    if (!r.ok()) {
      return fail(Error(r.error().code, o.constraints + ": segment " + std::to_string(i + 1) +
                                            ": " + r.error().message));
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  std::ofstream out(o.out);
  if (!out) return fail(io_error(o.out + ": cannot create output file"));
  std::vector<std::uint32_t> index(tri.vertex_id_bound(), 0);
  std::size_t nv = 0;
  for (kernel::VertexId v = 1; v < tri.vertex_id_bound(); ++v) {
    if (tri.is_vertex(v)) index[v] = static_cast<std::uint32_t>(nv++);
  }
  out << "OFF\n" << nv << " " << tri.num_finite_triangles() << " 0\n";
  char buf[128];
  for (kernel::VertexId v = 1; v < tri.vertex_id_bound(); ++v) {
    if (!tri.is_vertex(v)) continue;
    const int len =
        std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g\n", tri.xy(v).x, tri.xy(v).y, tri.z(v));
    out.write(buf, len);
  }
  tri.for_each_finite_triangle([&](kernel::TriangleId, const kernel::Triangle& t) {
    out << "3 " << index[t.v[0]] << " " << index[t.v[1]] << " " << index[t.v[2]] << "\n";
  });
  out.close();
  if (!out) return fail(io_error(o.out + ": write error"));

  nlohmann::json j;
  j["points"] = nv;
  j["triangles"] = tri.num_finite_triangles();
  j["seconds"] = seconds;
  j["duplicates"] = duplicates;
  std::cerr << j.dump() << "\n";
  return 0;
}

const CommandRegistration kRegistration{
    "triangulate", "Delaunay-triangulate points (and constraint segments) into an OFF mesh",
    [](CLI::App& sub) -> CommandRun {
      auto opts = std::make_shared<Options>();
      sub.add_option(
             "--in", opts->in,
             "Input points: .xyz text, one point per line as 'x y z' (blanks or commas; "
             "extra columns ignored; blank and '#' lines skipped) or a LAS file (all classes, "
             "coordinates as stored, no reprojection; LAZ reads like LAS).")
          ->required();
      sub.add_option(
             "--out", opts->out,
             "Output mesh (OFF): the distinct input points plus any vertices created where "
             "constraints cross, then the finite triangles, counter-clockwise, covering the "
             "convex hull of the points.")
          ->required();
      sub.add_option("--constraints", opts->constraints,
                     "Optional constraint segments, one per line 'x1 y1 z1 x2 y2 z2' (breaklines, "
                     "tile borders). Endpoints are inserted as points; segments are split where "
                     "they pass through vertices or cross each other.");
      sub.footer(
          "Prints one JSON line to stderr: {\"points\":N,\"triangles\":T,\"seconds\":S,"
          "\"duplicates\":D} with N the output vertices, D the input points dropped as exact (x,y) "
          "duplicates (the first one kept) and S the triangulation time without file I/O "
          "(spatial sorting included). Exit status 0 on success, 1 with a one-line error naming "
          "the "
          "file and line otherwise.");
      return [opts] { return run(*opts); };
    }};

}  // namespace
}  // namespace tinstream::cli
