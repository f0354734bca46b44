// What pass 4 hands from one level to the next beside the stored tiles (lod_tile.hpp): each
// tile's per-triangle error bounds and its witnesses, serialised, in one append-only scratch file
// per level (or in memory), kept until the pyramid is built (pyramid.hpp: any coarser level may
// read a level's records). Never published: it only lives while the pyramid is built.
//
//   record  = u32 triangles, triangles × (f32 above, f32 below),
//             u32 reaches, reaches × (u32 triangle, f64 reach),
//             u32 witnesses, witnesses × (f64 x, y, z, weight)       (host byte order)
//
// Threads: one thread (the pyramid's calling thread, which also owns the LayerWriter).
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/lod/lod_tile.hpp"

namespace tinstream::lod::detail {

// The side data of `tile` as a record, and back (a record from encode_side, for `triangles`).
std::vector<std::uint8_t> encode_side(const LodTile& tile);
Status decode_side(std::span<const std::uint8_t> record, LodTile& tile);

class SideStore {
 public:
  // `dir` empty: records stay in memory; otherwise files there, removed by forget_level and on
  // destruction.
  explicit SideStore(std::filesystem::path dir) : dir_(std::move(dir)) {}
  SideStore(const SideStore&) = delete;
  SideStore& operator=(const SideStore&) = delete;
  ~SideStore();

  Status put(const geo::TileId& id, std::vector<std::uint8_t> record);
  // The record of `id`, or nullopt when none was put (an unreduced finest tile).
  Result<std::optional<std::vector<std::uint8_t>>> get(const geo::TileId& id);
  // Forgets the records of a level that no level needs any more (frees memory, removes its file).
  void forget_level(std::uint32_t z);

 private:
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  struct LevelFile {
    std::filesystem::path path;
    std::unique_ptr<std::FILE, Closer> file;
    std::uint64_t end = 0;
  };
  Result<LevelFile*> file_of(std::uint32_t z);

  std::filesystem::path dir_;
  std::map<std::uint32_t, LevelFile> files_;
  std::map<geo::TileId, std::pair<std::uint64_t, std::uint64_t>> index_;  // offset, size
  std::map<geo::TileId, std::vector<std::uint8_t>> memory_;
};

}  // namespace tinstream::lod::detail
