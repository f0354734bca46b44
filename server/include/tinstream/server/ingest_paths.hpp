// tinstream/server/ingest_paths.hpp — which files an admin may ask the server to ingest.
// Pure functions over the file system (they read it; they change nothing). Thread-safe.
#pragma once

#include <filesystem>
#include <memory>
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

// A source resolved once (resolve_source) and held open from then on. The path handed to the
// ingest is /proc/self/fd/N/name, N a descriptor of the folder that held the file when it was
// checked (for a folder source: /proc/self/fd/N, the folder itself), so renaming or replacing
// anything under the data root afterwards cannot make the ingest read another file. (Left: the
// file's own name in that folder may still be replaced by someone who can write the folder;
// it was checked not to be a symlink when opened.) Closes the descriptor when destroyed.
class HeldSource {
 public:
  static Result<std::shared_ptr<const HeldSource>> open(const std::filesystem::path& data_root,
                                                        std::string_view requested);
  ~HeldSource();
  HeldSource(const HeldSource&) = delete;
  HeldSource& operator=(const HeldSource&) = delete;

  const std::filesystem::path& path() const { return path_; }  // /proc/self/fd/N[/name]

 private:
  HeldSource() = default;
  int fd_ = -1;
  std::filesystem::path path_;
};

// An uploaded file's name reduced to a safe basename: [A-Za-z0-9_.-], 1-100 characters, no
// leading '.'; invalid_argument otherwise.
Result<std::string> sanitize_filename(std::string_view name);

}  // namespace tinstream::server
