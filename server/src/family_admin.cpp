// Route family "admin": ingest jobs (from paths under the data root or uploads), their status,
// and layer removal. Every route needs the bearer token (check_admin).
#include <openssl/crypto.h>
#include <openssl/sha.h>

#include <array>
#include <nlohmann/json.hpp>

#include "families.hpp"
#include "negotiation.hpp"
#include "tinstream/server/ingest_options.hpp"
#include "tinstream/server/ingest_paths.hpp"

namespace tinstream::server {

using nlohmann::json;

std::optional<Response> check_admin(const Request& request, const Context& context) {
  if (context.admin_token.empty()) {
    return json_error(403, "admin API disabled: no admin token configured");
  }
  std::string_view auth = trim(request.authorization);
  if (auth.size() < 7 || !iequals(auth.substr(0, 7), "Bearer ")) {
    Response r =
        json_error(401, "admin API: bearer token required (Authorization: Bearer <token>)");
    r.set("WWW-Authenticate", "Bearer realm=\"tinstream-admin\"");
    return r;
  }
  // Compared as SHA-256 digests, in constant time: the time depends on neither token's
  // content nor its length (a byte-by-byte walk told the length of the real one).
  const auto digest = [](std::string_view text) {
    std::array<unsigned char, SHA256_DIGEST_LENGTH> d{};
    SHA256(reinterpret_cast<const unsigned char*>(text.data()), text.size(), d.data());
    return d;
  };
  const auto given = digest(trim(auth.substr(7)));
  const auto want = digest(context.admin_token);
  const int diff = CRYPTO_memcmp(given.data(), want.data(), given.size());
  if (diff != 0) return json_error(403, "admin API: wrong token");
  return std::nullopt;
}

bool is_upload(const Request& r) {
  if (r.method != "POST") return false;
  std::string_view path = r.target;
  path = path.substr(0, path.find('?'));
  if (path != "/admin/ingest") return false;
  std::string_view ct = trim(r.content_type);
  ct = ct.substr(0, ct.find(';'));
  return !iequals(trim(ct), "application/json");
}

namespace {

// The job of an upload (POST /admin/ingest with the file as the body): the layer, file name and
// options come from the query. The body file is renamed to carry the name (the readers look at
// the extension) and removed after the job, or here at once on any error.
std::optional<Response> upload_spec(const Request& req, const IngestRoute& r, IngestJobSpec& spec,
                                    std::vector<std::filesystem::path>& delete_after) {
  if (req.body_file.empty()) return json_error(400, "upload body missing");
  auto layer = r.query.find("layer");
  if (layer == r.query.end() || !is_valid_layer_name(layer->second)) {
    remove_quietly(req.body_file);
    return json_error(
        400, "upload: query parameter layer= must name a valid layer ([A-Za-z0-9_.-]{1,64})");
  }
  spec.layer = layer->second;
  std::string name = "upload";
  if (auto f = r.query.find("filename"); f != r.query.end()) {
    auto safe = sanitize_filename(f->second);
    if (!safe) {
      remove_quietly(req.body_file);
      return json_error(400, "upload: filename= " + safe.error().message);
    }
    name = *safe;
  }
  std::filesystem::path final_path = req.body_file;
  final_path += "-" + name;
  std::error_code ec;
  std::filesystem::rename(req.body_file, final_path, ec);
  if (ec) {
    remove_quietly(req.body_file);
    return json_error(500, "upload: cannot rename " + req.body_file.string() + ": " + ec.message());
  }
  spec.sources.push_back(final_path);
  spec.source_names.push_back(name);
  spec.root = final_path.parent_path();
  spec.allow_vrt = false;
  delete_after.push_back(final_path);
  if (auto o = r.query.find("options"); o != r.query.end()) {
    json opts = json::parse(o->second, nullptr, false);
    if (opts.is_discarded() || !opts.is_object()) {
      remove_quietly(final_path);
      return json_error(400, "upload: options= must be a JSON object");
    }
    if (Status valid = validate_ingest_options(opts); !valid) {
      remove_quietly(final_path);
      return json_error(400, "upload: " + valid.error().message);
    }
    spec.options = std::move(opts);
  }
  return std::nullopt;
}

// The job of a JSON request ({"layer", "sources", "options"}): each source is a path under the
// data root, opened and held here (resolved once; the job reads what was checked).
std::optional<Response> json_spec(const Request& req, const Context& ctx, IngestJobSpec& spec) {
  json body = json::parse(req.body, nullptr, false);
  if (body.is_discarded() || !body.is_object()) {
    return json_error(400,
                      "ingest: body must be a JSON object {\"layer\": ..., \"sources\": [...]}");
  }
  if (!body.contains("layer") || !body["layer"].is_string() ||
      !is_valid_layer_name(body["layer"].get<std::string>())) {
    return json_error(400, "ingest: \"layer\" must be a valid layer name ([A-Za-z0-9_.-]{1,64})");
  }
  spec.layer = body["layer"].get<std::string>();
  if (!body.contains("sources") || !body["sources"].is_array() || body["sources"].empty()) {
    return json_error(400,
                      "ingest: \"sources\" must be a non-empty array of paths under the data root");
  }
  if (ctx.config.data_root.empty()) {
    return json_error(403,
                      "ingest: server-side paths are disabled (no data_root configured); upload "
                      "the file instead");
  }
  spec.root = ctx.config.data_root;
  for (const auto& s : body["sources"]) {
    if (!s.is_string()) return json_error(400, "ingest: every source must be a string");
    auto held = HeldSource::open(ctx.config.data_root, s.get<std::string>());
    if (!held)
      return json_error(held.error().code == ErrorCode::not_found
                            ? 404
                            : (held.error().code == ErrorCode::invalid_argument ? 400 : 403),
                        held.error().message);
    spec.sources.push_back((*held)->path());
    spec.source_names.push_back(s.get<std::string>());
    spec.held.push_back(std::move(*held));
  }
  if (body.contains("options")) {
    if (!body["options"].is_object())
      return json_error(400, "ingest: \"options\" must be an object");
    if (Status valid = validate_ingest_options(body["options"]); !valid)
      return json_error(400, "ingest: " + valid.error().message);
    spec.options = body["options"];
  }
  return std::nullopt;
}

}  // namespace

Response serve(const Request& req, Context& ctx, const IngestRoute& r) {
  if (auto denied = check_admin(req, ctx)) {
    remove_quietly(req.body_file);
    return *denied;
  }
  if (!ctx.jobs) {
    remove_quietly(req.body_file);
    return json_error(503, "ingest is not available in this server");
  }
  IngestJobSpec spec;
  spec.store_path = ctx.config.store;
  spec.scratch_dir = ctx.scratch_dir;
  std::vector<std::filesystem::path> delete_after;
  if (auto refused =
          is_upload(req) ? upload_spec(req, r, spec, delete_after) : json_spec(req, ctx, spec)) {
    return *refused;
  }
  // A copy: when the job is refused (503) the upload is removed here, not by the job.
  auto id = ctx.jobs->submit(std::move(spec), delete_after);
  if (!id) {
    for (const auto& p : delete_after) remove_quietly(p);
    return json_error(503, id.error().message);
  }
  Response res =
      json_response(202, json{{"job", *id}, {"status_url", "/admin/jobs/" + *id}}.dump());
  res.set("Location", "/admin/jobs/" + *id);
  return res;
}

// Deleting is one write transaction that may wait up to the store's busy timeout (10 s) for the
// write lock: it runs on the blocking worker (Response::deferred), never on an io thread.
Response serve(const Request& req, Context& ctx, const DeleteLayerRoute& r) {
  if (auto denied = check_admin(req, ctx)) return *denied;
  Response res;
  res.deferred = [store = ctx.config.store, layers = ctx.layer_cache, name = r.layer] {
    auto rw = store::TileStore::open(store, store::TileStore::Mode::read_write);
    if (!rw) return error_response(rw.error());
    Status st = rw->delete_layer(name);
    if (layers) layers->clear();
    if (!st) return error_response(st.error());
    return json_response(200, json{{"deleted", name}}.dump());
  };
  return res;
}

Response serve(const Request& req, Context& ctx, const JobsRoute&) {
  if (auto denied = check_admin(req, ctx)) return *denied;
  json arr = json::array();
  if (ctx.jobs) {
    for (const auto& j : ctx.jobs->list()) arr.push_back(j.to_json());
  }
  return json_response(200, json{{"jobs", arr}}.dump());
}

Response serve(const Request& req, Context& ctx, const JobRoute& r) {
  if (auto denied = check_admin(req, ctx)) return *denied;
  auto job = ctx.jobs ? ctx.jobs->get(r.id) : std::nullopt;
  if (!job) return json_error(404, "no job " + r.id);
  return json_response(200, job->to_json().dump());
}

}  // namespace tinstream::server
