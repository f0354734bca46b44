// `tinstream ingest`: sources → constrained TIN tile pyramid in an SQLite store.
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <sstream>

#include "command.hpp"
#include "progress_printer.hpp"
#include "tinstream/ingest/ingest.hpp"

namespace tinstream::cli {
namespace {

struct IngestArgs {
  std::string store, layer, crs, z_units, vertical = "ellipsoidal", classes,
                                          projection = "spherical";
  std::string delimiter, columns, attribution, tmp;
  std::vector<std::string> inputs;
  std::uint32_t max_points = 16384, max_level = 24, min_level = 0;
  double epsilon = 0.0;
  std::size_t memory_mb = 256;
  unsigned threads = 0;
  bool no_pyramid = false, skip_invalid = false, json = false, quiet = false;
};

Result<std::vector<std::uint8_t>> parse_classes(const std::string& text) {
  std::vector<std::uint8_t> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      const int v = std::stoi(item);
      if (v < 0 || v > 255) throw std::out_of_range("class");
      out.push_back(static_cast<std::uint8_t>(v));
    } catch (const std::exception&) {
      return invalid_argument("--classes: '" + item + "' is not a class number 0-255");
    }
  }
  if (out.empty()) return invalid_argument("--classes: empty list");
  return out;
}

Result<ingest::IngestOptions> to_options(const IngestArgs& a) {
  ingest::IngestOptions o;
  o.store_path = a.store;
  o.layer = a.layer;
  auto projection = geo::parse_projection(a.projection);
  if (!projection) return projection.error();
  o.projection = *projection;
  o.max_points = a.max_points;
  o.max_level = a.max_level;
  o.min_level = a.min_level;
  o.epsilon = a.epsilon;
  o.pyramid = !a.no_pyramid;
  o.memory_bytes = a.memory_mb << 20;
  o.tmp_dir = a.tmp;
  o.threads = a.threads;
  o.attribution = a.attribution;
  for (const auto& path : a.inputs) {
    transform::InputSpec in;
    in.path = path;
    in.reproject.crs = a.crs;
    in.source.decode_threads = a.threads;  // LAZ chunk decoding (0 = one per core)
    in.reproject.vertical_datum = a.vertical;
    if (!a.z_units.empty()) {
      auto unit = sources::parse_linear_unit(a.z_units);
      if (!unit) return unit.error();
      in.reproject.z_unit = *unit;
    }
    if (!a.classes.empty()) {
      auto classes = parse_classes(a.classes);
      if (!classes) return classes.error();
      in.source.class_filter.classes = *classes;
    }
    if (a.skip_invalid) in.source.invalid = sources::InvalidPolicy::skip;
    if (!a.delimiter.empty()) {
      in.source.text.delimiter =
          a.delimiter == "\\t" || a.delimiter == "tab" ? '\t' : a.delimiter[0];
    }
    if (!a.columns.empty()) {
      std::stringstream ss(a.columns);
      std::string item;
      std::vector<std::size_t> cols;
      while (std::getline(ss, item, ',')) {
        try {
          cols.push_back(static_cast<std::size_t>(std::stoul(item)));
        } catch (const std::exception&) {
          return invalid_argument("--columns: '" + item + "' is not a column number");
        }
      }
      if (cols.size() < 3) return invalid_argument("--columns needs x,y,z (0-based), e.g. 0,1,2");
      in.source.text.x_column = cols[0];
      in.source.text.y_column = cols[1];
      in.source.text.z_column = cols[2];
    }
    o.inputs.push_back(std::move(in));
  }
  return o;
}

nlohmann::json summary_json(const ingest::IngestSummary& s) {
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& l : s.levels) {
    levels.push_back({{"level", l.level}, {"tiles", l.tiles}, {"max_error", l.max_error}});
  }
  nlohmann::json inputs = nlohmann::json::array();
  for (const auto& in : s.inputs) {
    inputs.push_back({{"path", in.path},
                      {"format", in.format},
                      {"crs", in.plan.crs_name.empty() ? in.plan.crs : in.plan.crs_name},
                      {"z_unit", in.plan.z_unit.name},
                      {"z_unit_rule", in.plan.z_unit_rule},
                      {"records", in.counters.records_read},
                      {"accepted", in.counters.accepted},
                      {"rejected_class", in.counters.rejected_class},
                      {"rejected_nodata", in.counters.rejected_nodata},
                      {"rejected_invalid", in.counters.rejected_invalid},
                      {"notes", in.notes}});
  }
  nlohmann::json phases = nlohmann::json::array();
  for (const auto& p : s.phases) {
    phases.push_back({{"phase", p.name}, {"seconds", p.seconds}, {"cpu_seconds", p.cpu_seconds}});
  }
  return {{"layer", s.layer},
          {"records_read", s.records_read},
          {"points_accepted", s.points_accepted},
          {"points_rejected", s.points_rejected},
          {"duplicates_merged", s.duplicates_merged},
          {"points", s.points},
          {"finest_level", s.finest_level},
          {"min_level", s.min_level},
          {"tiles", s.tiles},
          {"levels", levels},
          {"halo_overhead", s.halo_overhead},
          {"seconds", s.seconds},
          {"points_per_second",
           s.seconds > 0 ? static_cast<double>(s.points_accepted) / s.seconds : 0.0},
          {"peak_rss_mb", static_cast<double>(s.peak_rss_bytes) / (1024.0 * 1024.0)},
          {"phases", phases},
          {"inputs", inputs}};
}

// SIGINT/SIGTERM ask the ingest to stop at its next progress report: it then removes its
// temporary files, publishes nothing and exits 128 + the signal. A second signal kills at once
// (the handlers reset themselves).
std::atomic<int> g_stop_signal{0};
static_assert(std::atomic<int>::is_always_lock_free);

extern "C" void request_stop(int signo) { g_stop_signal.store(signo); }

class StopOnSignals {
 public:
  StopOnSignals() {
    struct sigaction sa {};
    sa.sa_handler = request_stop;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~StopOnSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  struct sigaction old_int_ {
  }, old_term_{};
};

// An ingest is a batch job whose passes allocate and free the same large buffers tile after tile
// (pass 4's parents: candidate lists, the greedy stage's pool, the chained error's known points,
// tens of MB each on a 770k-point DEM). glibc's defaults give every block above its mmap
// threshold (at most 32 MB) fresh pages, return freed heap tops to the system, and serve each
// worker thread from its own arena of 64 MB heaps, so those buffers were faulted in again for
// every parent: ~700k page faults and ~15 % of pass 4's CPU on Big Tujunga (bench/lod/RESULTS.md,
// #20 CPU). Here: one arena, no mmap for large blocks, no trimming — freed memory is reused by
// the next tile (peak memory within a few % of before; it is returned when the process exits).
// Outputs are unchanged (allocation never decides a result).
void keep_heap_for_batch() {
#if defined(__GLIBC__)
  (void)mallopt(M_ARENA_MAX, 1);
  (void)mallopt(M_MMAP_MAX, 0);
  (void)mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
#endif
}

int run(const IngestArgs& args) {
  keep_heap_for_batch();
  auto options = to_options(args);
  if (!options) {
    std::cerr << "tinstream ingest: " << options.error().message << "\n";
    return 2;
  }
  ProgressPrinter printer(args.quiet);
  StopOnSignals stop_on_signals;
  ProgressSink sink = [inner = printer.sink()](const Progress& p) {
    return g_stop_signal.load() == 0 && inner(p);
  };
  auto summary = ingest::run_ingest(*options, sink);
  printer.finish();
  if (!summary) {
    if (const int signo = g_stop_signal.load(); signo != 0) {
      std::cerr << "tinstream ingest: stopped by signal " << signo
                << "; nothing was published, the store is unchanged, temporary files removed\n";
      return 128 + signo;
    }
    std::cerr << "tinstream ingest: " << summary.error().message << "\n";
    std::cerr << "(nothing was published; the store is unchanged)\n";
    return 1;
  }
  const auto j = summary_json(*summary);
  if (args.json) {
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::cout << "layer '" << summary->layer << "': " << summary->points << " points in "
            << summary->tiles << " tiles, levels " << summary->min_level << "–"
            << summary->finest_level << "\n"
            << "  read " << summary->records_read << " records: " << summary->points_accepted
            << " accepted, " << summary->points_rejected << " rejected, "
            << summary->duplicates_merged << " duplicates merged\n";
  for (const auto& l : summary->levels) {
    std::cout << "  level " << l.level << ": " << l.tiles << " tiles, max error " << l.max_error
              << " m\n";
  }
  char line[160];
  std::snprintf(line, sizeof line, "  %.1f s, %.0f points/s, peak memory %.0f MB\n",
                summary->seconds, j["points_per_second"].get<double>(),
                j["peak_rss_mb"].get<double>());
  std::cout << line;
  for (const auto& p : summary->phases) {
    std::snprintf(line, sizeof line, "  %-12s %8.1f s wall %8.1f s CPU\n", p.name.c_str(),
                  p.seconds, p.cpu_seconds);
    std::cout << line;
  }
  return 0;
}

const CommandRegistration kRegistration{
    "ingest", "Build a constrained-TIN tile pyramid from LAS / XYZ / raster inputs into a store",
    [](CLI::App& sub) -> CommandRun {
      auto a = std::make_shared<IngestArgs>();
      sub.add_option("--store", a->store, "SQLite tile store (created when absent)")->required();
      sub.add_option("--layer", a->layer,
                     "Layer name ([A-Za-z0-9_.-], replaced atomically if it exists)")
          ->required();
      sub.add_option(
             "inputs", a->inputs,
             "Input files: LAS 1.0-1.4 (.las), XYZ/CSV text (.xyz .csv .txt .pts), or any "
             "raster GDAL reads (GeoTIFF, .hgt, ESRI ASCII .asc, VRT…); formats may be mixed")
          ->required()
          ->check(CLI::ExistingFile);
      sub.add_option(
          "--crs", a->crs,
          "Source CRS for every input (EPSG:n, WKT or PROJ string); default: the file's own");
      sub.add_option(
          "--z-units", a->z_units,
          "Unit of the input heights: metre, foot, us-foot (default: from the CRS; a CRS "
          "without a vertical part → the horizontal unit)");
      sub.add_option(
             "--vertical", a->vertical,
             "Vertical datum of the input heights: ellipsoidal (taken as is), egm96, egm2008, "
             "crs (the source CRS's vertical part) or a PROJ geoid grid file")
          ->capture_default_str();
      sub.add_option("--classes", a->classes,
                     std::string("Comma-separated ASPRS classes to keep. ") +
                         std::string(sources::kClassFilterRule));
      sub.add_option(
             "--projection", a->projection,
             "Layer projection: spherical (Web Mercator tiles) or ellipsoidal (WGS84 Mercator)")
          ->capture_default_str();
      sub.add_option("--max-points", a->max_points, "Maximum points per tile (3-65535)")
          ->capture_default_str();
      sub.add_option("--max-level", a->max_level, "Finest level cap (0-30)")->capture_default_str();
      sub.add_option("--min-level", a->min_level, "Coarsest pyramid level")->capture_default_str();
      sub.add_option(
             "--epsilon", a->epsilon,
             "Metres: keep thinning while the vertical error stays below this (LOD levels and "
             "reduced TINs of rasters)")
          ->capture_default_str();
      sub.add_flag("--no-pyramid", a->no_pyramid, "Store only the finest level");
      sub.add_option("--memory", a->memory_mb, "Sort memory budget in MB")->capture_default_str();
      sub.add_option("--tmp", a->tmp, "Directory for temporary files (default: system temp)");
      sub.add_option("--threads", a->threads, "Worker threads (0 = all cores)")
          ->capture_default_str();
      sub.add_option("--delimiter", a->delimiter,
                     "Text inputs: field delimiter (default: whitespace; 'tab' for tabs)");
      sub.add_option("--columns", a->columns, "Text inputs: 0-based x,y,z columns (default 0,1,2)");
      sub.add_option("--attribution", a->attribution, "Attribution text stored with the layer");
      sub.add_flag("--skip-invalid", a->skip_invalid,
                   "Count and skip invalid records (NaN, bad lines) instead of failing");
      sub.add_flag("--json", a->json, "Print the summary as JSON");
      sub.add_flag("-q,--quiet", a->quiet, "No progress display");
      return [a] { return run(*a); };
    }};

}  // namespace
}  // namespace tinstream::cli
