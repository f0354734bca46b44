// tinstream/lod/tile_sink.hpp — where pass 4 reads its finest level and writes the levels above.
//
// build_pyramid (pyramid.hpp) knows no store: it lists a level's tiles, reads a tile back and
// writes one through a TileSink, and leaves the tile's encoded form to it. The ingest's sink is
// the unpublished layer version of the SQLite store (ingest/layer_sink.hpp); a test may keep the
// tiles in memory.
//
// Encoded tiles: what the sink stores (for the store, the compressed blob with its entity tag).
// The pyramid moves them between its threads and reads only id, error and vertex count; encoding
// and decoding run on its workers, reading and writing on the calling thread.
//
// Threads: tile_ids, get, put and flush are called on the thread that called build_pyramid only;
// encode and decode on any thread, concurrently (they must not touch what put writes).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

// A tile in the sink's encoded form, made by TileSink::encode or read by TileSink::get.
class EncodedTile {
 public:
  EncodedTile() = default;
  EncodedTile(const EncodedTile&) = delete;
  EncodedTile& operator=(const EncodedTile&) = delete;
  virtual ~EncodedTile() = default;

  virtual const geo::TileId& id() const = 0;
  virtual double geometric_error() const = 0;
  virtual std::uint32_t vertex_count() const = 0;
};

class TileSink {
 public:
  TileSink() = default;
  TileSink(const TileSink&) = delete;
  TileSink& operator=(const TileSink&) = delete;
  virtual ~TileSink() = default;

  // The ids of the tiles of `level` (any order).
  virtual Result<std::vector<geo::TileId>> tile_ids(std::uint32_t level) = 0;
  // Tile `id` as written (or there before the pyramid started); null when there is none. A
  // tile put is readable by the next get, flushed or not.
  virtual Result<std::unique_ptr<EncodedTile>> get(const geo::TileId& id) = 0;
  // Writes (or replaces) a tile made by this sink's encode.
  virtual Status put(std::unique_ptr<EncodedTile> tile) = 0;
  // Writes what put may have buffered; the pyramid calls it after each level.
  virtual Status flush() = 0;

  // Thread-safe codec. decode must give back the tile that encode was given (and check that an
  // encoded tile holds its id); errors say what is wrong with the tile, not where it came from.
  virtual Result<std::unique_ptr<EncodedTile>> encode(const tile::TinTile& tile) const = 0;
  virtual Result<tile::TinTile> decode(const EncodedTile& tile) const = 0;
};

}  // namespace tinstream::lod
