// `tinstream ingest-imagery`: colour rasters → an imagery pyramid on the terrain's quadtree.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command.hpp"
#include "progress_printer.hpp"
#include "stop_signals.hpp"
#include "tinstream/imagery/ingest_imagery.hpp"

namespace tinstream::cli {
namespace {

struct ImageryArgs {
  std::string store, layer, crs, projection, format = "png", resampling = "bilinear", attribution;
  std::vector<std::string> inputs;
  std::optional<std::uint32_t> max_level;
  std::uint32_t min_level = 0;
  int quality = 85;
  bool lossless = false, json = false, quiet = false;
  unsigned threads = 0;
  std::size_t memory_mb = 256;
};

Result<imagery::ImageryIngestOptions> to_options(const ImageryArgs& a) {
  imagery::ImageryIngestOptions o;
  o.store_path = a.store;
  o.layer = a.layer;
  for (const auto& in : a.inputs) o.sources.emplace_back(in);
  o.crs = a.crs;
  if (!a.projection.empty()) {
    auto p = geo::parse_projection(a.projection);
    if (!p) return Error(p.error().code, "--projection: " + p.error().message);
    o.projection = *p;
  }
  auto format = imagery::parse_image_format(a.format);
  if (!format) return Error(format.error().code, "--format: " + format.error().message);
  o.format = *format;
  if (a.quality < 1 || a.quality > 100) {
    return invalid_argument("--quality " + std::to_string(a.quality) + " is outside 1-100");
  }
  o.encode.quality = a.quality;
  o.encode.lossless = a.lossless;
  o.max_level = a.max_level;
  o.min_level = a.min_level;
  o.resampling = a.resampling;
  o.threads = a.threads;
  o.memory_bytes = a.memory_mb << 20;
  o.attribution = a.attribution;
  return o;
}

nlohmann::json summary_json(const imagery::ImagerySummary& s) {
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& l : s.levels) {
    levels.push_back({{"level", l.level}, {"tiles", l.tiles}, {"bytes", l.bytes}});
  }
  nlohmann::json sources = nlohmann::json::array();
  for (const auto& src : s.sources) {
    sources.push_back({{"path", src.path},
                       {"driver", src.driver},
                       {"crs", src.crs},
                       {"bands", src.bands},
                       {"width", src.width},
                       {"height", src.height},
                       {"mercator_metres_per_pixel", src.resolution}});
  }
  return {{"layer", s.layer},
          {"format", s.format},
          {"projection", geo::to_string(s.projection)},
          {"projection_from", s.projection_rule},
          {"native_level", s.native_level},
          {"min_level", s.min_level},
          {"max_level", s.max_level},
          {"tiles", s.tiles},
          {"bytes", s.bytes},
          {"bounds",
           {{"west", s.bounds.west},
            {"south", s.bounds.south},
            {"east", s.bounds.east},
            {"north", s.bounds.north}}},
          {"levels", levels},
          {"sources", sources},
          {"seconds", s.seconds}};
}

int run(const ImageryArgs& args) {
  auto options = to_options(args);
  if (!options) {
    std::cerr << "tinstream ingest-imagery: " << options.error().message << "\n";
    return 2;
  }
  ProgressPrinter printer(args.quiet);
  StopOnSignals stop_on_signals;
  ProgressSink sink = [inner = printer.sink()](const Progress& p) {
    return stop_signal() == 0 && inner(p);
  };
  auto summary = imagery::ingest_imagery(*options, sink);
  printer.finish();
  if (!summary) {
    if (const int signo = stop_signal(); signo != 0) {
      std::cerr << "tinstream ingest-imagery: stopped by signal " << signo
                << "; nothing was published, the store is unchanged\n";
      return 128 + signo;
    }
    std::cerr << "tinstream ingest-imagery: " << summary.error().message << "\n"
              << "(nothing was published; the store is unchanged)\n";
    return 1;
  }
  if (args.json) {
    std::cout << summary_json(*summary).dump(2) << "\n";
    return 0;
  }
  std::cout << "imagery layer '" << summary->layer << "': " << summary->tiles << " "
            << summary->format << " tiles, levels " << summary->min_level << "–"
            << summary->max_level << " (native " << summary->native_level << "), "
            << geo::to_string(summary->projection) << " (" << summary->projection_rule << ")\n";
  for (const auto& s : summary->sources) {
    std::cout << "  " << s.path << ": " << s.driver << " " << s.width << " × " << s.height << " "
              << s.bands << ", " << s.crs << "\n";
  }
  char line[160];
  for (const auto& l : summary->levels) {
    std::snprintf(line, sizeof line, "  level %2u: %8llu tiles %10.1f kB\n", l.level,
                  static_cast<unsigned long long>(l.tiles), static_cast<double>(l.bytes) / 1e3);
    std::cout << line;
  }
  std::snprintf(line, sizeof line, "  bounds %.6f, %.6f to %.6f, %.6f; %.1f s\n",
                summary->bounds.west, summary->bounds.south, summary->bounds.east,
                summary->bounds.north, summary->seconds);
  std::cout << line;
  return 0;
}

const CommandRegistration kRegistration{
    "ingest-imagery",
    "Tile colour rasters (orthophotos) into an imagery layer on the terrain's quadtree",
    [](CLI::App& sub) -> CommandRun {
      auto a = std::make_shared<ImageryArgs>();
      sub.add_option("--store", a->store, "SQLite tile store (created when absent)")->required();
      sub.add_option("--layer", a->layer,
                     "Imagery layer name ([A-Za-z0-9_.-]); the web viewer drapes it over the "
                     "terrain layer of the same name. Replaced atomically if it exists")
          ->required();
      sub.add_option("inputs", a->inputs,
                     "8-bit RGB(A), grey or palette rasters GDAL reads (GeoTIFF orthophotos, any "
                     "CRS); several files form one mosaic, later ones drawn over earlier ones")
          ->required()
          ->check(CLI::ExistingFile);
      sub.add_option("--format", a->format,
                     "Tile encoding: png (lossless, alpha), jpeg (smallest, no alpha: black "
                     "outside the sources) or webp (alpha; lossy unless --lossless)")
          ->capture_default_str();
      sub.add_option("--quality", a->quality, "JPEG / lossy WebP quality, 1-100")
          ->capture_default_str();
      sub.add_flag("--lossless", a->lossless, "WebP: lossless");
      sub.add_option("--max-level", a->max_level,
                     "Finest level (default: the level that matches the finest source pixel)");
      sub.add_option("--min-level", a->min_level, "Coarsest level")->capture_default_str();
      sub.add_option("--resampling", a->resampling,
                     "Finest level resampling: near, bilinear, cubic, cubicspline, lanczos, "
                     "average, mode (coarser levels: 2:1 box filter in linear light)")
          ->capture_default_str();
      sub.add_option("--crs", a->crs,
                     "CRS of every input (EPSG:n, WKT or PROJ string); default: the file's own");
      sub.add_option("--projection", a->projection,
                     "spherical (EPSG:3857 tiles) or ellipsoidal; default: the projection of the "
                     "terrain layer of the same name, else spherical");
      sub.add_option("--threads", a->threads, "Worker threads (0 = all cores)")
          ->capture_default_str();
      sub.add_option("--memory", a->memory_mb, "Memory budget in MB (half is GDAL's block cache)")
          ->capture_default_str();
      sub.add_option("--attribution", a->attribution, "Attribution text stored with the layer");
      sub.add_flag("--json", a->json, "Print the summary as JSON");
      sub.add_flag("-q,--quiet", a->quiet, "No progress display");
      return [a] { return run(*a); };
    }};

}  // namespace
}  // namespace tinstream::cli
