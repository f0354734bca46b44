// schema.hpp — the SQL schema of the tile store (docs/store-format.md documents it).
#pragma once

#include <string>

namespace tinstream::store::schema {

inline constexpr const char* kFormat = "tinstream-store";
inline constexpr int kSchemaVersion = 1;

// Creates every table, index and view; idempotent (IF NOT EXISTS). Run inside a write transaction.
const std::string& create_sql();
// The imagery tables and view alone (part of create_sql()); idempotent.
const std::string& imagery_create_sql();

// An SQL expression for the Bing quadkey of tile (z, x, y) given the column names, z ≤ 30.
std::string quadkey_expression(const std::string& z, const std::string& x, const std::string& y);

}  // namespace tinstream::store::schema
