// `tinstream las-info FILE [--decode] [--threads N]`: what a LAS or LAZ file's header says, as
// JSON: version, point format, record length, count, scale/offset, bounds, the VLR directory,
// and for LAZ the LASzip VLR (compressor, items and their coder versions, chunk size) and the
// chunk table. --decode also decodes every record and reports the time, the rate and the
// sha256 of the records (the bytes an uncompressed LAS file would hold), so a decode can be
// compared with another tool's.
#include <openssl/evp.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.hpp"
#include "tinstream/sources/las_records.hpp"

namespace tinstream::cli {
namespace {

struct LasInfoOptions {
  std::string path;
  bool decode = false;
  unsigned threads = 0;
  bool chunks = false;
};

nlohmann::json laszip_json(const laz::LaszipVlr& v) {
  nlohmann::json items = nlohmann::json::array();
  for (const auto& item : v.items) {
    items.push_back(
        {{"type", laz::to_string(item.type)}, {"size", item.size}, {"version", item.version}});
  }
  return {
      {"compressor", laz::to_string(v.compressor)},
      {"coder", v.coder == 0 ? "arithmetic" : std::to_string(v.coder)},
      {"laszip_version", std::to_string(v.version_major) + "." + std::to_string(v.version_minor) +
                             "r" + std::to_string(v.version_revision)},
      {"chunk_size",
       v.variable_chunks() ? nlohmann::json("variable") : nlohmann::json(v.chunk_size)},
      {"items", items}};
}

nlohmann::json summary_json(const sources::LasRecordReader& r, bool list_chunks) {
  const sources::LasFileSummary& s = r.summary();
  nlohmann::json vlrs = nlohmann::json::array();
  for (const auto& v : s.vlrs) {
    vlrs.push_back({{"kind", v.extended ? "EVLR" : "VLR"},
                    {"user_id", v.user_id},
                    {"record_id", v.record_id},
                    {"length", v.length},
                    {"description", v.description}});
  }
  nlohmann::json j = {
      {"path", s.path},
      {"file_size", s.file_size},
      {"format", s.laszip ? "LAZ" : "LAS"},
      {"version", std::to_string(s.version_major) + "." + std::to_string(s.version_minor)},
      {"header_size", s.header_size},
      {"offset_to_points", s.offset_to_points},
      {"point_format", s.point_format},
      {"record_length", s.record_length},
      {"point_count", s.point_count},
      {"scale", s.scale},
      {"offset", s.offset},
      {"min", s.min},
      {"max", s.max},
      {"vlrs", vlrs}};
  if (s.laszip) j["laszip"] = laszip_json(*s.laszip);
  if (const laz::LazReader* lz = r.laz()) {
    nlohmann::json chunks = {
        {"count", lz->chunks().size()}, {"decode_threads", lz->threads()}, {"notes", lz->notes()}};
    if (list_chunks) {
      nlohmann::json list = nlohmann::json::array();
      for (const auto& c : lz->chunks()) {
        list.push_back({{"offset", c.offset},
                        {"bytes", c.bytes},
                        {"first_point", c.first_point},
                        {"points", c.points}});
      }
      chunks["table"] = list;
    }
    j["chunks"] = chunks;
  }
  return j;
}

int run_las_info(const LasInfoOptions& o) {
  sources::RecordOptions ro;
  ro.threads = o.threads;
  auto reader = sources::LasRecordReader::open(o.path, ro);
  if (!reader.ok()) {
    std::cerr << "tinstream las-info: " << reader.error().message << "\n";
    return 1;
  }
  nlohmann::json j = summary_json(**reader, o.chunks);
  if (o.decode) {
    const std::size_t rl = (*reader)->summary().record_length;
    constexpr std::size_t kBatch = 65536;
    std::vector<std::uint8_t> buf(kBatch * rl);
    std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> sha(EVP_MD_CTX_new(), &EVP_MD_CTX_free);
    EVP_DigestInit_ex(sha.get(), EVP_sha256(), nullptr);
    std::uint64_t records = 0;
    const auto start = std::chrono::steady_clock::now();
    for (;;) {
      auto n = (*reader)->read(buf.data(), kBatch);
      if (!n.ok()) {
        std::cerr << "tinstream las-info: " << n.error().message << "\n";
        return 1;
      }
      if (*n == 0) break;
      EVP_DigestUpdate(sha.get(), buf.data(), *n * rl);
      records += *n;
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned len = 0;
    EVP_DigestFinal_ex(sha.get(), md, &len);
    std::string hex;
    for (unsigned i = 0; i < len; ++i) {
      static const char* d = "0123456789abcdef";
      hex += d[md[i] >> 4];
      hex += d[md[i] & 15];
    }
    j["decoded"] = {{"records", records},
                    {"seconds", seconds},
                    {"points_per_second", seconds > 0 ? static_cast<double>(records) / seconds : 0},
                    {"records_sha256", hex}};
  }
  std::cout << j.dump(2) << "\n";
  return 0;
}

const CommandRegistration kRegistration{
    "las-info",
    "Show a LAS/LAZ file's header, VLRs and LASzip chunk table (JSON); --decode checks every "
    "record",
    [](CLI::App& sub) -> CommandRun {
      auto opts = std::make_shared<LasInfoOptions>();
      sub.add_option("file", opts->path, "A .las, .laz or .copc.laz file")->required();
      sub.add_flag("--decode", opts->decode,
                   "Decode every record: report the count, time, points/s and the sha256 of "
                   "the records as an uncompressed LAS file holds them");
      sub.add_option("--threads", opts->threads,
                     "LAZ decoding threads for --decode (0: one per core, at most 8)")
          ->default_val(0);
      sub.add_flag("--chunks", opts->chunks, "List every LAZ chunk (offset, bytes, points)");
      return [opts] { return run_las_info(*opts); };
    }};

}  // namespace
}  // namespace tinstream::cli
