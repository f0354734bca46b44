// The streamer's imagery (imagery.hpp): which imagery tile each drawn terrain tile gets, the
// requests and uploads for the missing ones, and what the loader hands back. Same tiers as the
// terrain: requests go to the same loader (priority: the terrain tile's), decoded images to a RAM
// tier, textures to the GPU tier (their bytes counted against the same budget as the meshes).
#include <unordered_set>

#include "tinstream/client/imagery.hpp"
#include "tinstream/client/streamer.hpp"

namespace tinstream::client {

GpuMesh GpuUploader::upload_image(const imagery::RgbaImage& image) {
  GpuMesh g;
  g.bytes = image.pixels.size();
  return g;
}

void TileStreamer::take_image(LoadResult& r) {
  switch (r.status) {
    case LoadStatus::loaded: {
      ++imagery_counters_.loaded;
      const std::uint64_t bytes = r.image->pixels.size();
      image_ram_.insert(r.key, std::move(r.image), bytes, frame_, frame_ - 1);
      break;
    }
    case LoadStatus::absent:
      ++imagery_counters_.absent;
      absent_.insert(r.key);
      break;
    case LoadStatus::failed:
      ++imagery_counters_.failed;
      ++failures_;
      last_error_ = r.error;
      failed_[r.key] = std::chrono::steady_clock::now() + options_.failure_retry;
      break;
  }
}

void TileStreamer::drape() {
  if (!imagery_enabled_ || options_.imagery_layer < 0 ||
      static_cast<std::size_t>(options_.imagery_layer) >= layers_.size())
    return;
  const auto il = static_cast<std::uint16_t>(options_.imagery_layer);
  const LayerDescription& img = layers_[il];
  std::unordered_set<TileKey, TileKeyHash> asked;  // one request per imagery tile and frame
  for (DrawItem& d : frame_result_.draws) {
    // Another projection has another quadtree: no tile of it matches (the ramp stays).
    if (layers_[d.key.layer].projection != img.projection || d.key.tile.z < img.min_level) continue;
    geo::TileId id = d.key.tile;
    while (id.z > img.max_level) id = id.parent();
    // Up the chain: the first tile the imagery may have is asked for; the first resident one is
    // drawn (the same tile once it arrives, an ancestor meanwhile or when it is absent).
    bool wanted = false;
    for (;;) {
      const TileKey key{TileKind::imagery, il, id};
      if (img.may_contain(id) && !absent_.contains(key) && !failed_recently(key)) {
        if (const ResidentTile* t = gpu_.peek(key)) {
          gpu_.find(key);
          gpu_.pin(key, frame_);
          d.texture = t->gpu.texture;
          d.image_uv = ancestor_uv(d.key.tile, id);
          break;
        }
        if (!wanted) {
          wanted = true;
          if (image_ram_.peek(key)) {  // decoded already: only an upload
            if (asked.insert(key).second) {
              image_ram_.pin(key, frame_);
              uploads_.push_back({key, d.sse, d.distance});
            }
          } else if (!d.stand_in && asked.insert(key).second) {
            // A stand-in (drawn until its children arrive) asks for nothing: its imagery would
            // arrive for a tile soon gone (#19: 13–15 images loaded for 2 draped).
            wanted_.push_back({key, d.sse, d.distance});
            if (requested_ever_.insert(key).second) ++imagery_counters_.requested;
          }
        }
      }
      if (id.z <= img.min_level || id.z == 0) break;
      id = id.parent();
    }
  }
}

int TileStreamer::upload_image(const TileRequest& r, GpuUploader& gpu, std::uint64_t& used) {
  std::shared_ptr<const imagery::RgbaImage>* image = image_ram_.find(r.key);
  if (!image) return 0;
  const std::uint64_t bytes = (*image)->pixels.size();
  if (frame_result_.uploaded > 0 && used + bytes > options_.upload_bytes_per_frame) return -1;
  ResidentTile t;
  t.gpu = gpu.upload_image(**image);
  const std::uint64_t gpu_bytes = t.gpu.bytes;
  const auto release = [&gpu](const TileKey&, ResidentTile& e) { gpu.release(e.gpu); };
  if (!gpu_.insert(r.key, t, gpu_bytes, frame_, frame_, release)) return -1;
  used += bytes;
  ++frame_result_.uploaded;
  return 1;
}

}  // namespace tinstream::client
