// The tile store as a tile source: every connection is its own read-only TileStore (one SQLite
// connection per worker thread, as the store requires).
#include <filesystem>
#include <system_error>
#include <utility>

#include "tinstream/client/imagery.hpp"
#include "tinstream/client/tile_source.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::client {

namespace {

class StoreConnection final : public TileConnection {
 public:
  explicit StoreConnection(store::TileStore store) : store_(std::move(store)) {}

  FetchResponse fetch(const FetchRequest& request, const std::atomic<bool>& cancel) override {
    FetchResponse r;
    r.attempts = 1;
    if (cancel.load()) {
      r.error = Error(ErrorCode::cancelled, "cancelled");
      return r;
    }
    if (request.key.kind == TileKind::imagery) return fetch_image(request);
    auto tile = store_.tile(request.layer->name, request.key.tile);
    if (!tile) {
      r.error = Error(tile.error().code, "tile " + request.key.tile.quadkey() + " of layer \"" +
                                             request.layer->name + "\": " + tile.error().message);
      return r;
    }
    if (!tile->has_value()) {
      r.status = FetchResponse::Status::not_found;
      return r;
    }
    store::StoredTile& stored = **tile;
    r.status = FetchResponse::Status::ok;
    r.etag = stored.etag;
    r.encoding = ContentEncoding::deflate;  // the store keeps zlib streams
    r.body = std::move(stored.compressed);
    return r;
  }

 private:
  FetchResponse fetch_image(const FetchRequest& request) {
    FetchResponse r;
    r.attempts = 1;
    auto image = store_.imagery_tile(request.layer->name, request.key.tile);
    if (!image) {
      r.error =
          Error(image.error().code, "imagery tile " + request.key.tile.quadkey() + " of layer \"" +
                                        request.layer->name + "\": " + image.error().message);
      return r;
    }
    if (!image->has_value()) {
      r.status = FetchResponse::Status::not_found;
      return r;
    }
    r.status = FetchResponse::Status::ok;
    r.etag = (**image).etag;
    r.encoding = ContentEncoding::identity;  // PNG / JPEG / WebP as encoded
    r.body = std::move((**image).data);
    return r;
  }

  store::TileStore store_;
};

std::filesystem::path absolute_or_given(const std::filesystem::path& path) {
  std::error_code ec;
  std::filesystem::path full = std::filesystem::absolute(path, ec);
  return ec ? path : full.lexically_normal();
}

class StoreSource final : public TileSource {
 public:
  // The path as an absolute one (what the panel and the statistics show: a relative --store
  // says nothing once the viewer runs elsewhere); as given when it cannot be made absolute.
  explicit StoreSource(const std::filesystem::path& path) : path_(absolute_or_given(path)) {}

  std::string describe() const override { return "store " + path_.string(); }
  bool remote() const override { return false; }

  Result<std::vector<LayerDescription>> layers(const std::vector<std::string>& names) override {
    auto st = store::TileStore::open(path_, store::TileStore::Mode::read_only);
    if (!st) return st.error();
    std::vector<LayerDescription> out;
    if (names.empty()) {
      auto all = st->layers();
      if (!all) return all.error();
      for (const auto& info : *all) out.push_back(from_store_info(info));
      return out;
    }
    for (const std::string& name : names) {
      auto info = st->layer(name);
      if (!info) return Error(info.error().code, path_.string() + ": " + info.error().message);
      out.push_back(from_store_info(*info));
    }
    return out;
  }

  Result<LayerDescription> imagery_layer(const std::string& name) override {
    auto st = store::TileStore::open(path_, store::TileStore::Mode::read_only);
    if (!st) return st.error();
    auto info = st->imagery_layer(name);
    if (!info) return Error(info.error().code, path_.string() + ": " + info.error().message);
    return from_imagery_info(*info);
  }

  Result<std::unique_ptr<TileConnection>> connect() override {
    auto st = store::TileStore::open(path_, store::TileStore::Mode::read_only);
    if (!st) return st.error();
    return std::unique_ptr<TileConnection>(std::make_unique<StoreConnection>(std::move(*st)));
  }

 private:
  std::filesystem::path path_;
};

}  // namespace

Result<std::shared_ptr<TileSource>> open_store_source(const std::filesystem::path& store) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(store, ec))
    return not_found("tile store " + store.string() + " does not exist");
  auto st = store::TileStore::open(store, store::TileStore::Mode::read_only);
  if (!st) return st.error();
  return std::shared_ptr<TileSource>(std::make_shared<StoreSource>(store));
}

}  // namespace tinstream::client
