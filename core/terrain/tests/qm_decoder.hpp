// An independent quantized-mesh-1.0 decoder for tests, written from the published specification
// (github.com/CesiumGS/quantized-mesh), deliberately sharing no code with the encoder.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tinstream::testing {

struct DecodedMesh {
  double centre[3];
  float min_height, max_height;
  double sphere_centre[3];
  double sphere_radius;
  double horizon_point[3];
  std::vector<std::uint16_t> u, v, h;
  std::vector<std::uint32_t> indices;  // 3 per triangle
  std::vector<std::uint32_t> west, south, east, north;
  bool wide_indices = false;
  std::optional<std::vector<std::uint8_t>> oct_normals;  // 2 per vertex
  std::size_t total_bytes = 0;
};

class ByteReader {
 public:
  explicit ByteReader(const std::vector<std::uint8_t>& b) : b_(b) {}
  void need(std::size_t n) const {
    if (pos_ + n > b_.size()) throw std::runtime_error("truncated at byte " + std::to_string(pos_));
  }
  std::uint64_t uint(int bytes) {
    need(static_cast<std::size_t>(bytes));
    std::uint64_t v = 0;
    for (int i = 0; i < bytes; ++i)
      v |= std::uint64_t{b_[pos_ + static_cast<std::size_t>(i)]} << (8 * i);
    pos_ += static_cast<std::size_t>(bytes);
    return v;
  }
  double f64() {
    const std::uint64_t bits = uint(8);
    double d;
    std::memcpy(&d, &bits, 8);
    return d;
  }
  float f32() {
    const auto bits = static_cast<std::uint32_t>(uint(4));
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
  }
  std::size_t pos() const { return pos_; }
  void skip(std::size_t n) { need(n), pos_ += n; }
  bool done() const { return pos_ == b_.size(); }

 private:
  const std::vector<std::uint8_t>& b_;
  std::size_t pos_ = 0;
};

inline DecodedMesh decode_quantized_mesh(const std::vector<std::uint8_t>& bytes) {
  DecodedMesh m;
  ByteReader r(bytes);
  for (double& c : m.centre) c = r.f64();
  m.min_height = r.f32();
  m.max_height = r.f32();
  for (double& c : m.sphere_centre) c = r.f64();
  m.sphere_radius = r.f64();
  for (double& c : m.horizon_point) c = r.f64();
  if (r.pos() != 88) throw std::runtime_error("header is not 88 bytes");

  const auto n = static_cast<std::uint32_t>(r.uint(4));
  auto unzigzag = [](std::uint32_t z) {
    return static_cast<int>(z >> 1) ^ -static_cast<int>(z & 1);
  };
  for (auto* arr : {&m.u, &m.v, &m.h}) {
    int value = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      value += unzigzag(static_cast<std::uint32_t>(r.uint(2)));
      if (value < 0 || value > 32767) throw std::runtime_error("quantised value out of range");
      arr->push_back(static_cast<std::uint16_t>(value));
    }
  }
  m.wide_indices = n > 65536;
  const int isz = m.wide_indices ? 4 : 2;
  if (r.pos() % static_cast<std::size_t>(isz) != 0)
    r.skip(static_cast<std::size_t>(isz) - r.pos() % static_cast<std::size_t>(isz));
  const auto tri_count = static_cast<std::uint32_t>(r.uint(4));
  std::uint32_t highest = 0;
  for (std::uint64_t k = 0; k < std::uint64_t{tri_count} * 3; ++k) {
    const auto code = static_cast<std::uint32_t>(r.uint(isz));
    if (code > highest) throw std::runtime_error("high-water-mark code above the mark");
    m.indices.push_back(highest - code);
    if (code == 0) ++highest;
  }
  for (auto* list : {&m.west, &m.south, &m.east, &m.north}) {
    const auto count = static_cast<std::uint32_t>(r.uint(4));
    for (std::uint32_t k = 0; k < count; ++k)
      list->push_back(static_cast<std::uint32_t>(r.uint(isz)));
  }
  while (!r.done()) {
    const auto id = static_cast<std::uint8_t>(r.uint(1));
    const auto len = static_cast<std::uint32_t>(r.uint(4));
    if (id == 1) {
      if (len != 2 * n) throw std::runtime_error("octvertexnormals length");
      std::vector<std::uint8_t> oct;
      for (std::uint32_t k = 0; k < len; ++k) oct.push_back(static_cast<std::uint8_t>(r.uint(1)));
      m.oct_normals = std::move(oct);
    } else {
      r.skip(len);
    }
  }
  m.total_bytes = bytes.size();
  return m;
}

// Inverse of Cesium's oct encoding (AttributeCompression.octDecodeInRange, 0..255).
inline void oct_decode(std::uint8_t ex, std::uint8_t ey, double out[3]) {
  double x = ex / 255.0 * 2.0 - 1.0;
  double y = ey / 255.0 * 2.0 - 1.0;
  double z = 1.0 - (std::abs(x) + std::abs(y));
  if (z < 0.0) {
    const double ox = x;
    x = (1.0 - std::abs(y)) * (ox >= 0.0 ? 1.0 : -1.0);
    y = (1.0 - std::abs(ox)) * (y >= 0.0 ? 1.0 : -1.0);
  }
  const double len = std::sqrt(x * x + y * y + z * z);
  out[0] = x / len, out[1] = y / len, out[2] = z / len;
}

}  // namespace tinstream::testing
