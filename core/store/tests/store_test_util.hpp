// Helpers for the store tests: temporary directories and raw SQLite access to check the file.
#pragma once

#include <sqlite3.h>
#include <stdlib.h>

#include <filesystem>
#include <string>

#include "test_tiles.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::store::testing {

// A fresh directory under the system temp dir, removed with everything in it at scope exit.
class TempDir {
 public:
  TempDir() {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "tinstream-store-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const char* name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// Runs one SQL statement on its own connection and returns the first column of the first row as
// text ("" when there is no row, "ERROR: …" on failure).
inline std::string sql_value(const std::filesystem::path& db_path, const std::string& sql,
                             bool read_only = true) {
  sqlite3* db = nullptr;
  const int flags = read_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  if (sqlite3_open_v2(db_path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    std::string e = "ERROR: " + std::string(sqlite3_errmsg(db));
    sqlite3_close(db);
    return e;
  }
  sqlite3_busy_timeout(db, 10000);
  sqlite3_stmt* stmt = nullptr;
  std::string out;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
    out = "ERROR: " + std::string(sqlite3_errmsg(db));
  } else {
    const int rc = sqlite3_step(stmt);
    if (rc == SQLITE_ROW) {
      const auto* text = sqlite3_column_text(stmt, 0);
      out = text == nullptr ? "NULL" : reinterpret_cast<const char*>(text);
    } else if (rc != SQLITE_DONE) {
      out = "ERROR: " + std::string(sqlite3_errmsg(db));
    }
  }
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return out;
}

inline LayerInfo basic_info(const std::string& name) {
  LayerInfo info;
  info.name = name;
  info.mercator_bounds = {-0.5, -0.25, 0.5, 0.25};
  info.bounds = {-90, -22.0, 90, 22.0};
  info.min_level = 0;
  info.max_level = 4;
  info.max_points = 1000;
  info.options_json = R"({"max_points":1000})";
  info.level_max_error = {10, 5, 2.5, 1.25, 0};
  return info;
}

}  // namespace tinstream::store::testing
