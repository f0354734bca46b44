// Side-by-side benchmarks of the triangulation kernel against CGAL 5.x
// (Exact_predicates_inexact_constructions_kernel), on identical point sets in one process:
//   build      Delaunay of n points (ours: insert_bulk; CGAL: range insert = spatial sort + insert)
//   constrain  tile border + 1e4 random non-crossing segments into the n-point triangulation
//   remove     removal of 50 % of the points in random order
// Every case reports the time and, for builds, heap bytes per point (glibc mallinfo2 delta).
// At the end a table of ratios CGAL time / our time (> 1: we are faster) is printed.
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <benchmark/benchmark.h>
#include <malloc.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "datasets.hpp"
#include "tinstream/kernel/triangulation.hpp"

namespace {

using tinstream::bench::dataset;
using tinstream::bench::kKind;
using tinstream::bench::removal_victims;
using tinstream::kernel::Point3;
using tinstream::kernel::Rect;
using tinstream::kernel::Triangulation;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using CgalDt = CGAL::Delaunay_triangulation_2<K>;
using CgalCdt =
    CGAL::Constrained_Delaunay_triangulation_2<K, CGAL::Default, CGAL::Exact_predicates_tag>;

std::vector<K::Point_2> cgal_points(const std::vector<Point3>& p) {
  std::vector<K::Point_2> v;
  v.reserve(p.size());
  for (const auto& q : p) v.emplace_back(q.x, q.y);
  return v;
}

std::size_t heap_in_use() { return mallinfo2().uordblks + mallinfo2().hblkhd; }

// Segments for the constrained case: the unit square border plus 1e4 short segments, one per
// cell of a 100 x 100 grid (so they do not cross each other).
std::vector<std::array<Point3, 2>> segments() {
  std::vector<std::array<Point3, 2>> s;
  const Point3 c[4] = {{0, 0, 0, 0}, {1, 0, 0, 0}, {1, 1, 0, 0}, {0, 1, 0, 0}};
  for (int i = 0; i < 4; ++i) s.push_back({c[i], c[(i + 1) % 4]});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < 100; ++j) {
      s.push_back({Point3{(i + u(rng)) / 100, (j + u(rng)) / 100, 0, 0},
                   Point3{(i + u(rng)) / 100, (j + u(rng)) / 100, 0, 0}});
    }
  }
  return s;
}

// ---- benchmarks
// ----------------------------------------------------------------------------------
void BM_build_ours(benchmark::State& st) {
  const auto& pts = dataset(static_cast<int>(st.range(0)), static_cast<std::size_t>(st.range(1)));
  double bytes = 0;
  for (auto _ : st) {
    const std::size_t before = heap_in_use();
    auto t = std::make_unique<Triangulation>();
    t->insert_bulk(pts);
    bytes = double(heap_in_use() - before) / double(pts.size());
    benchmark::DoNotOptimize(t->num_finite_triangles());
    st.PauseTiming();
    t.reset();
    st.ResumeTiming();
  }
  st.counters["bytes_per_point"] = bytes;
  st.SetLabel(kKind[st.range(0)]);
}

void BM_build_cgal(benchmark::State& st) {
  const auto& pts = dataset(static_cast<int>(st.range(0)), static_cast<std::size_t>(st.range(1)));
  const auto cp = cgal_points(pts);
  double bytes = 0;
  for (auto _ : st) {
    const std::size_t before = heap_in_use();
    auto t = std::make_unique<CgalDt>();
    t->insert(cp.begin(), cp.end());
    bytes = double(heap_in_use() - before) / double(pts.size());
    benchmark::DoNotOptimize(t->number_of_faces());
    st.PauseTiming();
    t.reset();
    st.ResumeTiming();
  }
  st.counters["bytes_per_point"] = bytes;
  st.SetLabel(kKind[st.range(0)]);
}

void BM_constrain_ours(benchmark::State& st) {
  const auto& pts = dataset(0, static_cast<std::size_t>(st.range(1)));
  const auto segs = segments();
  for (auto _ : st) {
    st.PauseTiming();
    auto t = std::make_unique<Triangulation>(Rect{0, 0, 1, 1});
    t->insert_bulk(pts);
    st.ResumeTiming();
    for (const auto& s : segs) {
      if (!t->insert_constraint(s[0], s[1]).ok()) st.SkipWithError("constraint failed");
    }
    st.PauseTiming();
    t.reset();
    st.ResumeTiming();
  }
  st.SetLabel("uniform + border + 1e4 segments");
}

void BM_constrain_cgal(benchmark::State& st) {
  const auto& pts = dataset(0, static_cast<std::size_t>(st.range(1)));
  const auto cp = cgal_points(pts);
  const auto segs = segments();
  for (auto _ : st) {
    st.PauseTiming();
    auto t = std::make_unique<CgalCdt>();
    t->insert(cp.begin(), cp.end());
    st.ResumeTiming();
    for (const auto& s : segs)
      t->insert_constraint(K::Point_2(s[0].x, s[0].y), K::Point_2(s[1].x, s[1].y));
    st.PauseTiming();
    t.reset();
    st.ResumeTiming();
  }
  st.SetLabel("uniform + border + 1e4 segments");
}

void BM_remove_half_ours(benchmark::State& st) {
  const auto& pts = dataset(static_cast<int>(st.range(0)), static_cast<std::size_t>(st.range(1)));
  const auto victims = removal_victims(pts.size());
  for (auto _ : st) {
    st.PauseTiming();
    auto t = std::make_unique<Triangulation>();
    const auto ids = t->insert_bulk(pts);
    std::vector<tinstream::kernel::VertexId> handles;
    std::set<tinstream::kernel::VertexId> taken;
    for (std::size_t i : victims) {
      if (taken.insert(ids[i].vertex).second) handles.push_back(ids[i].vertex);
    }
    st.ResumeTiming();
    for (auto v : handles) {
      if (!t->remove_vertex(v).ok()) st.SkipWithError("remove failed");
    }
    st.PauseTiming();
    t.reset();
    st.ResumeTiming();
  }
  st.SetLabel(kKind[st.range(0)]);
}

void BM_remove_half_cgal(benchmark::State& st) {
  const auto& pts = dataset(static_cast<int>(st.range(0)), static_cast<std::size_t>(st.range(1)));
  const auto cp = cgal_points(pts);
  const auto victims = removal_victims(pts.size());
  for (auto _ : st) {
    st.PauseTiming();
    auto t = std::make_unique<CgalDt>();
    t->insert(cp.begin(), cp.end());
    // Handles by input index (the first of duplicates), without touching the timed part.
    std::map<std::pair<double, double>, CgalDt::Vertex_handle> at;
    for (auto v : t->finite_vertex_handles()) at[{v->point().x(), v->point().y()}] = v;
    std::vector<CgalDt::Vertex_handle> handles;
    std::set<std::pair<double, double>> taken;
    for (std::size_t i : victims) {
      const std::pair<double, double> key{pts[i].x, pts[i].y};
      if (taken.insert(key).second) handles.push_back(at.at(key));
    }
    st.ResumeTiming();
    for (auto v : handles) t->remove(v);
    st.PauseTiming();
    t.reset();
    st.ResumeTiming();
  }
  st.SetLabel(kKind[st.range(0)]);
}

void build_args(benchmark::internal::Benchmark* b) {
  for (long n : {1000000L, 4000000L}) {
    b->Args({0, n});
    b->Args({1, n});
  }
  b->Args({2, 0});
}
void half_args(benchmark::internal::Benchmark* b) {
  for (long n : {1000000L, 4000000L}) b->Args({0, n});
  b->Args({1, 1000000L});
  b->Args({2, 0});
}
void constrain_args(benchmark::internal::Benchmark* b) {
  for (long n : {1000000L, 4000000L}) b->Args({0, n});
}

BENCHMARK(BM_build_ours)
    ->Apply(build_args)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3)
    ->ReportAggregatesOnly(false);
BENCHMARK(BM_build_cgal)
    ->Apply(build_args)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3);
BENCHMARK(BM_constrain_ours)
    ->Apply(constrain_args)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3);
BENCHMARK(BM_constrain_cgal)
    ->Apply(constrain_args)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3);
BENCHMARK(BM_remove_half_ours)
    ->Apply(half_args)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3);
BENCHMARK(BM_remove_half_cgal)
    ->Apply(half_args)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Repetitions(3);

// Collects the minimum time of each case and prints CGAL / ours ratios at the end.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const auto& r : runs) {
      if (r.run_type != Run::RT_Iteration || r.error_occurred) continue;
      std::string name = r.run_name.function_name;
      const std::string args = r.run_name.args;
      auto& slot = best_[{name, args}];
      const double t = r.GetAdjustedCPUTime();  // CPU time: the 2-core machine is shared
      if (slot == 0 || t < slot) slot = t;
      if (r.counters.count("bytes_per_point"))
        bytes_[{name, args}] = r.counters.at("bytes_per_point");
    }
    ConsoleReporter::ReportRuns(runs);
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf("\n%-14s %-18s %12s %12s %8s %10s %10s\n", "case", "data/n", "ours cpu ms",
                "cgal cpu ms", "ratio", "ours B/pt", "cgal B/pt");
    for (const auto& [key, ours] : best_) {
      const auto& [name, args] = key;
      if (name.size() < 5 || name.compare(name.size() - 5, 5, "_ours") != 0) continue;
      const std::string peer = name.substr(0, name.size() - 5) + "_cgal";
      const auto it = best_.find({peer, args});
      if (it == best_.end()) continue;
      const std::string shortname = name.substr(3, name.size() - 8);
      const double bo = bytes_.count(key) ? bytes_.at(key) : 0,
                   bc = bytes_.count({peer, args}) ? bytes_.at({peer, args}) : 0;
      std::printf("%-14s %-18s %12.1f %12.1f %8.2f %10.0f %10.0f\n", shortname.c_str(),
                  args.c_str(), ours, it->second, it->second / ours, bo, bc);
    }
  }

 private:
  std::map<std::pair<std::string, std::string>, double> best_;
  std::map<std::pair<std::string, std::string>, double> bytes_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
