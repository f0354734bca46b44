// libFuzzer target for the Cesium quantized-mesh encoder, fed with whatever the tile decoder
// accepts (the server encodes stored tiles on request, so a hostile or corrupt store reaches it).
//   scripts/fuzz.sh --only qmesh_fuzzer        (seeds: core/tile/fuzz/corpus)
// The input is a native tile blob (either format version); the last byte, when the blob decodes
// without it, chooses the oct-normals extension. Properties: encode never crashes and finishes
// in bounded time (libFuzzer's -timeout: the neighbour search must not be quadratic in the
// triangles around one vertex); whatever it returns parses back here as quantized-mesh-1.0
// (header, zig-zag u/v/h in 0..32767, high-water-mark indices below the vertex count, edge
// lists of valid indices, extensions of the stated length, nothing after them).
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "tinstream/terrain/quantized_mesh.hpp"
#include "tinstream/tile/codec.hpp"

namespace {

class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> b) : b_(b) {}
  template <typename T>
  T get() {
    if (b_.size() - pos_ < sizeof(T)) std::abort();
    T v;
    std::memcpy(&v, b_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void skip(std::size_t n) {
    if (b_.size() - pos_ < n) std::abort();
    pos_ += n;
  }
  void align(std::size_t a) {
    while (pos_ % a != 0) skip(1);
  }
  bool at_end() const { return pos_ == b_.size(); }

 private:
  std::span<const std::uint8_t> b_;
  std::size_t pos_ = 0;
};

std::int32_t unzigzag(std::uint16_t v) {
  return static_cast<std::int32_t>(v >> 1) ^ -static_cast<std::int32_t>(v & 1);
}

// Aborts unless `mesh` is well-formed quantized-mesh-1.0 with `extensions` extension bytes.
void check_quantized_mesh(std::span<const std::uint8_t> mesh, bool normals) {
  Reader r(mesh);
  r.skip(88);  // header: centre, heights, bounding sphere, horizon occlusion point
  const auto vertices = r.get<std::uint32_t>();
  if (vertices == 0 || vertices > (1u << 24)) std::abort();
  for (int column = 0; column < 3; ++column) {  // u, v, height: zig-zag deltas in 0..32767
    std::int32_t value = 0;
    for (std::uint32_t i = 0; i < vertices; ++i) {
      value += unzigzag(r.get<std::uint16_t>());
      if (value < 0 || value > 32767) std::abort();
    }
  }
  const bool wide = vertices > 65536;
  if (wide) r.align(4);
  const auto triangles = r.get<std::uint32_t>();
  std::uint32_t highest = 0;
  for (std::uint64_t i = 0; i < std::uint64_t{triangles} * 3; ++i) {
    const std::uint32_t code = wide ? r.get<std::uint32_t>() : r.get<std::uint16_t>();
    if (code > highest) std::abort();  // high-water mark: at most one above the highest so far
    const std::uint32_t index = highest - code;
    if (index >= vertices) std::abort();
    if (code == 0) ++highest;
  }
  for (int edge = 0; edge < 4; ++edge) {
    const auto count = r.get<std::uint32_t>();
    if (count > vertices) std::abort();
    for (std::uint32_t i = 0; i < count; ++i) {
      const std::uint32_t index = wide ? r.get<std::uint32_t>() : r.get<std::uint16_t>();
      if (index >= vertices) std::abort();
    }
  }
  if (normals) {
    if (r.get<std::uint8_t>() != 1) std::abort();
    if (r.get<std::uint32_t>() != 2 * vertices) std::abort();
    r.skip(2 * std::size_t{vertices});
  }
  if (!r.at_end()) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > (1u << 20)) return 0;
  std::span<const std::uint8_t> bytes(data, size);
  bool normals = false;
  auto tile = tinstream::tile::decode(bytes);
  if (!tile.ok() && size > 0) {
    normals = (data[size - 1] & 1) != 0;
    tile = tinstream::tile::decode(bytes.first(size - 1));
  }
  if (!tile.ok()) return 0;
  tinstream::terrain::QuantizedMeshOptions options;
  options.oct_vertex_normals = normals;
  const auto mesh = tinstream::terrain::encode_quantized_mesh(
      *tile, tinstream::geo::Projection::spherical, options);
  if (mesh.ok()) check_quantized_mesh(*mesh, normals);
  // Ellipsoidal layers are refused, never encoded.
  if (tinstream::terrain::encode_quantized_mesh(*tile, tinstream::geo::Projection::ellipsoidal)
          .ok()) {
    std::abort();
  }
  return 0;
}
