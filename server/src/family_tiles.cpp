// Route family "tiles", native part: /tiles/{layer}/{quadkey}, the stored blob.
#include "families.hpp"
#include "negotiation.hpp"
#include "stored_tiles.hpp"

namespace tinstream::server {

// The stored zlib bytes with `Content-Encoding: deflate` when accepted (preferred at equal
// quality), else rewrapped as gzip, else inflated; one ETag per encoding. The blob's header is
// checked first (stored_tiles.hpp): it names this tile and a bounded size.
Response serve(const Request& req, Context& ctx, const NativeTileRoute& r) {
  auto st = get_store(ctx);
  if (!st) return error_response(st.error());
  auto t = (*st)->tile(r.layer, r.id);
  if (!t) return error_response(t.error());
  if (!t->has_value()) {
    return json_error(404, "no tile " + r.id.quadkey() + " (" + r.id.to_string() + ") in layer \"" +
                               r.layer + "\"");
  }
  const store::StoredTile& tile = **t;
  const double q_deflate = accept_quality(req.accept_encoding, "deflate");
  const double q_gzip = accept_quality(req.accept_encoding, "gzip");
  const bool deflate = q_deflate > 0 && q_deflate >= q_gzip;
  const std::string etag = representation_etag(safe_etag(tile), deflate      ? ""
                                                                : q_gzip > 0 ? "gz"
                                                                             : "id");
  Response res;
  res.set("ETag", etag);
  res.set("Cache-Control", cache_control(ctx.config));
  res.set("Vary", "Accept-Encoding");
  if (etag_matches(req.if_none_match, etag)) {
    res.status = 304;
    return res;
  }
  res.set("Content-Type", "application/vnd.tinstream.tile");
  if (deflate) {
    if (auto checked = check_blob(tile, r.id); !checked) return error_response(checked.error());
    res.set("Content-Encoding", "deflate");
    res.body.assign(tile.compressed.begin(), tile.compressed.end());
  } else if (q_gzip > 0) {
    auto gz = blob_as_gzip(tile, r.id);
    if (!gz) return error_response(gz.error());
    res.set("Content-Encoding", "gzip");
    res.body.assign(gz->begin(), gz->end());
  } else {
    auto raw = inflate_blob(tile, r.id);
    if (!raw) return error_response(raw.error());
    res.body.assign(raw->begin(), raw->end());
  }
  return res;
}

}  // namespace tinstream::server
