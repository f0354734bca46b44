// tinstream/server/ingest_paths.hpp — which files an admin may ask the server to ingest.
// Pure functions over the file system (they read it; they change nothing). Thread-safe.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "tinstream/base/result.hpp"

namespace tinstream::server {

// Resolves a requested source path against the data root: relative paths are relative to the
// root, absolute ones must lie inside it. Rejects ".." components outright (invalid_argument),
// then canonicalises (following every symlink) and requires the result to be the root or below
// it, component by component (unsupported: "outside the data root"). not_found when the path does
// not exist. Returns the canonical path.
Result<std::filesystem::path> resolve_source(const std::filesystem::path& data_root,
                                             std::string_view requested);

// An uploaded file's name reduced to a safe basename: [A-Za-z0-9_.-], 1-100 characters, no
// leading '.'; invalid_argument otherwise.
Result<std::string> sanitize_filename(std::string_view name);

}  // namespace tinstream::server
