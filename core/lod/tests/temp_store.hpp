// A tile store in a fresh temporary directory, removed with it: the pyramid tests' real SQLite
// file, and build_pyramid over a layer of it through the ingest's sink.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <system_error>

#include "tinstream/ingest/layer_sink.hpp"
#include "tinstream/lod/pyramid.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::lod::testing {

struct TempStore {
  std::filesystem::path dir;
  std::optional<store::TileStore> store;
  explicit TempStore(const std::string& name) {
    dir = std::filesystem::temp_directory_path() /
          ("tinstream-lod-test-" + name + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    auto s = store::TileStore::open(dir / "tiles.sqlite", store::TileStore::Mode::read_write);
    EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
    if (s.ok()) store.emplace(std::move(*s));
  }
  ~TempStore() {
    store.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  TempStore(const TempStore&) = delete;
  TempStore& operator=(const TempStore&) = delete;
  std::unique_ptr<store::LayerWriter> writer(const std::string& layer) {
    store::LayerInfo info;
    info.name = layer;
    auto w = store->begin_layer(info);
    EXPECT_TRUE(w.ok()) << (w.ok() ? "" : w.error().message);
    return w.ok() ? std::move(*w) : nullptr;
  }
};

// build_pyramid over the unpublished layer `writer` writes, as the ingest runs it.
inline Result<PyramidSummary> build_stored_pyramid(store::LayerWriter& writer,
                                                   std::uint32_t finest_level,
                                                   std::uint32_t min_level,
                                                   const PyramidOptions& options, unsigned threads,
                                                   const ProgressSink& progress = {}) {
  ingest::LayerSink sink(writer);
  return build_pyramid(sink, finest_level, min_level, options, threads, progress);
}

}  // namespace tinstream::lod::testing
