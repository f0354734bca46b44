// Route family "web": the browser viewers (`/` CesiumJS, `/maplibre` MapLibre GL JS) and their
// static files under `/web/…` — the pages, CesiumJS's Build/Cesium and MapLibre's dist, copied
// there at build time by web/build.mjs (nothing is fetched from another host at run time).
//
// The web root is $TINSTREAM_WEB_ROOT when set, else `../web` or `../share/tinstream/web`
// beside the executable (build/bin/tinstream-server → build/web), found once per process.
// Files are read per request (the page cache keeps them); a `.gz` sibling made at build time is
// sent instead when the client takes gzip. ETags come from size and modification time, with
// `Cache-Control: no-cache`, so a rebuilt viewer is picked up at the next load.
#include <sys/stat.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "families.hpp"
#include "negotiation.hpp"

namespace tinstream::server {
namespace {

namespace fs = std::filesystem;

fs::path find_web_root() {
  if (const char* env = std::getenv("TINSTREAM_WEB_ROOT"); env != nullptr && *env != 0) {
    return env;
  }
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const fs::path prefix = exe.parent_path().parent_path();
  for (const fs::path& candidate : {prefix / "web", prefix / "share" / "tinstream" / "web"}) {
    if (fs::exists(candidate / "index.html", ec)) return candidate;
  }
  return {};
}

const fs::path& web_root() {
  static const fs::path root = find_web_root();  // thread-safe initialisation
  return root;
}

std::string_view content_type(std::string_view name) {
  const auto dot = name.rfind('.');
  const std::string_view ext = dot == std::string_view::npos ? "" : name.substr(dot + 1);
  static constexpr std::pair<std::string_view, std::string_view> kTypes[] = {
      {"html", "text/html; charset=utf-8"},
      {"js", "text/javascript; charset=utf-8"},
      {"mjs", "text/javascript; charset=utf-8"},
      {"cjs", "text/javascript; charset=utf-8"},
      {"css", "text/css; charset=utf-8"},
      {"json", "application/json"},
      {"map", "application/json"},
      {"wasm", "application/wasm"},
      {"png", "image/png"},
      {"jpg", "image/jpeg"},
      {"gif", "image/gif"},
      {"svg", "image/svg+xml"},
      {"xml", "application/xml"},
      {"txt", "text/plain; charset=utf-8"},
      {"ktx2", "image/ktx2"},
      {"glb", "model/gltf-binary"},
  };
  for (const auto& [e, type] : kTypes) {
    if (e == ext) return type;
  }
  return "application/octet-stream";
}

struct FileStat {
  std::uint64_t size = 0;
  std::int64_t mtime_ns = 0;
};

std::optional<FileStat> regular_file(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return FileStat{static_cast<std::uint64_t>(st.st_size),
                  static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec};
}

std::string hex(std::uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%llx", static_cast<unsigned long long>(v));
  return buf;
}

// Serves `relative` (validated by the route parser: no "..", no hidden names) from the web root.
Response serve_file(const Request& req, const std::string& relative) {
  const fs::path& root = web_root();
  if (root.empty()) {
    return json_error(404,
                      "the web viewer is not installed: build it (cmake --build build --target "
                      "web) or point TINSTREAM_WEB_ROOT at its folder");
  }
  const fs::path file = root / relative;
  const auto plain = regular_file(file);
  if (!plain) return json_error(404, "no such file: " + relative);
  fs::path chosen = file;
  FileStat stat = *plain;
  std::string tag_suffix;
  const bool gzip = accept_quality(req.accept_encoding, "gzip") > 0;
  if (gzip) {
    const fs::path gz = file.string() + ".gz";
    if (const auto zipped = regular_file(gz); zipped && zipped->mtime_ns >= plain->mtime_ns) {
      chosen = gz;
      stat = *zipped;
      tag_suffix = "-gz";
    }
  }
  const std::string etag = "\"w-" + hex(stat.size) + "-" +
                           hex(static_cast<std::uint64_t>(stat.mtime_ns)) + tag_suffix + "\"";
  Response res;
  res.set("ETag", etag);
  res.set("Cache-Control", "no-cache");
  res.set("Vary", "Accept-Encoding");
  if (etag_matches(req.if_none_match, etag)) {
    res.status = 304;
    return res;
  }
  std::ifstream in(chosen, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (!in && !in.eof()) return json_error(500, "cannot read " + relative);
  res.set("Content-Type", std::string(content_type(relative)));
  if (!tag_suffix.empty()) res.set("Content-Encoding", "gzip");
  res.body = std::move(bytes).str();
  return res;
}

}  // namespace

Response serve(const Request& req, Context&, const WebPageRoute& r) {
  return serve_file(req, r.page);
}

Response serve(const Request& req, Context&, const WebAssetRoute& r) {
  return serve_file(req, r.path);
}

}  // namespace tinstream::server
