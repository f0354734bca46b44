// tinstream/ingest/layer_sink.hpp — pass 4's tiles in the store: the unpublished layer version a
// store::LayerWriter writes, as the lod::TileSink that build_pyramid reads and writes.
//
// Encoded tiles are store::StoredTile (compressed blob, entity tag: store::prepare_tile), so
// what the pyramid writes is what LayerWriter::put(const TinTile&) would have written.
// Threads: as lod::TileSink; the LayerWriter is touched by get, put, flush and tile_ids only.
// The sink must not outlive the writer.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "tinstream/lod/tile_sink.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::ingest {

class LayerSink final : public lod::TileSink {
 public:
  explicit LayerSink(store::LayerWriter& writer) : writer_(writer) {}

  Result<std::vector<geo::TileId>> tile_ids(std::uint32_t level) override;
  Result<std::unique_ptr<lod::EncodedTile>> get(const geo::TileId& id) override;
  Status put(std::unique_ptr<lod::EncodedTile> tile) override;
  Status flush() override;
  Result<std::unique_ptr<lod::EncodedTile>> encode(const tile::TinTile& tile) const override;
  Result<tile::TinTile> decode(const lod::EncodedTile& tile) const override;

 private:
  store::LayerWriter& writer_;
};

}  // namespace tinstream::ingest
