// schema.hpp — the SQL schema of the tile store (docs/store-format.md documents it).
#pragma once

namespace tinstream::store::schema {

inline constexpr const char* kFormat = "tinstream-store";
inline constexpr int kSchemaVersion = 1;

// Creates every table, index and view; idempotent (IF NOT EXISTS). Run inside a write transaction.
extern const char* const kCreate;

}  // namespace tinstream::store::schema
