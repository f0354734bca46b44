// tinstream/store/tile_store.hpp — the SQLite tile store (docs/DESIGN.md §4; schema in
// docs/store-format.md).
//
// One SQLite file holds any number of layers. A layer is a named, published *version*; tiles are
// immutable zlib-compressed blobs (tile/codec.hpp) keyed by (version, z, x, y). An ingest writes a
// new version through a LayerWriter in batched transactions; nothing of it is visible to
// readers until publish(), which switches the layer to the new version in one transaction and
// drops the old one. A crash or kill at any point leaves the previously published state intact and
// readable (WAL mode); the abandoned version is garbage-collected by the next writer.
//
// Threads: a TileStore owns one SQLite connection and must be used by one thread at a time.
// Several TileStore objects (one per server worker thread, say) may open the same file
// concurrently, readers alongside one writer (WAL). A LayerWriter belongs to the TileStore that
// made it and must not outlive it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/mercator.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::store {

struct LayerInfo {
  std::string name;  // [A-Za-z0-9_.-]{1,64}
  geo::Projection projection = geo::Projection::spherical;
  std::string vertical_datum = "ellipsoidal";  // heights are ellipsoidal after ingest; this names
                                               // the datum the sources were converted from
  geo::MercatorRect mercator_bounds{};         // of the data
  geo::LonLatRect bounds{};                    // of the data, degrees
  std::uint32_t min_level = 0;
  std::uint32_t max_level = 0;   // the finest level L
  std::uint32_t max_points = 0;  // per-tile budget used
  std::uint64_t tile_count = 0;
  std::uint64_t point_count = 0;    // distinct points at the finest level
  std::uint64_t source_points = 0;  // points read from the sources
  double min_z = 0, max_z = 0;
  std::vector<double> level_max_error;  // index z: max geometric error of level z tiles
  std::string options_json = "{}";      // ingest options used, as JSON
  std::string attribution;
  std::int64_t created_unix = 0;  // seconds; set by publish()
  std::int64_t version = 0;       // set by the store
};

// A tile as stored: compressed bytes plus what a server needs without decoding.
struct StoredTile {
  geo::TileId id;
  std::vector<std::uint8_t> compressed;  // zlib (RFC 1950) of the encoded tile
  std::string etag;                      // strong, quoted, content-derived: "\"…\""
  double min_z = 0, max_z = 0;
  double geometric_error = 0;
  std::uint32_t vertex_count = 0;
  std::uint32_t triangle_count = 0;
};

// The CPU-heavy part of LayerWriter::put() — encoding, compression, the entity tag — without the
// store: thread-safe, so workers prepare tiles in parallel and one thread puts them.
Result<StoredTile> prepare_tile(const tile::TinTile& tile);
// Decompresses and decodes a stored blob and checks that it holds tile `stored.id` (thread-safe,
// no store needed). Errors say what is wrong with the blob, not where it came from.
Result<tile::TinTile> decode_tile(const StoredTile& stored);

// An imagery layer: 8-bit colour tiles of the same quadtree, stored apart from the terrain layers
// (docs/store-format.md, "Imagery"). An imagery layer may share its name with a terrain layer
// (the web viewer drapes it over that terrain); each is published and replaced on its own.
struct ImageryInfo {
  std::string name;  // [A-Za-z0-9_.-]{1,64}
  geo::Projection projection = geo::Projection::spherical;
  std::string format = "png";           // of every tile blob: "png", "jpeg" or "webp"
  std::uint32_t tile_size = 256;        // pixels per side
  geo::MercatorRect mercator_bounds{};  // of the source footprint
  geo::LonLatRect bounds{};             // of the source footprint, degrees
  std::uint32_t min_level = 0;
  std::uint32_t max_level = 0;      // the level of the sources' native resolution
  std::uint64_t tile_count = 0;     // counted by publish
  std::string options_json = "{}";  // ingest options used, as JSON
  std::string attribution;
  std::int64_t created_unix = 0;  // seconds; set by publish()
  std::int64_t version = 0;       // set by the store
};

// An imagery tile as stored: the encoded image (`format` of its layer) and its entity tag.
struct StoredImage {
  geo::TileId id;
  std::vector<std::uint8_t> data;
  std::string etag;  // strong, quoted, content-derived (make_etag): set by ImageryWriter::put
};

class LayerWriter;
class ImageryWriter;

class TileStore {
 public:
  enum class Mode { read_only, read_write };

  // read_write creates the file and schema when absent. Errors name the path.
  static Result<TileStore> open(const std::filesystem::path& path, Mode mode);

  TileStore(TileStore&&) noexcept;
  TileStore& operator=(TileStore&&) noexcept;
  ~TileStore();

  const std::filesystem::path& path() const;

  // Published layers only.
  Result<std::vector<LayerInfo>> layers();
  Result<LayerInfo> layer(std::string_view name);  // not_found when absent
  Result<std::optional<StoredTile>> tile(std::string_view layer, const geo::TileId& id);
  Result<std::optional<tile::TinTile>> read_tile(std::string_view layer, const geo::TileId& id);
  // Tile ids of a layer, optionally of one level, in (z, x, y) order.
  Result<std::vector<geo::TileId>> tile_ids(std::string_view layer,
                                            std::optional<std::uint32_t> level = std::nullopt);

  // Starts a new, invisible version of layer `info.name` (which may or may not exist yet).
  // One writer per layer: fails (invalid_argument) while another live process or LayerWriter is
  // building the same layer; versions left by dead writers are deleted here.
  Result<std::unique_ptr<LayerWriter>> begin_layer(const LayerInfo& info);
  // Removes a published layer and its tiles. not_found when absent.
  Status delete_layer(std::string_view name);

  // Imagery layers (published only): the same contract as the terrain calls above, on tables of
  // their own, so writing or deleting imagery never touches a terrain layer, and back. A store
  // written before imagery existed simply has none.
  Result<std::vector<ImageryInfo>> imagery_layers();
  Result<ImageryInfo> imagery_layer(std::string_view name);  // not_found when absent
  Result<std::optional<StoredImage>> imagery_tile(std::string_view layer, const geo::TileId& id);
  Result<std::vector<geo::TileId>> imagery_tile_ids(
      std::string_view layer, std::optional<std::uint32_t> level = std::nullopt);
  // One writer per imagery layer at a time, as begin_layer.
  Result<std::unique_ptr<ImageryWriter>> begin_imagery(const ImageryInfo& info);
  Status delete_imagery(std::string_view name);  // not_found when absent

  struct Impl;

 private:
  explicit TileStore(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  friend class LayerWriter;
};

// Writes one new layer version. Single-threaded. put() batches tiles in memory (256 tiles or
// 8 MiB) and writes each batch in one short transaction, so the file's write lock is never held
// while the caller computes; tiles still in memory are lost if the process dies (the version is
// unpublished then anyway).
class LayerWriter {
 public:
  ~LayerWriter();  // abandons the version unless published

  // Encodes, compresses and stores a tile (replacing one with the same id in this version).
  Status put(const tile::TinTile& tile);
  // Stores a tile made by prepare_tile() (the same as put() of the tile it was prepared from).
  Status put(StoredTile&& tile);
  // Writes the tiles batched in memory now. put() and publish() flush by themselves; a failed
  // flush (e.g. the file stayed locked past the busy timeout) keeps the batch for a retry.
  Status flush();
  // Reads back a tile written to this (unpublished) version, e.g. children for the LOD pass.
  Result<std::optional<tile::TinTile>> get(const geo::TileId& id);
  // The same tile still compressed, for decode_tile() on another thread.
  Result<std::optional<StoredTile>> get_stored(const geo::TileId& id);
  Result<std::vector<geo::TileId>> tile_ids(std::optional<std::uint32_t> level = std::nullopt);
  // Makes the version the layer's published one, atomically; `info` replaces the metadata given
  // to begin_layer (counts, bounds, errors are known only at the end). `info.name` must be the
  // writer's layer; tile_count is counted by the store and created_unix set to now.
  Status publish(const LayerInfo& info);
  // Drops the version and its tiles.
  void abandon();

  struct Impl;
  explicit LayerWriter(std::unique_ptr<Impl> impl);

 private:
  std::unique_ptr<Impl> impl_;
};

// Writes one new imagery version; the LayerWriter contract (batched transactions, invisible until
// publish, abandoned when destroyed unpublished). Single-threaded.
class ImageryWriter {
 public:
  ~ImageryWriter();

  // Stores an encoded tile (replacing one with the same id in this version); sets its ETag.
  Status put(StoredImage&& tile);
  Status flush();
  Result<std::optional<StoredImage>> get(const geo::TileId& id);
  // Makes the version the layer's published imagery, atomically; `info` replaces the metadata
  // given to begin_imagery, tile_count is counted, created_unix set to now.
  Status publish(const ImageryInfo& info);
  void abandon();

  struct Impl;
  explicit ImageryWriter(std::unique_ptr<Impl> impl);

 private:
  std::unique_ptr<Impl> impl_;
};

// Layer names: 1–64 characters from [A-Za-z0-9_.-], not starting with '.'.
Status validate_layer_name(std::string_view name);

}  // namespace tinstream::store
