// A minimal LAS writer for tests, written from the ASPRS LAS 1.4 R15 tables (not from the
// reader), so that reader and writer cannot share a layout mistake silently.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace tinstream::sources::testing {

struct TestPoint {
  std::int32_t X = 0, Y = 0, Z = 0;
  std::uint8_t cls = 1;
  bool withheld = false;
};

struct TestVlr {
  std::string user_id = "LASF_Projection";
  std::uint16_t record_id = 0;
  std::vector<unsigned char> body;
};

struct LasSpec {
  std::uint8_t minor = 2;
  std::uint8_t format = 0;
  std::uint16_t extra_bytes = 0;  // appended to every record
  double scale[3] = {0.01, 0.01, 0.01};
  double offset[3] = {1000, 2000, 0};
  std::vector<TestPoint> points;
  std::vector<TestVlr> vlrs;
  std::vector<TestVlr> evlrs;      // LAS 1.4 only
  bool legacy_count_zero = false;  // 1.4: leave the legacy 32-bit count at 0
};

inline constexpr std::uint16_t kFormatLength[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

inline void put(std::vector<unsigned char>& b, std::size_t at, const void* src, std::size_t n) {
  if (b.size() < at + n) b.resize(at + n);
  std::memcpy(b.data() + at, src, n);  // tests run on little-endian hosts
}
template <typename T>
void put_value(std::vector<unsigned char>& b, std::size_t at, T v) {
  static_assert(std::endian::native == std::endian::little);
  put(b, at, &v, sizeof v);
}

inline std::vector<unsigned char> build_las(const LasSpec& s) {
  const std::uint16_t header_size = s.minor >= 4 ? 375 : (s.minor == 3 ? 235 : 227);
  const std::uint16_t record_length =
      static_cast<std::uint16_t>(kFormatLength[s.format] + s.extra_bytes);
  std::vector<unsigned char> b(header_size, 0);
  std::memcpy(b.data(), "LASF", 4);
  b[24] = 1;
  b[25] = s.minor;
  std::memcpy(b.data() + 26, "tinstream test", 14);
  put_value<std::uint16_t>(b, 94, header_size);
  std::size_t vlr_bytes = 0;
  for (const auto& v : s.vlrs) vlr_bytes += 54 + v.body.size();
  const auto offset = static_cast<std::uint32_t>(header_size + vlr_bytes);
  put_value<std::uint32_t>(b, 96, offset);
  put_value<std::uint32_t>(b, 100, static_cast<std::uint32_t>(s.vlrs.size()));
  b[104] = s.format;
  put_value<std::uint16_t>(b, 105, record_length);
  const auto n = static_cast<std::uint32_t>(s.points.size());
  put_value<std::uint32_t>(b, 107, s.legacy_count_zero ? 0u : n);
  for (std::size_t i = 0; i < 3; ++i) {
    put_value<double>(b, 131 + 8 * i, s.scale[i]);
    put_value<double>(b, 155 + 8 * i, s.offset[i]);
  }
  // Bounds: max x, min x, max y, min y, max z, min z.
  if (!s.points.empty()) {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (const auto& p : s.points) {
      const std::int32_t v[3] = {p.X, p.Y, p.Z};
      for (int a = 0; a < 3; ++a) {
        const double d = v[a] * s.scale[a] + s.offset[a];
        lo[a] = std::min(lo[a], d);
        hi[a] = std::max(hi[a], d);
      }
    }
    for (std::size_t a = 0; a < 3; ++a) {
      put_value<double>(b, 179 + 16 * a, hi[a]);
      put_value<double>(b, 187 + 16 * a, lo[a]);
    }
  }
  for (const auto& v : s.vlrs) {
    std::vector<unsigned char> h(54, 0);
    std::memcpy(h.data() + 2, v.user_id.data(), std::min<std::size_t>(16, v.user_id.size()));
    put_value<std::uint16_t>(h, 18, v.record_id);
    put_value<std::uint16_t>(h, 20, static_cast<std::uint16_t>(v.body.size()));
    b.insert(b.end(), h.begin(), h.end());
    b.insert(b.end(), v.body.begin(), v.body.end());
  }
  for (const auto& p : s.points) {
    std::vector<unsigned char> r(record_length, 0);
    put_value<std::int32_t>(r, 0, p.X);
    put_value<std::int32_t>(r, 4, p.Y);
    put_value<std::int32_t>(r, 8, p.Z);
    if (s.format <= 5) {
      r[15] = static_cast<unsigned char>((p.cls & 0x1f) | (p.withheld ? 0x80 : 0));
    } else {
      r[15] = p.withheld ? 0x04 : 0;
      r[16] = p.cls;
    }
    b.insert(b.end(), r.begin(), r.end());
  }
  if (s.minor >= 4) {
    put_value<std::uint64_t>(b, 247, s.points.size());
    if (!s.evlrs.empty()) {
      put_value<std::uint64_t>(b, 235, b.size());
      put_value<std::uint32_t>(b, 243, static_cast<std::uint32_t>(s.evlrs.size()));
      for (const auto& v : s.evlrs) {
        std::vector<unsigned char> h(60, 0);
        std::memcpy(h.data() + 2, v.user_id.data(), std::min<std::size_t>(16, v.user_id.size()));
        put_value<std::uint16_t>(h, 18, v.record_id);
        put_value<std::uint64_t>(h, 20, v.body.size());
        b.insert(b.end(), h.begin(), h.end());
        b.insert(b.end(), v.body.begin(), v.body.end());
      }
    }
  }
  return b;
}

inline std::vector<unsigned char> text_body(const std::string& s) {
  std::vector<unsigned char> v(s.begin(), s.end());
  v.push_back(0);
  return v;
}

// GeoKeyDirectory body with SHORT keys {id, value}.
inline std::vector<unsigned char> geokey_body(
    const std::vector<std::pair<std::uint16_t, std::uint16_t>>& keys) {
  std::vector<unsigned char> b;
  auto push16 = [&](std::uint16_t v) {
    b.push_back(static_cast<unsigned char>(v & 0xff));
    b.push_back(static_cast<unsigned char>(v >> 8));
  };
  push16(1);
  push16(1);
  push16(0);
  push16(static_cast<std::uint16_t>(keys.size()));
  for (auto [id, value] : keys) {
    push16(id);
    push16(0);
    push16(1);
    push16(value);
  }
  return b;
}

inline void write_file(const std::filesystem::path& p, const std::vector<unsigned char>& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

// A fresh, empty directory for one test.
inline std::filesystem::path scratch_dir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("tinstream_sources_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace tinstream::sources::testing
