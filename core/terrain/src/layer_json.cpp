#include "tinstream/terrain/layer_json.hpp"

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>

namespace tinstream::terrain {

std::vector<TileRange> merge_ranges(std::vector<geo::TileId> tiles) {
  std::vector<TileRange> done;
  if (tiles.empty()) return done;
  // Sort by TMS row, then column; drop duplicates.
  for (auto& t : tiles) t.y = t.tms_row();
  std::sort(tiles.begin(), tiles.end(), [](const geo::TileId& a, const geo::TileId& b) {
    return std::tie(a.y, a.x) < std::tie(b.y, b.x);
  });
  tiles.erase(std::unique(tiles.begin(), tiles.end()), tiles.end());

  // Runs per row, then extend rectangles of the previous row whose x-span matches exactly.
  std::map<std::pair<std::uint32_t, std::uint32_t>, TileRange> open;  // (start_x, end_x) → rect
  std::size_t i = 0;
  while (i < tiles.size()) {
    const std::uint32_t row = tiles[i].y;
    std::map<std::pair<std::uint32_t, std::uint32_t>, TileRange> next;
    while (i < tiles.size() && tiles[i].y == row) {
      const std::uint32_t start = tiles[i].x;
      std::uint32_t end = start;
      ++i;
      while (i < tiles.size() && tiles[i].y == row && tiles[i].x == end + 1) end = tiles[i++].x;
      const auto key = std::make_pair(start, end);
      auto it = open.find(key);
      if (it != open.end() && it->second.end_y + 1 == row) {
        TileRange r = it->second;
        r.end_y = row;
        next[key] = r;
        open.erase(it);
      } else {
        next[key] = TileRange{start, row, end, row};
      }
    }
    for (auto& [key, r] : open) done.push_back(r);
    open = std::move(next);
  }
  for (auto& [key, r] : open) done.push_back(r);
  std::sort(done.begin(), done.end(), [](const TileRange& a, const TileRange& b) {
    return std::tie(a.start_y, a.start_x) < std::tie(b.start_y, b.start_x);
  });
  return done;
}

bool is_filler(std::uint32_t z, std::uint32_t min_level, bool over_data) {
  return z < kWholeLevels || (z < min_level && over_data);
}

bool may_be_filler(const geo::TileId& id, std::uint32_t min_level,
                   const geo::MercatorRect& data_bounds) {
  const geo::MercatorRect r = id.bounds();
  // Closed rectangles: sharing a point is enough.
  const bool overlaps = r.min_x <= data_bounds.max_x && data_bounds.min_x <= r.max_x &&
                        r.min_y <= data_bounds.max_y && data_bounds.min_y <= r.max_y;
  return is_filler(id.z, min_level, overlaps);
}

std::vector<geo::TileId> synthetic_tiles(const std::vector<geo::TileId>& stored,
                                         std::uint32_t min_level) {
  std::vector<geo::TileId> out;
  // Over the data: the ancestors of the stored tiles of min_level.
  for (geo::TileId id : stored) {
    if (id.z < min_level) continue;
    while (id.z > min_level) id = id.parent();
    while (id.z > 0) {
      id = id.parent();
      if (is_filler(id.z, min_level, true)) out.push_back(id);
    }
  }
  // Whatever the data: the whole levels.
  for (std::uint32_t z = 0; is_filler(z, min_level, false); ++z) {
    const std::uint32_t n = 1u << z;
    for (std::uint32_t y = 0; y < n; ++y) {
      for (std::uint32_t x = 0; x < n; ++x) out.push_back(*geo::TileId::from_zxy(z, x, y));
    }
  }
  std::vector<geo::TileId> sorted_stored = stored;
  std::sort(sorted_stored.begin(), sorted_stored.end());
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  std::erase_if(out, [&](const geo::TileId& id) {
    return std::binary_search(sorted_stored.begin(), sorted_stored.end(), id);
  });
  return out;
}

std::string layer_json(const LayerJsonInput& in) {
  using nlohmann::json;
  // A corrupt layer row may say min_level > max_level: by_level is sized by max_level, so the
  // ancestors must stay above it.
  const std::uint32_t min_level = std::min(in.min_level, in.max_level);
  // The whole levels are listed even above a layer whose finest level is 0.
  const std::uint32_t top = std::max(in.max_level, kWholeLevels - 1);
  std::vector<std::vector<geo::TileId>> by_level(top + 1);
  for (const auto& id : in.tile_ids) {
    if (id.z <= in.max_level && id.z >= min_level) by_level[id.z].push_back(id);
  }
  for (const auto& id : synthetic_tiles(in.tile_ids, min_level)) {
    if (id.z <= top) by_level[id.z].push_back(id);
  }
  json available = json::array();
  for (std::uint32_t z = 0; z <= top; ++z) {
    json level = json::array();
    for (const TileRange& r : merge_ranges(std::move(by_level[z]))) {
      level.push_back(
          {{"startX", r.start_x}, {"startY", r.start_y}, {"endX", r.end_x}, {"endY", r.end_y}});
    }
    available.push_back(std::move(level));
  }
  json doc = {
      {"tilejson", "2.1.0"},
      {"name", in.name},
      {"description", in.description},
      {"version", in.version},
      {"format", "quantized-mesh-1.0"},
      {"attribution", in.attribution},
      {"scheme", "tms"},
      {"tiles", json::array({"{z}/{x}/{y}.terrain?v={version}"})},
      {"projection", "EPSG:3857"},
      {"bounds", {in.bounds.west, in.bounds.south, in.bounds.east, in.bounds.north}},
      {"minzoom", 0},
      {"maxzoom", top},
      {"extensions", in.oct_vertex_normals ? json::array({"octvertexnormals"}) : json::array()},
      {"available", std::move(available)},
  };
  return doc.dump(2);
}

}  // namespace tinstream::terrain
