#include "tinstream/ingest/layer_sink.hpp"

#include <utility>

namespace tinstream::ingest {

namespace {

// A stored tile as the pyramid holds it.
class StoredBlob final : public lod::EncodedTile {
 public:
  explicit StoredBlob(store::StoredTile stored) : stored_(std::move(stored)) {}

  const geo::TileId& id() const override { return stored_.id; }
  double geometric_error() const override { return stored_.geometric_error; }
  std::uint32_t vertex_count() const override { return stored_.vertex_count; }

  const store::StoredTile& stored() const { return stored_; }
  store::StoredTile take() && { return std::move(stored_); }

 private:
  store::StoredTile stored_;
};

// `tile` as this sink made it (encode or get); null for another sink's tile.
const StoredBlob* ours(const lod::EncodedTile& tile) {
  return dynamic_cast<const StoredBlob*>(&tile);
}

Error foreign(const geo::TileId& id) {
  return Error(ErrorCode::internal,
               "lod: tile " + id.to_string() + " was not encoded by the layer's sink");
}

}  // namespace

Result<std::vector<geo::TileId>> LayerSink::tile_ids(std::uint32_t level) {
  return writer_.tile_ids(level);
}

Result<std::unique_ptr<lod::EncodedTile>> LayerSink::get(const geo::TileId& id) {
  auto stored = writer_.get_stored(id);
  if (!stored) return stored.error();
  if (!*stored) return std::unique_ptr<lod::EncodedTile>{};
  return std::unique_ptr<lod::EncodedTile>(std::make_unique<StoredBlob>(std::move(**stored)));
}

Status LayerSink::put(std::unique_ptr<lod::EncodedTile> tile) {
  if (!tile) return Error(ErrorCode::internal, "lod: put of no tile");
  auto* blob = dynamic_cast<StoredBlob*>(tile.get());
  if (blob == nullptr) return foreign(tile->id());
  return writer_.put(std::move(*blob).take());
}

Status LayerSink::flush() { return writer_.flush(); }

Result<std::unique_ptr<lod::EncodedTile>> LayerSink::encode(const tile::TinTile& tile) const {
  auto stored = store::prepare_tile(tile);
  if (!stored) return stored.error();
  return std::unique_ptr<lod::EncodedTile>(std::make_unique<StoredBlob>(std::move(*stored)));
}

Result<tile::TinTile> LayerSink::decode(const lod::EncodedTile& tile) const {
  const StoredBlob* blob = ours(tile);
  if (blob == nullptr) return foreign(tile.id());
  return store::decode_tile(blob->stored());
}

}  // namespace tinstream::ingest
