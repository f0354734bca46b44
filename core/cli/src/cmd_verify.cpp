// `tinstream verify`: checks every tile of a layer; non-zero exit on any failure.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <iostream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "command.hpp"
#include "progress_printer.hpp"
#include "tinstream/ingest/verify.hpp"

namespace tinstream::cli {
namespace {

struct VerifyArgs {
  std::string store, layer;
  std::string error_samples = "4";
  bool no_delaunay = false, surface_error = false, quiet = false;
};

int run(const VerifyArgs& a) {
  auto store = store::TileStore::open(a.store, store::TileStore::Mode::read_only);
  if (!store) {
    std::cerr << "tinstream verify: " << store.error().message << "\n";
    return 2;
  }
  ProgressPrinter printer(a.quiet);
  ingest::VerifyOptions options;
  options.delaunay = !a.no_delaunay;
  options.surface_error = a.surface_error;
  if (a.error_samples == "all") {
    options.error_samples = SIZE_MAX;
  } else {
    try {
      std::size_t used = 0;
      options.error_samples = std::stoul(a.error_samples, &used);
      if (used != a.error_samples.size()) throw std::invalid_argument("trailing characters");
    } catch (const std::exception&) {
      std::cerr << "tinstream verify: --error-samples wants a count or 'all', not '"
                << a.error_samples << "'\n";
      return 2;
    }
  }
  auto report = ingest::verify_layer(*store, a.layer, options, printer.sink());
  printer.finish();
  if (!report) {
    std::cerr << "tinstream verify: " << report.error().message << "\n";
    return 2;
  }
  nlohmann::json j{{"layer", a.layer},
                   {"tiles", report->tiles},
                   {"triangles", report->triangles},
                   {"shared_borders", report->shared_borders},
                   {"error_checks", report->error_checks},
                   {"worst_error_ratio", report->worst_error_ratio},
                   {"near_duplicate_pairs", report->near_duplicate_pairs},
                   {"problems", report->problems},
                   {"messages", report->messages},
                   {"ok", report->ok()}};
  if (a.surface_error) j["worst_surface_ratio"] = report->worst_surface_ratio;
  std::cout << j.dump(2) << "\n";
  return report->ok() ? 0 : 1;
}

const CommandRegistration kRegistration{
    "verify",
    "Check every tile of a layer: structure, Delaunay, watertight borders, pyramid, point count",
    [](CLI::App& sub) -> CommandRun {
      auto a = std::make_shared<VerifyArgs>();
      sub.add_option("--store", a->store, "SQLite tile store")
          ->required()
          ->check(CLI::ExistingFile);
      sub.add_option("--layer", a->layer, "Layer name")->required();
      sub.add_flag("--no-delaunay", a->no_delaunay, "Skip the empty-circle check (faster)");
      sub.add_option("--error-samples", a->error_samples,
                     "Finest tiles sampled under each coarser tile to check that its stored "
                     "geometric error bounds the finest surface: a count (0 = no check) or "
                     "'all' (exhaustive)")
          ->default_str("4");
      sub.add_flag("--surface-error", a->surface_error,
                   "Also check each sampled stored error against the exact maximum difference "
                   "to the finest surface (edge crossings included), not only at its points");
      sub.add_flag("-q,--quiet", a->quiet, "No progress display");
      return [a] { return run(*a); };
    }};

}  // namespace
}  // namespace tinstream::cli
