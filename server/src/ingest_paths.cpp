#include "tinstream/server/ingest_paths.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <system_error>

namespace tinstream::server {

Result<std::filesystem::path> resolve_source(const std::filesystem::path& data_root,
                                             std::string_view requested) {
  namespace fs = std::filesystem;
  if (requested.empty()) return invalid_argument("ingest source: empty path");
  if (requested.find('\0') != std::string_view::npos)
    return invalid_argument("ingest source: NUL in path");
  const fs::path req{std::string(requested)};
  for (const auto& part : req) {
    if (part == "..")
      return invalid_argument("ingest source \"" + std::string(requested) +
                              "\": '..' is not allowed");
  }
  std::error_code ec;
  const fs::path root = fs::canonical(data_root, ec);
  if (ec)
    return Error(ErrorCode::unsupported,
                 "ingest: data root " + data_root.string() + " is not usable: " + ec.message());
  const fs::path candidate = req.is_absolute() ? req : root / req;
  const fs::path real = fs::canonical(candidate, ec);
  if (ec) return not_found("ingest source \"" + std::string(requested) + "\" does not exist");
  // Component-wise prefix test (a string prefix would accept /data-other for /data).
  auto r = root.begin();
  auto p = real.begin();
  for (; r != root.end(); ++r, ++p) {
    if (p == real.end() || *p != *r) {
      return Error(ErrorCode::unsupported,
                   "ingest source \"" + std::string(requested) + "\" is outside the data root");
    }
  }
  const auto type = fs::status(real, ec).type();
  if (type != fs::file_type::regular && type != fs::file_type::directory) {
    return invalid_argument("ingest source \"" + std::string(requested) +
                            "\" is not a file or directory");
  }
  return real;
}

Result<std::shared_ptr<const HeldSource>> HeldSource::open(const std::filesystem::path& data_root,
                                                           std::string_view requested) {
  namespace fs = std::filesystem;
  auto real = resolve_source(data_root, requested);
  if (!real) return real.error();
  std::error_code ec;
  const bool folder = fs::is_directory(*real, ec);
  const fs::path held = folder ? *real : real->parent_path();
  auto source = std::shared_ptr<HeldSource>(new HeldSource());
  source->fd_ = ::open(held.c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC | O_NOFOLLOW);
  const auto changed = [&] {
    return Error(ErrorCode::unsupported,
                 "ingest source \"" + std::string(requested) + "\" changed while it was checked");
  };
  if (source->fd_ < 0) return changed();
  // The folder opened is the one checked: nothing was swapped between the check and the open.
  const fs::path by_fd = "/proc/self/fd/" + std::to_string(source->fd_);
  if (fs::read_symlink(by_fd, ec) != held || ec) return changed();
  if (folder) {
    source->path_ = by_fd;
    return std::shared_ptr<const HeldSource>(std::move(source));
  }
  struct stat st {};
  const std::string name = real->filename().string();
  if (::fstatat(source->fd_, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISREG(st.st_mode))
    return changed();
  source->path_ = by_fd / name;
  return std::shared_ptr<const HeldSource>(std::move(source));
}

HeldSource::~HeldSource() {
  if (fd_ >= 0) ::close(fd_);
}

Result<std::string> sanitize_filename(std::string_view name) {
  if (name.empty() || name.size() > 100 || name.front() == '.') {
    return invalid_argument("must be 1-100 characters from [A-Za-z0-9_.-], not starting with '.'");
  }
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '.' || c == '-';
    if (!ok)
      return invalid_argument(
          "must be 1-100 characters from [A-Za-z0-9_.-], not starting with '.'");
  }
  return std::string(name);
}

}  // namespace tinstream::server
