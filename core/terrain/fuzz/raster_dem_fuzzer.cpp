// libFuzzer target for the raster-DEM renderer, fed with whatever the tile decoder accepts (the
// server renders stored tiles on request, so a hostile or corrupt store reaches it).
//   scripts/fuzz.sh --only raster_dem_fuzzer        (seeds: core/tile/fuzz/corpus)
// The input is a native tile blob; its last byte, when the blob decodes without it, picks the
// encoding, the NODATA form and a raster size of 1–64. Properties: render never crashes and
// finishes in bounded time (libFuzzer's -timeout: overlapping triangles are cut off by the work
// budget); a raster it returns has size² pixels of alpha 0 or 255, as many alpha-0 pixels as it
// reports NODATA pixels when NODATA is transparent and none when it is opaque.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "tinstream/terrain/raster_dem.hpp"
#include "tinstream/tile/codec.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace tinstream;
  std::span<const std::uint8_t> blob(data, size);
  std::uint8_t choice = 0;
  auto tile = tile::decode(blob);
  if (!tile && size > 0) {
    choice = data[size - 1];
    tile = tile::decode(blob.first(size - 1));
  }
  if (!tile) return 0;
  const auto encoding =
      (choice & 1) != 0 ? terrain::DemEncoding::mapbox : terrain::DemEncoding::terrarium;
  const auto nodata =
      (choice & 2) != 0 ? terrain::DemNodata::transparent : terrain::DemNodata::opaque;
  const std::uint32_t pixels = 1 + (choice >> 2) % 64;
  auto raster = terrain::render_raster_dem(*tile, encoding, pixels, nodata);
  if (!raster) return 0;
  if (raster->size != pixels || raster->rgba.size() != std::size_t{pixels} * pixels * 4)
    std::abort();
  std::uint64_t transparent = 0;
  for (std::size_t i = 0; i < raster->rgba.size(); i += 4) {
    const std::uint8_t a = raster->rgba[i + 3];
    if (a != 0 && a != 255) std::abort();
    transparent += a == 0 ? 1 : 0;
  }
  if (transparent != (nodata == terrain::DemNodata::transparent ? raster->nodata_pixels : 0))
    std::abort();
  return 0;
}
