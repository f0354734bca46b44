// Private: the working memory of one finest tile (pass 3), kept by a worker from tile to tile so
// that its capacity is reused. Contents never carry over: HaloGatherer and cut_at_border clear
// what they use before use. One per thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "delaunay.hpp"
#include "tinstream/subdivide/sorted_run.hpp"

namespace tinstream::triangulate::detail {

struct TileBuffers {
  std::unordered_set<std::uint64_t> have;  // cells in S or pending (keys: pack(cx, cy))
  // Cells whose points are in S → (first, count): where their points are in pts.
  std::unordered_map<std::uint64_t, std::pair<std::size_t, std::size_t>> in_s;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pending;  // cells to gather next round
  std::vector<subdivide::SortedPoint> pts;                       // S, in gathering order
  std::vector<subdivide::SortedPoint> own;    // the tile's own records, read at once
  std::vector<subdivide::SortedPoint> chunk;  // one cell's records
  // Points of candidate cells (peek_pool[first, first + count) per cell key).
  std::unordered_map<std::uint64_t, std::pair<std::size_t, std::size_t>> peeked;
  std::vector<kernel::XY> peek_pool;
  std::vector<kernel::XY> xy;  // pts' positions (the halo), then the tile's vertices
  std::vector<IndexTriangle> tris;
  // The halo rounds' triangulation (extended round by round), then the tile's own.
  DelaunayBuilder delaunay;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> hull;   // the halo's local hull edges
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  // edges crossing the border lines

  // Gives back what one unusual tile (a huge halo) grew, so a worker's memory between tiles stays
  // that of a typical tile.
  void release_oversized() {
    constexpr std::size_t kKeepBytes = std::size_t{16} << 20;
    auto release = [](auto& v) {
      if (v.capacity() * sizeof(v[0]) > kKeepBytes) std::decay_t<decltype(v)>().swap(v);
    };
    release(pts), release(own), release(chunk), release(peek_pool), release(xy), release(tris);
    release(hull), release(edges), release(pending);
    if (delaunay.memory_bytes() > kKeepBytes) delaunay = DelaunayBuilder();
  }
};

}  // namespace tinstream::triangulate::detail
