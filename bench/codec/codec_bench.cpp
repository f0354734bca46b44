// bench/codec: tile blob format version 1 vs version 2 on the tiles of a real store. Not a test.
//
//   codec_bench <store.tinstream> [reps] [levels]
//
// Reads every blob of the store's `tiles` table (any layer, any version), inflates and decodes it
// (either format version), then for each variant — version 1 at level 2 (what LayerWriter::put
// wrote before version 2), version 2 at each libdeflate level of `levels` (default "1,2,4") and
// version 2 through tile::compress_runs (level "runs" in the table) — times
//   encode + compress      tile::compress(tile::encode(t, version), level), as LayerWriter::put;
//   decompress + decode    tile::decode(*tile::decompress(blob)), as the LOD stage and server;
// in process CPU time (the machine may be shared: CPU time is what a variant costs; wall time is
// printed too), the best of `reps` runs over all tiles. Every variant's blobs are checked to
// decode to the tiles read (bit-identical) before anything is printed. Ratios are against v1 L2.
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <sstream>
#include <string>
#include <vector>

#include "tinstream/tile/codec.hpp"

namespace {

using tinstream::tile::FormatVersion;
using tinstream::tile::TinTile;

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double wall_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Timing {
  double cpu = 1e300, wall = 1e300;
};

// Best (smallest CPU) of `reps` runs of f().
template <typename F>
Timing best_of(int reps, F&& f) {
  Timing best;
  for (int r = 0; r < reps; ++r) {
    const double c0 = cpu_seconds(), w0 = wall_seconds();
    f();
    const double cpu = cpu_seconds() - c0, wall = wall_seconds() - w0;
    if (cpu < best.cpu) best = {cpu, wall};
  }
  return best;
}

std::vector<std::vector<std::uint8_t>> read_blobs(const char* path) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path, &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    std::fprintf(stderr, "cannot open %s: %s\n", path, sqlite3_errmsg(db));
    std::exit(1);
  }
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db, "SELECT data FROM tiles", -1, &st, nullptr) != SQLITE_OK) {
    std::fprintf(stderr, "%s: %s\n", path, sqlite3_errmsg(db));
    std::exit(1);
  }
  std::vector<std::vector<std::uint8_t>> blobs;
  while (sqlite3_step(st) == SQLITE_ROW) {
    const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(st, 0));
    blobs.emplace_back(p, p + sqlite3_column_bytes(st, 0));
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return blobs;
}

bool same_bits(const TinTile& a, const TinTile& b) {
  return tinstream::tile::encode(a, FormatVersion::v1) ==
         tinstream::tile::encode(b, FormatVersion::v1);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: codec_bench <store> [reps] [levels, e.g. 1,2,4]\n");
    return 2;
  }
  const int reps = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  std::vector<int> levels;
  {
    std::stringstream in(argc > 3 ? argv[3] : "1,2,4");
    for (std::string item; std::getline(in, item, ',');) levels.push_back(std::stoi(item));
  }

  std::vector<TinTile> tiles;
  std::size_t raw_bytes = 0, vertices = 0;
  for (const auto& blob : read_blobs(argv[1])) {
    auto raw = tinstream::tile::decompress(blob);
    auto t = raw ? tinstream::tile::decode(*raw) : tinstream::Result<TinTile>(raw.error());
    if (!t) {
      std::fprintf(stderr, "%s\n", t.error().message.c_str());
      return 1;
    }
    raw_bytes += raw->size();
    vertices += t->vertex_count();
    tiles.push_back(std::move(*t));
  }
  if (tiles.empty()) {
    std::fprintf(stderr, "no tiles in %s\n", argv[1]);
    return 1;
  }
  const double n = static_cast<double>(tiles.size());
  std::printf("%zu tiles, %.0f vertices per tile, %.1f MB uncompressed (%d reps, best CPU)\n",
              tiles.size(), static_cast<double>(vertices) / n,
              1e-6 * static_cast<double>(raw_bytes), reps);
  std::printf("%-8s %5s %11s %7s %14s %14s %12s %14s %14s\n", "format", "level", "stored MB",
              "ratio", "enc+comp ms/t", "(wall ms/t)", "(enc ms/t)", "infl+dec ms/t",
              "(wall ms/t)");

  struct Variant {
    FormatVersion version;
    int level;  // libdeflate level, or kRuns: tile::compress_runs
  };
  constexpr int kRuns = -1;
  std::vector<Variant> variants{{FormatVersion::v1, 2}};
  for (const int level : levels) variants.push_back({FormatVersion::v2, level});
  variants.push_back({FormatVersion::v2, kRuns});

  double base_encode = 0, base_decode = 0, base_bytes = 0;
  for (const Variant& v : variants) {
    std::vector<std::vector<std::uint8_t>> stored(tiles.size());
    const Timing enc = best_of(reps, [&] {
      for (std::size_t i = 0; i < tiles.size(); ++i) {
        const auto raw = tinstream::tile::encode(tiles[i], v.version);
        stored[i] = v.level == kRuns ? tinstream::tile::compress_runs(raw)
                                     : tinstream::tile::compress(raw, v.level);
      }
    });
    // encode alone (its share of enc+comp), the blobs kept out of the timing by a checksum.
    std::size_t sink = 0;
    const Timing encode_only = best_of(reps, [&] {
      for (const TinTile& t : tiles) sink += tinstream::tile::encode(t, v.version).back();
    });
    std::vector<TinTile> back(tiles.size());
    bool failed = false;
    const Timing dec = best_of(reps, [&] {
      for (std::size_t i = 0; i < tiles.size(); ++i) {
        auto raw = tinstream::tile::decompress(stored[i]);
        auto t = raw ? tinstream::tile::decode(*raw) : tinstream::Result<TinTile>(raw.error());
        if (!t) {
          failed = true;
          continue;
        }
        back[i] = std::move(*t);
      }
    });
    std::size_t bytes = 0;
    for (std::size_t i = 0; i < tiles.size(); ++i) {
      bytes += stored[i].size();
      if (failed || !same_bits(back[i], tiles[i])) {
        std::fprintf(stderr, "tile %zu does not round-trip\n", i);
        return 1;
      }
    }
    const double mb = 1e-6 * static_cast<double>(bytes);
    std::printf("v%-7d %5s %11.2f %7.4f %14.3f %14.3f %12.3f %14.3f %14.3f%s\n",
                static_cast<int>(v.version),
                v.level == kRuns ? "runs" : std::to_string(v.level).c_str(), mb,
                static_cast<double>(bytes) / static_cast<double>(raw_bytes), 1e3 * enc.cpu / n,
                1e3 * enc.wall / n, 1e3 * encode_only.cpu / n, 1e3 * dec.cpu / n,
                1e3 * dec.wall / n, sink == 1 ? " " : "");
    if (base_bytes == 0) {
      base_encode = enc.cpu;
      base_decode = dec.cpu;
      base_bytes = mb;
    } else {
      std::printf(
          "%14s vs v1 L2: encode+compress CPU %.2fx faster, bytes %.3fx, "
          "inflate+decode CPU %.2fx faster\n",
          "", base_encode / enc.cpu, mb / base_bytes, base_decode / dec.cpu);
    }
  }
  return 0;
}
