// GLSL 3.30 core sources of the renderer. Variants are made by prepending #defines:
//   WIREFRAME  terrain through a geometry shader that adds barycentrics, edges darkened
//   MASKED     terrain fragments outside the quadrant mask are discarded (absent children)
//   IMAGERY    terrain coloured by its imagery tile (unlit: orthophotos carry their own light),
//              the ramp showing through transparent pixels
//   LOG_DEPTH  the fragment depth is logarithmic (drivers without glClipControl)
#pragma once

namespace tinstream::client::shaders {

inline constexpr const char* kTerrainVertex = R"(
layout(location = 0) in vec3 a_position;
layout(location = 1) in float a_height;
layout(location = 2) in vec4 a_normal;
layout(location = 3) in vec2 a_uv;
uniform mat4 u_mvp;
// Skirts: a skirt vertex (a_normal.w = 1) sits at its border vertex and goes down along the
// ellipsoid normal by u_skirt.x metres, never below the height u_skirt.y (skirts.hpp).
uniform vec3 u_centre;  // the tile's centre, ECEF (float is plenty for a direction)
uniform vec2 u_skirt;
const vec3 kGeodetic = vec3(1.0, 1.0, 1.0067394967422765);  // (1, 1, a²/b²) of WGS84
#ifdef WIREFRAME
out VS_OUT {
#else
out FS_IN {
#endif
  vec3 normal;
  float height;
  vec2 uv;
  float skirt;
  float logz;
  noperspective vec3 bary;
} vs;
void main() {
  vec3 p = a_position;
  if (a_normal.w > 0.5) {
    vec3 up = normalize((u_centre + a_position) * kGeodetic);
    p -= up * clamp(a_height - u_skirt.y, 0.0, u_skirt.x);
  }
  gl_Position = u_mvp * vec4(p, 1.0);
  vs.normal = a_normal.xyz;
  vs.height = a_height;
  vs.uv = a_uv;
  vs.skirt = a_normal.w;
  vs.logz = 1.0 + max(gl_Position.w, 0.0);
  vs.bary = vec3(1.0);
}
)";

inline constexpr const char* kTerrainGeometry = R"(
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in VS_OUT {
  vec3 normal;
  float height;
  vec2 uv;
  float skirt;
  float logz;
  noperspective vec3 bary;
} gin[];
out FS_IN {
  vec3 normal;
  float height;
  vec2 uv;
  float skirt;
  float logz;
  noperspective vec3 bary;
} gout;
void main() {
  bool skirt = gin[0].skirt > 0.5 || gin[1].skirt > 0.5 || gin[2].skirt > 0.5;
  for (int i = 0; i < 3; ++i) {
    gl_Position = gl_in[i].gl_Position;
    gout.normal = gin[i].normal;
    gout.height = gin[i].height;
    gout.uv = gin[i].uv;
    gout.skirt = gin[i].skirt;
    gout.logz = gin[i].logz;
    gout.bary = skirt ? vec3(1.0) : vec3(i == 0 ? 1.0 : 0.0, i == 1 ? 1.0 : 0.0, i == 2 ? 1.0 : 0.0);
    EmitVertex();
  }
  EndPrimitive();
}
)";

// The hypsometric ramp: the same five stops as the legend (renderer.cpp kRamp).
inline constexpr const char* kTerrainFragment = R"(
in FS_IN {
  vec3 normal;
  float height;
  vec2 uv;
  float skirt;
  float logz;
  noperspective vec3 bary;
} fs;
uniform vec3 u_light;
uniform vec2 u_ramp;
uniform int u_mask;
uniform float u_log_coef;
uniform vec3 u_stops[5];
#ifdef IMAGERY
uniform sampler2D u_image;
uniform vec4 u_image_uv;  // scale, offset of the tile's uv in the image (imagery.hpp)
#endif
out vec4 o_color;
vec3 ramp(float t) {
  float s = t * 4.0;
  int i = int(min(floor(s), 3.0));
  return mix(u_stops[i], u_stops[i + 1], s - float(i));
}
void main() {
#ifdef MASKED
  int q = (fs.uv.y >= 0.5 ? 2 : 0) + (fs.uv.x >= 0.5 ? 1 : 0);
  if ((u_mask & (1 << q)) == 0) discard;
#endif
  vec3 n = normalize(fs.normal);
  float t = clamp((fs.height - u_ramp.x) / max(u_ramp.y - u_ramp.x, 1e-6), 0.0, 1.0);
  float shade = 0.3 + 0.7 * max(dot(n, u_light), 0.0);
  vec3 c = ramp(t) * shade;
#ifdef IMAGERY
  vec4 image = texture(u_image, fs.uv * u_image_uv.xy + u_image_uv.zw);
  c = mix(c, image.rgb, image.a);
#endif
#ifdef WIREFRAME
  float d = min(min(fs.bary.x, fs.bary.y), fs.bary.z);
  float line = 1.0 - smoothstep(0.0, 1.5 * fwidth(d), d);
#ifdef IMAGERY
  c = mix(c, vec3(0.95, 0.95, 0.90), 0.6 * line);  // light lines show on dark orthophotos
#else
  c = mix(c, vec3(0.04, 0.04, 0.05), 0.85 * line);
#endif
#endif
  o_color = vec4(c, 1.0);
#ifdef LOG_DEPTH
  gl_FragDepth = log2(fs.logz) * u_log_coef;
#endif
}
)";

inline constexpr const char* kGlobeVertex = R"(
layout(location = 0) in vec3 a_position;
layout(location = 2) in vec4 a_normal;
layout(location = 3) in vec2 a_uv;
uniform mat4 u_mvp;
out vec3 v_normal;
out vec2 v_lonlat;
out float v_logz;
void main() {
  gl_Position = u_mvp * vec4(a_position, 1.0);
  v_normal = a_normal.xyz;
  v_lonlat = vec2(a_uv.x * 360.0 - 180.0, 90.0 - a_uv.y * 180.0);
  v_logz = 1.0 + max(gl_Position.w, 0.0);
}
)";

// Ocean blue, lit from above the camera, with a 10° graticule.
inline constexpr const char* kGlobeFragment = R"(
in vec3 v_normal;
in vec2 v_lonlat;
in float v_logz;
uniform vec3 u_sun;
uniform float u_log_coef;
out vec4 o_color;
float grid(float v) {
  float d = abs(fract(v / 10.0 + 0.5) - 0.5) * 10.0;
  return 1.0 - clamp(d / max(fwidth(v), 1e-6), 0.0, 1.0);
}
void main() {
  float shade = 0.55 + 0.45 * max(dot(normalize(v_normal), u_sun), 0.0);
  vec3 c = vec3(0.13, 0.24, 0.45) * shade;
  float line = max(grid(v_lonlat.x), grid(v_lonlat.y));
  c = mix(c, vec3(0.32, 0.46, 0.72), 0.6 * line);
  o_color = vec4(c, 1.0);
#ifdef LOG_DEPTH
  gl_FragDepth = log2(v_logz) * u_log_coef;
#endif
}
)";

inline constexpr const char* kOverlayVertex = R"(
layout(location = 0) in vec2 a_position;
layout(location = 1) in vec2 a_uv;
layout(location = 2) in vec4 a_color;
uniform mat4 u_projection;
out vec2 v_uv;
out vec4 v_color;
void main() {
  v_uv = a_uv;
  v_color = a_color;
  gl_Position = u_projection * vec4(a_position, 0.0, 1.0);
}
)";

inline constexpr const char* kOverlayFragment = R"(
in vec2 v_uv;
in vec4 v_color;
uniform sampler2D u_texture;
out vec4 o_color;
void main() { o_color = v_color * texture(u_texture, v_uv); }
)";

}  // namespace tinstream::client::shaders
