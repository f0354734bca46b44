// `tinstream export --store FILE --layer NAME --dir DIR`: a static Cesium terrain tree for CDN or
// plain web-server hosting, byte-for-byte what tinstream-server serves:
//
//   DIR/layer.json                 tilejson 2.1.0, quantized-mesh-1.0, scheme tms, EPSG:3857
//   DIR/{z}/{x}/{y}.terrain        gzip-compressed quantized mesh, TMS rows (y = 2^z − 1 − row)
//
// Every stored tile is written, plus flat tiles for the ancestors of the coarsest stored level
// (Cesium starts at the single level-0 tile). The .terrain files are gzip bytes: the web server
// must send them with `Content-Encoding: gzip` (see server/README-section.md for nginx).
// Only spherical-Mercator layers can be exported (ellipsoidal tiles do not match EPSG:3857).
// Runs on the main thread; memory is one tile at a time.
#include <CLI/CLI.hpp>
#include <fstream>
#include <iostream>

#include "export_cesium.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/terrain/gzip.hpp"
#include "tinstream/terrain/layer_json.hpp"
#include "tinstream/terrain/quantized_mesh.hpp"

namespace tinstream::cli {
namespace {

struct CesiumExtraOptions {
  bool no_normals = false;
};

CesiumExtraOptions& extra() {
  static CesiumExtraOptions options;  // filled by CLI11 during parsing, read by the run
  return options;
}

int fail(const std::string& message) {
  std::cerr << "tinstream export: " << message << "\n";
  return 1;
}

Status write_file(const std::filesystem::path& path, std::span<const std::uint8_t> bytes) {
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);
  if (ec) return io_error("cannot create " + path.parent_path().string() + ": " + ec.message());
  const std::filesystem::path tmp = path.string() + ".part";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    if (!out) return io_error("cannot write " + tmp.string());
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) return io_error("cannot rename " + tmp.string() + ": " + ec.message());
  return {};
}

}  // namespace

void add_cesium_dir_options(CLI::App& export_command, CesiumDirExport& /*request*/) {
  export_command.add_flag(
      "--no-normals", extra().no_normals,
      "--dir: leave out the octvertexnormals extension (smaller tiles, no lighting)");
}

int run_export_cesium_dir(const CesiumDirExport& request) {
  auto st = store::TileStore::open(request.store, store::TileStore::Mode::read_only);
  if (!st) return fail(st.error().message);
  auto info = st->layer(request.layer);
  if (!info) return fail(info.error().message);
  if (info->projection != geo::Projection::spherical) {
    return fail("layer \"" + request.layer +
                "\" uses ellipsoidal Mercator; Cesium terrain (EPSG:3857) needs a spherical layer");
  }
  auto ids = st->tile_ids(request.layer);
  if (!ids) return fail(ids.error().message);
  const bool normals = !extra().no_normals;

  std::uint64_t written = 0, bytes = 0;
  auto emit = [&](const tile::TinTile& tin) -> Status {
    auto qm = terrain::encode_quantized_mesh(tin, info->projection, {normals});
    if (!qm) return qm.error();
    const auto gz = terrain::gzip_compress(*qm);
    const auto path = request.dir / std::to_string(tin.id.z) / std::to_string(tin.id.x) /
                      (std::to_string(tin.id.tms_row()) + ".terrain");
    if (Status s = write_file(path, gz); !s) return s;
    ++written;
    bytes += gz.size();
    return {};
  };
  for (const geo::TileId& id : terrain::synthetic_tiles(*ids, info->min_level)) {
    auto filler = terrain::filler_tile(
        id, info->min_level, [&](const geo::TileId& n) { return st->read_tile(request.layer, n); });
    if (!filler) return fail(filler.error().message);
    if (Status s = emit(*filler); !s) return fail(s.error().message);
  }
  for (const geo::TileId& id : *ids) {
    auto tin = st->read_tile(request.layer, id);
    if (!tin) return fail(tin.error().message);
    if (!tin->has_value()) return fail("tile " + id.to_string() + " listed but absent");
    if (Status s = emit(**tin); !s)
      return fail("tile " + id.to_string() + ": " + s.error().message);
  }

  terrain::LayerJsonInput in;
  in.name = info->name;
  in.description = "tinstream layer " + info->name;
  in.attribution = info->attribution;
  in.version = std::to_string(info->version);
  in.bounds = info->bounds;
  in.min_level = info->min_level;
  in.max_level = info->max_level;
  in.tile_ids = std::move(*ids);
  in.oct_vertex_normals = normals;
  const std::string doc = terrain::layer_json(in);
  if (Status s =
          write_file(request.dir / "layer.json",
                     std::span(reinterpret_cast<const std::uint8_t*>(doc.data()), doc.size()));
      !s) {
    return fail(s.error().message);
  }
  std::cout << "exported " << written << " terrain tiles (" << bytes
            << " bytes gzip) and layer.json to " << request.dir.string() << "\n";
  return 0;
}

}  // namespace tinstream::cli
