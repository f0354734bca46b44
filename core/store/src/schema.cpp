#include "schema.hpp"

namespace tinstream::store::schema {

// Keep in sync with docs/store-format.md.
namespace {

constexpr const char* kTables = R"sql(
CREATE TABLE IF NOT EXISTS metadata (
  name  TEXT PRIMARY KEY,
  value TEXT NOT NULL
);

CREATE TABLE IF NOT EXISTS layer_versions (
  id              INTEGER PRIMARY KEY AUTOINCREMENT,
  name            TEXT    NOT NULL,
  status          TEXT    NOT NULL CHECK (status IN ('building', 'ready')),
  writer_pid      INTEGER,
  writer_host     TEXT,
  writer_start    INTEGER,
  projection      TEXT    NOT NULL,
  vertical_datum  TEXT    NOT NULL,
  min_x REAL NOT NULL, min_y REAL NOT NULL, max_x REAL NOT NULL, max_y REAL NOT NULL,
  west  REAL NOT NULL, south REAL NOT NULL, east  REAL NOT NULL, north REAL NOT NULL,
  min_level       INTEGER NOT NULL,
  max_level       INTEGER NOT NULL,
  max_points      INTEGER NOT NULL,
  tile_count      INTEGER NOT NULL,
  point_count     INTEGER NOT NULL,
  source_points   INTEGER NOT NULL,
  min_z REAL NOT NULL, max_z REAL NOT NULL,
  level_max_error TEXT    NOT NULL,
  options         TEXT    NOT NULL,
  attribution     TEXT    NOT NULL,
  started_unix    INTEGER NOT NULL,
  created_unix    INTEGER
);
CREATE INDEX IF NOT EXISTS layer_versions_by_name ON layer_versions (name, status);

CREATE TABLE IF NOT EXISTS layers (
  name    TEXT PRIMARY KEY,
  version INTEGER NOT NULL UNIQUE
);

CREATE TABLE IF NOT EXISTS tiles (
  version         INTEGER NOT NULL,
  z               INTEGER NOT NULL,
  x               INTEGER NOT NULL,
  y               INTEGER NOT NULL,
  data            BLOB    NOT NULL,
  etag            TEXT    NOT NULL,
  min_z           REAL    NOT NULL,
  max_z           REAL    NOT NULL,
  geometric_error REAL    NOT NULL,
  vertex_count    INTEGER NOT NULL,
  triangle_count  INTEGER NOT NULL,
  PRIMARY KEY (version, z, x, y)
) WITHOUT ROWID;

)sql";

// Imagery (added after schema version 1 shipped; files without these tables are still version 1
// and get them from the first read-write open that knows them).
constexpr const char* kImageryTables = R"sql(
CREATE TABLE IF NOT EXISTS imagery_versions (
  id              INTEGER PRIMARY KEY AUTOINCREMENT,
  name            TEXT    NOT NULL,
  status          TEXT    NOT NULL CHECK (status IN ('building', 'ready')),
  writer_pid      INTEGER,
  writer_host     TEXT,
  writer_start    INTEGER,
  projection      TEXT    NOT NULL,
  format          TEXT    NOT NULL CHECK (format IN ('png', 'jpeg', 'webp')),
  tile_size       INTEGER NOT NULL,
  min_x REAL NOT NULL, min_y REAL NOT NULL, max_x REAL NOT NULL, max_y REAL NOT NULL,
  west  REAL NOT NULL, south REAL NOT NULL, east  REAL NOT NULL, north REAL NOT NULL,
  min_level       INTEGER NOT NULL,
  max_level       INTEGER NOT NULL,
  tile_count      INTEGER NOT NULL,
  options         TEXT    NOT NULL,
  attribution     TEXT    NOT NULL,
  started_unix    INTEGER NOT NULL,
  created_unix    INTEGER
);
CREATE INDEX IF NOT EXISTS imagery_versions_by_name ON imagery_versions (name, status);

CREATE TABLE IF NOT EXISTS imagery_layers (
  name    TEXT PRIMARY KEY,
  version INTEGER NOT NULL UNIQUE
);

CREATE TABLE IF NOT EXISTS imagery_tiles (
  version INTEGER NOT NULL,
  z       INTEGER NOT NULL,
  x       INTEGER NOT NULL,
  y       INTEGER NOT NULL,
  data    BLOB    NOT NULL,
  etag    TEXT    NOT NULL,
  PRIMARY KEY (version, z, x, y)
) WITHOUT ROWID;

)sql";

}  // namespace

std::string quadkey_expression(const std::string& z, const std::string& x, const std::string& y) {
  // Digit i (most significant level first) is 2·ybit + xbit of bit (z − 1 − i); levels past z
  // contribute ''. 30 terms: the deepest level (geo::kMaxLevel).
  std::string e;
  for (int i = 0; i < 30; ++i) {
    const std::string shift = "(" + z + " - " + std::to_string(i + 1) + ")";
    if (!e.empty()) e += " || ";
    e.append("(CASE WHEN ").append(z).append(" > ").append(std::to_string(i));
    e.append(" THEN (((").append(y).append(" >> ").append(shift).append(") & 1) * 2 + ((");
    e.append(x).append(" >> ").append(shift).append(") & 1)) ELSE '' END)");
  }
  return e;
}

const std::string& imagery_create_sql() {
  static const std::string sql =
      std::string(kImageryTables) +
      "CREATE VIEW IF NOT EXISTS published_imagery AS\n"
      "  SELECT l.name AS layer, v.format, t.z, t.x, t.y, (1 << t.z) - 1 - t.y AS tms_y,\n"
      "         " +
      quadkey_expression("t.z", "t.x", "t.y") +
      " AS quadkey,\n"
      "         t.etag, length(t.data) AS bytes, t.data\n"
      "  FROM imagery_layers AS l JOIN imagery_versions AS v ON v.id = l.version\n"
      "       JOIN imagery_tiles AS t ON t.version = l.version;\n";
  return sql;
}

const std::string& create_sql() {
  static const std::string sql =
      std::string(kTables) + imagery_create_sql() +
      "CREATE VIEW IF NOT EXISTS published_tiles AS\n"
      "  SELECT l.name AS layer, t.z, t.x, t.y, (1 << t.z) - 1 - t.y AS tms_y,\n"
      "         " +
      quadkey_expression("t.z", "t.x", "t.y") +
      " AS quadkey,\n"
      "         t.etag, length(t.data) AS bytes, t.min_z, t.max_z, t.geometric_error,\n"
      "         t.vertex_count, t.triangle_count, t.data\n"
      "  FROM layers AS l JOIN tiles AS t ON t.version = l.version;\n";
  return sql;
}

}  // namespace tinstream::store::schema
