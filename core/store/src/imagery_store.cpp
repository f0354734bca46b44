// The imagery tables of the tile store: imagery_versions, imagery_layers, imagery_tiles
// (schema.cpp, docs/store-format.md "Imagery").
//
// The same protocol as the terrain tables (tile_store.cpp's invariants 1–3), on tables of their
// own: an imagery layer is visible iff imagery_layers has a row for it, that row names a 'ready'
// imagery version, and publish switches it in one transaction. No statement here reads or writes
// a terrain table, so imagery and terrain layers are replaced independently.

#include <cmath>
#include <nlohmann/json.hpp>

#include "schema.hpp"
#include "store_impl.hpp"
#include "tinstream/store/etag.hpp"

namespace tinstream::store {

namespace {

bool known_format(std::string_view f) { return f == "png" || f == "jpeg" || f == "webp"; }

Status validate_imagery_info(const ImageryInfo& info) {
  if (Status s = validate_layer_name(info.name); !s) return s;
  const std::string layer = "imagery layer '" + info.name + "': ";
  if (!known_format(info.format)) {
    return invalid_argument(layer + "format '" + info.format + "' is not png, jpeg or webp");
  }
  if (info.tile_size < 16 || info.tile_size > 4096) {
    return invalid_argument(layer + "tile size " + std::to_string(info.tile_size) +
                            " is outside 16–4096 pixels");
  }
  if (info.max_level > static_cast<std::uint32_t>(geo::kMaxLevel) ||
      info.min_level > info.max_level) {
    return invalid_argument(layer + "levels must satisfy min ≤ max ≤ " +
                            std::to_string(geo::kMaxLevel));
  }
  if (!finite_bounds(info.mercator_bounds, info.bounds)) {
    return invalid_argument(layer + "non-finite bounds");
  }
  if (!nlohmann::json::accept(info.options_json)) {
    return invalid_argument(layer + "options are not valid JSON");
  }
  return {};
}

// Columns of imagery_versions read into an ImageryInfo, in this order, by read_imagery_info().
constexpr const char* kImageryColumns =
    "v.id, v.name, v.projection, v.format, v.tile_size, v.min_x, v.min_y, v.max_x, v.max_y, "
    "v.west, v.south, v.east, v.north, v.min_level, v.max_level, v.tile_count, v.options, "
    "v.attribution, v.created_unix";

Result<ImageryInfo> read_imagery_info(const Query& q, const std::filesystem::path& path) {
  ImageryInfo i;
  i.version = q.i64(0);
  i.name = q.text(1);
  const auto projection = geo::parse_projection(q.text(2));
  if (!projection) {
    return corrupt_data(path.string() + ": imagery layer '" + i.name +
                        "': " + projection.error().message);
  }
  i.projection = *projection;
  i.format = q.text(3);
  i.tile_size = q.u32(4);
  read_bounds(q, 5, i.mercator_bounds, i.bounds);
  i.min_level = q.u32(13);
  i.max_level = q.u32(14);
  i.tile_count = q.u64(15);
  i.options_json = q.text(16);
  i.attribution = q.text(17);
  i.created_unix = q.i64(18);
  return i;
}

Error no_imagery(const std::filesystem::path& path, std::string_view name) {
  return not_found(path.string() + ": no imagery layer '" + std::string(name) + "'");
}

}  // namespace

Result<bool> TileStore::Impl::has_imagery_tables() {
  if (imagery_tables) return true;
  auto q = query(
      "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN "
      "('imagery_versions', 'imagery_layers', 'imagery_tiles')");
  if (!q) return q.error();
  if (q->step() != SQLITE_ROW) return sql_error("reading the schema");
  imagery_tables = q->i64(0) == 3;
  return imagery_tables;
}

Status TileStore::Impl::create_imagery_tables() {
  auto present = has_imagery_tables();
  if (!present) return present.error();
  if (*present) return {};
  Status s = transaction("adding the imagery tables", [&]() -> Status {
    return exec(schema::imagery_create_sql().c_str(), "adding the imagery tables");
  });
  if (s) imagery_tables = true;
  return s;
}

Status TileStore::Impl::drop_imagery_version(std::int64_t version) {
  auto tiles = query("DELETE FROM imagery_tiles WHERE version = ?1");
  if (!tiles) return tiles.error();
  tiles->bind(1, version);
  if (!done(*tiles)) {
    return sql_error("deleting the tiles of imagery version " + std::to_string(version));
  }
  auto row = query("DELETE FROM imagery_versions WHERE id = ?1");
  if (!row) return row.error();
  row->bind(1, version);
  if (!done(*row)) return sql_error("deleting imagery version " + std::to_string(version));
  return {};
}

// ---------------------------------------------------------------------------------------------
// Readers

Result<std::vector<ImageryInfo>> TileStore::imagery_layers() {
  auto present = impl_->has_imagery_tables();
  if (!present) return present.error();
  if (!*present) return std::vector<ImageryInfo>();
  static const std::string sql =
      std::string("SELECT ") + kImageryColumns +
      " FROM imagery_layers AS l JOIN imagery_versions AS v ON v.id = l.version ORDER BY l.name";
  auto q = impl_->query(sql.c_str());
  if (!q) return q.error();
  std::vector<ImageryInfo> out;
  int rc = 0;
  while ((rc = q->step()) == SQLITE_ROW) {
    auto info = read_imagery_info(*q, impl_->path);
    if (!info) return info.error();
    out.push_back(std::move(*info));
  }
  if (rc != SQLITE_DONE) return impl_->sql_error("listing imagery layers");
  return out;
}

Result<ImageryInfo> TileStore::imagery_layer(std::string_view name) {
  if (Status s = validate_layer_name(name); !s) return s.error();
  auto present = impl_->has_imagery_tables();
  if (!present) return present.error();
  if (!*present) return no_imagery(impl_->path, name);
  static const std::string sql =
      std::string("SELECT ") + kImageryColumns +
      " FROM imagery_layers AS l JOIN imagery_versions AS v ON v.id = l.version WHERE l.name = ?1";
  auto q = impl_->query(sql.c_str());
  if (!q) return q.error();
  q->bind(1, name);
  const int rc = q->step();
  if (rc == SQLITE_DONE) return no_imagery(impl_->path, name);
  if (rc != SQLITE_ROW) {
    return impl_->sql_error("reading imagery layer '" + std::string(name) + "'");
  }
  return read_imagery_info(*q, impl_->path);
}

Result<std::optional<StoredImage>> TileStore::imagery_tile(std::string_view layer,
                                                           const geo::TileId& id) {
  if (!id.valid()) return invalid_argument("invalid tile id " + id.to_string());
  if (Status s = validate_layer_name(layer); !s) return s.error();
  auto present = impl_->has_imagery_tables();
  if (!present) return present.error();
  if (!*present) return no_imagery(impl_->path, layer);
  // One statement, so the layer → version lookup and the tile read see the same snapshot.
  auto q = impl_->query(
      "SELECT t.data, t.etag FROM imagery_layers AS l JOIN imagery_tiles AS t "
      "ON t.version = l.version WHERE l.name = ?1 AND t.z = ?2 AND t.x = ?3 AND t.y = ?4");
  if (!q) return q.error();
  q->bind(1, layer).bind(2, id.z).bind(3, id.x).bind(4, id.y);
  const int rc = q->step();
  if (rc == SQLITE_ROW) {
    StoredImage image;
    image.id = id;
    image.data = q->blob(0);
    image.etag = q->text(1);
    return std::optional<StoredImage>(std::move(image));
  }
  if (rc != SQLITE_DONE) {
    return impl_->sql_error("reading imagery layer '" + std::string(layer) + "' tile " +
                            id.to_string());
  }
  // No tile: an unknown layer is an error, a tile the layer does not have is not.
  auto exists = imagery_layer(layer);
  if (!exists) return exists.error();
  return std::optional<StoredImage>();
}

Result<std::vector<geo::TileId>> TileStore::imagery_tile_ids(std::string_view layer,
                                                             std::optional<std::uint32_t> level) {
  auto info = imagery_layer(layer);
  if (!info) return info.error();
  auto q =
      level ? impl_->query(
                  "SELECT z, x, y FROM imagery_tiles WHERE version = ?1 AND z = ?2 "
                  "ORDER BY z, x, y")
            : impl_->query("SELECT z, x, y FROM imagery_tiles WHERE version = ?1 ORDER BY z, x, y");
  if (!q) return q.error();
  q->bind(1, info->version);
  if (level) q->bind(2, *level);
  std::vector<geo::TileId> out;
  int rc = 0;
  while ((rc = q->step()) == SQLITE_ROW) {
    auto id = geo::TileId::from_zxy(q->i64(0), q->i64(1), q->i64(2));
    if (!id) {
      return corrupt_data(impl_->path.string() + ": imagery layer '" + std::string(layer) +
                          "': " + id.error().message);
    }
    out.push_back(*id);
  }
  if (rc != SQLITE_DONE) {
    return impl_->sql_error("listing the tiles of imagery layer '" + std::string(layer) + "'");
  }
  return out;
}

Status TileStore::delete_imagery(std::string_view name) {
  if (Status s = impl_->require_writable(); !s) return s;
  if (Status s = validate_layer_name(name); !s) return s;
  return impl_->transaction("deleting an imagery layer", [&]() -> Status {
    auto info = imagery_layer(name);
    if (!info) return info.error();
    auto q = impl_->query("DELETE FROM imagery_layers WHERE name = ?1");
    if (!q) return q.error();
    q->bind(1, name);
    if (!Impl::done(*q)) {
      return impl_->sql_error("deleting imagery layer '" + std::string(name) + "'");
    }
    return impl_->drop_imagery_version(info->version);
  });
}

// ---------------------------------------------------------------------------------------------
// The writer

const VersionKind kImageryKind{
    "imagery layer",
    "SELECT id, writer_pid, writer_host, writer_start FROM imagery_versions "
    "WHERE name = ?1 AND status = 'building'",
    "SELECT count(*) FROM imagery_tiles WHERE version = ?1",
    "SELECT version FROM imagery_layers WHERE name = ?1",
    "INSERT INTO imagery_layers (name, version) VALUES (?1, ?2) "
    "ON CONFLICT (name) DO UPDATE SET version = excluded.version",
    &TileStore::Impl::drop_imagery_version};

struct ImageryWriter::Impl : VersionBatch<StoredImage> {
  Status flush() {
    return write_pending(
        "INSERT OR REPLACE INTO imagery_tiles (version, z, x, y, data, etag) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        [](Query& q, const StoredImage& t) { q.bind_blob(5, t.data).bind(6, t.etag); });
  }
};

Result<std::unique_ptr<ImageryWriter>> TileStore::begin_imagery(const ImageryInfo& info) {
  if (Status s = impl_->require_writable(); !s) return s.error();
  if (Status s = validate_imagery_info(info); !s) return s.error();
  if (Status s = impl_->create_imagery_tables(); !s) return s.error();
  auto version = impl_->begin_version(
      kImageryKind, info.name,
      "INSERT INTO imagery_versions (name, status, writer_pid, writer_host, writer_start, "
      "projection, format, tile_size, min_x, min_y, max_x, max_y, west, south, east, north, "
      "min_level, max_level, tile_count, options, attribution, started_unix) VALUES (?1, "
      "'building', ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, 0, "
      "?18, ?19, ?20)",
      [&](Query& q) {
        q.bind(5, geo::to_string(info.projection)).bind(6, info.format).bind(7, info.tile_size);
        bind_bounds(q, 8, info.mercator_bounds, info.bounds);
        q.bind(16, info.min_level).bind(17, info.max_level);
        q.bind(18, info.options_json).bind(19, info.attribution).bind(20, now_unix());
      });
  if (!version) return version.error();
  auto writer = std::make_unique<ImageryWriter::Impl>();
  writer->kind = &kImageryKind;
  writer->store = impl_.get();
  writer->name = info.name;
  writer->version = *version;
  return std::make_unique<ImageryWriter>(std::move(writer));
}

ImageryWriter::ImageryWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

ImageryWriter::~ImageryWriter() {
  if (impl_ && impl_->state == Impl::State::building) abandon();
}

Status ImageryWriter::put(StoredImage&& tile) {
  if (Status s = impl_->usable(); !s) return s;
  if (!tile.id.valid()) {
    return invalid_argument(impl_->what() + ": invalid tile id " + tile.id.to_string());
  }
  if (tile.data.empty()) {
    return invalid_argument(impl_->what() + ": empty image for tile " + tile.id.to_string());
  }
  tile.etag = make_etag(tile.data);
  const std::size_t bytes = tile.data.size();
  return impl_->add(std::move(tile), bytes, [&] { return impl_->flush(); });
}

Status ImageryWriter::flush() {
  if (Status s = impl_->usable(); !s) return s;
  return impl_->flush();
}

Result<std::optional<StoredImage>> ImageryWriter::get(const geo::TileId& id) {
  if (Status s = impl_->usable(); !s) return s.error();
  if (const StoredImage* p = impl_->find_pending(id)) return std::optional<StoredImage>(*p);
  auto q = impl_->store->query(
      "SELECT data, etag FROM imagery_tiles WHERE version = ?1 AND z = ?2 AND x = ?3 AND y = ?4");
  if (!q) return q.error();
  q->bind(1, impl_->version).bind(2, id.z).bind(3, id.x).bind(4, id.y);
  const int rc = q->step();
  if (rc == SQLITE_DONE) return std::optional<StoredImage>();
  if (rc != SQLITE_ROW) {
    return impl_->store->sql_error("reading " + impl_->what() + " tile " + id.to_string());
  }
  StoredImage image;
  image.id = id;
  image.data = q->blob(0);
  image.etag = q->text(1);
  return std::optional<StoredImage>(std::move(image));
}

Status ImageryWriter::publish(const ImageryInfo& info) {
  if (Status s = impl_->usable(); !s) return s;
  if (info.name != impl_->name) {
    return invalid_argument(impl_->what() + ": publish() given the metadata of imagery layer '" +
                            info.name + "'");
  }
  if (Status s = validate_imagery_info(info); !s) return s;
  if (Status s = impl_->flush(); !s) return s;
  return impl_->publish(
      "UPDATE imagery_versions SET status = 'ready', writer_pid = NULL, writer_host = NULL, "
      "writer_start = NULL, projection = ?2, format = ?3, tile_size = ?4, min_x = ?5, "
      "min_y = ?6, max_x = ?7, max_y = ?8, west = ?9, south = ?10, east = ?11, north = ?12, "
      "min_level = ?13, max_level = ?14, tile_count = ?15, options = ?16, attribution = ?17, "
      "created_unix = ?18 WHERE id = ?1 AND status = 'building'",
      [&](Query& q, std::int64_t tiles) {
        q.bind(2, geo::to_string(info.projection)).bind(3, info.format);
        q.bind(4, info.tile_size);
        bind_bounds(q, 5, info.mercator_bounds, info.bounds);
        q.bind(13, info.min_level).bind(14, info.max_level).bind(15, tiles);
        q.bind(16, info.options_json).bind(17, info.attribution).bind(18, now_unix());
      });
}

void ImageryWriter::abandon() { impl_->abandon(); }

}  // namespace tinstream::store
