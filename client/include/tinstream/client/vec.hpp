// tinstream/client/vec.hpp — the small double-precision linear algebra of the client.
//
// The client keeps every position in double-precision ECEF (metres, WGS84) and converts to float
// only after subtracting a nearby origin (a tile's centre, the camera), so these types are double.
// Mat4 is column-major (m[column][row]) as OpenGL expects when converted with to_float().
// Pure value types; thread-safe.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>

namespace tinstream::client {

struct Vec3 {
  double x = 0, y = 0, z = 0;

  friend Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
  friend Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
  friend Vec3 operator*(double s, Vec3 a) { return a * s; }
  friend Vec3 operator/(Vec3 a, double s) { return {a.x / s, a.y / s, a.z / s}; }
  Vec3& operator+=(Vec3 b) { return *this = *this + b; }
  Vec3& operator-=(Vec3 b) { return *this = *this - b; }
  friend bool operator==(const Vec3&, const Vec3&) = default;
};

inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(Vec3 a) { return std::sqrt(dot(a, a)); }
// Requires: a is not the zero vector.
inline Vec3 normalize(Vec3 a) { return a / length(a); }
inline Vec3 lerp(Vec3 a, Vec3 b, double t) { return a + (b - a) * t; }

struct Vec4 {
  double x = 0, y = 0, z = 0, w = 0;
};

struct Mat4 {
  std::array<std::array<double, 4>, 4> m{};  // m[column][row]

  static Mat4 identity() {
    Mat4 r;
    for (std::size_t i = 0; i < 4; ++i) r.m[i][i] = 1;
    return r;
  }
  friend Mat4 operator*(const Mat4& a, const Mat4& b) {
    Mat4 r;
    for (std::size_t c = 0; c < 4; ++c)
      for (std::size_t row = 0; row < 4; ++row) {
        double s = 0;
        for (std::size_t k = 0; k < 4; ++k) s += a.m[k][row] * b.m[c][k];
        r.m[c][row] = s;
      }
    return r;
  }
  friend Vec4 operator*(const Mat4& a, Vec4 v) {
    const std::array<double, 4> in{v.x, v.y, v.z, v.w};
    std::array<double, 4> out{};
    for (std::size_t row = 0; row < 4; ++row)
      for (std::size_t k = 0; k < 4; ++k) out[row] += a.m[k][row] * in[k];
    return {out[0], out[1], out[2], out[3]};
  }
  // Column-major floats for glUniformMatrix4fv (the only place doubles become floats).
  std::array<float, 16> to_float() const {
    std::array<float, 16> f{};
    for (std::size_t c = 0; c < 4; ++c)
      for (std::size_t row = 0; row < 4; ++row) f[c * 4 + row] = static_cast<float>(m[c][row]);
    return f;
  }
};

inline Mat4 translation(Vec3 t) {
  Mat4 r = Mat4::identity();
  r.m[3][0] = t.x;
  r.m[3][1] = t.y;
  r.m[3][2] = t.z;
  return r;
}

}  // namespace tinstream::client
