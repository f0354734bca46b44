// Skirts as drawn: real meshes, the real renderer, OpenGL through EGL on Mesa (llvmpipe), in
// this process. Here and not in client_tests: that suite runs under ThreadSanitizer, where no
// client suite makes a GL context (Makefile TSAN_TARGETS).
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <numbers>

#include "grid_tile.hpp"
#include "offscreen_renderer.hpp"
#include "tinstream/client/render_mesh.hpp"
#include "tinstream/client/renderer.hpp"
#include "tinstream/client/skirts.hpp"

namespace tinstream::client {
namespace {

// Pixels where the sky or the globe shows (blue over green; terrain colours are never).
std::size_t background_pixels(const std::vector<std::uint8_t>& rgba) {
  std::size_t n = 0;
  for (std::size_t i = 0; i + 3 < rgba.size(); i += 4) n += rgba[i + 2] > rgba[i + 1] ? 1 : 0;
  return n;
}

TEST(Skirts, NoOpeningShowsAboveALowerChildSeenThroughMesa) {
  // The #17 gap above children, rendered (EGL on Mesa): parent P drawn without its NE quadrant,
  // child C there 100 m lower than P's surface (within their errors, 60 + 50 m). Looking
  // south-west across the cut from above C, rays that pass over C's border below P's cut edge
  // go on under P: the sky or the globe shows through, unless P's cut skirt closes the opening.
  auto offscreen = testing::open_offscreen_renderer(96);
  ASSERT_TRUE(offscreen.ok()) << offscreen.error().message;
  GlobeRenderer& gl = *offscreen->renderer;

  const geo::TileId p_id{12, 2120, 1400}, c_id{13, 4241, 2800};
  tile::TinTile p =
      tinstream::testing::make_grid_tile(p_id, 4, tinstream::testing::synthetic_height);
  tile::TinTile c = tinstream::testing::make_grid_tile(c_id, 5, [](double lon, double lat) {
    return tinstream::testing::synthetic_height(lon, lat) - 100;
  });
  p.geometric_error = 60;
  c.geometric_error = 50;
  LayerDescription layer;
  layer.max_level = 20;
  layer.min_z = 0;
  std::deque<TileMesh> meshes;
  std::deque<ResidentTile> tiles;
  std::vector<DrawItem> draws;
  for (const auto& [t, mask] :
       {std::pair{&p, std::uint8_t{0b1101}}, std::pair{&c, std::uint8_t{0xF}}}) {
    const TileKey key{TileKind::terrain, 0, t->id};
    const TileMesh& m = meshes.emplace_back(build_render_mesh(*t, layer, key));
    tiles.push_back({gl.upload(m), m.centre, m.frame, m.bounds, m.geometric_error, m.min_z, m.max_z,
                     m.quadrant_data, m.skirt_margin, m.skirt_lowest, m.skirt_spans});
    draws.push_back({key, &tiles.back(), mask});
  }
  plan_skirts(draws);

  const geo::MercatorRect r = p_id.bounds();
  const geo::LonLat centre = geo::NormalisedMercator(geo::Projection::spherical)
                                 .inverse({(r.min_x + r.max_x) / 2, (r.min_y + r.max_y) / 2});
  Camera camera(96, 96, 20);
  const double metre = 1 / 111320.0;
  camera.set_pose({centre.lon + 1300 * metre / std::cos(centre.lat * std::numbers::pi / 180),
                   centre.lat + 1300 * metre, 1800, 225, -40});
  RenderSettings settings;
  gl.render(camera, draws, settings);
  EXPECT_EQ(background_pixels(gl.read_rgba()), 0u) << "the opening above C shows";
  // The same frame without P's cut skirts (what the renderer drew before them) shows it: the
  // view does look into the opening.
  draws[0].skirt_runs.clear();
  gl.render(camera, draws, settings);
  EXPECT_GT(background_pixels(gl.read_rgba()), 0u);  // 891 of 9216 pixels when written
  for (ResidentTile& t : tiles) gl.release(t.gpu);
}

}  // namespace
}  // namespace tinstream::client
