// Integration tests of the `tinstream` command line: ingest real LAS and GeoTIFF files into a real
// SQLite store, verify, inspect and export; bad inputs; killing an ingest midway.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "tinstream/store/tile_store.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path kTinstream = fs::path(TINSTREAM_BINARY_DIR) / "bin" / "tinstream";
const fs::path kData = TINSTREAM_SHARED_DATA;

struct Outcome {
  int status = -1;
  std::string out, err;
};

// Runs argv (no shell), capturing stdout and stderr.
Outcome run(const std::vector<std::string>& args) {
  const fs::path out_file =
      fs::temp_directory_path() / ("tinstream-cli-out-" + std::to_string(::getpid()));
  const fs::path err_file = out_file.string() + ".err";
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::freopen(out_file.c_str(), "w", stdout);
    std::freopen(err_file.c_str(), "w", stderr);
    std::vector<char*> argv;
    argv.reserve(args.size() + 1);
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int wstatus = 0;
  ::waitpid(pid, &wstatus, 0);
  Outcome r;
  r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
  std::stringstream o, e;
  o << std::ifstream(out_file).rdbuf();
  e << std::ifstream(err_file).rdbuf();
  r.out = o.str();
  r.err = e.str();
  fs::remove(out_file);
  fs::remove(err_file);
  return r;
}

std::string sql_value(const fs::path& db_path, const std::string& sql) {
  sqlite3* db = nullptr;
  std::string value;
  if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) == SQLITE_OK &&
        sqlite3_step(st) == SQLITE_ROW) {
      value = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    }
    sqlite3_finalize(st);
  }
  sqlite3_close(db);
  return value;
}

// Skips the calling test when a real dataset is absent (a user's clone has no ../shared).
// A macro: GTEST_SKIP only returns from the function it is written in.
#define REQUIRE_DATA(name)                                                   \
  do {                                                                       \
    if (!fs::exists(kData / (name))) {                                       \
      GTEST_SKIP() << "real dataset " << (kData / (name)) << " not present"; \
    }                                                                        \
  } while (false)

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tinstream-cli-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    store_ = dir_ / "tiles.sqlite";
  }
  void TearDown() override { fs::remove_all(dir_); }
  Outcome ingest(const std::string& layer, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {
        kTinstream.string(), "ingest", "--store", store_.string(),        "--layer", layer,
        "--threads",         "2",      "--tmp",   (dir_ / "tmp").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    return run(args);
  }
  // Starts `tinstream ingest` of `input` into layer `layer` in the background (stderr to `err`),
  // with the fault points `fault` armed (TINSTREAM_FAULT, base/fault.hpp) when not empty.
  pid_t spawn_ingest(const std::string& layer, const fs::path& input, const fs::path& err,
                     const std::string& fault = {}) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      if (!fault.empty()) ::setenv("TINSTREAM_FAULT", fault.c_str(), 1);
      std::freopen("/dev/null", "w", stdout);
      std::freopen(err.c_str(), "w", stderr);
      const std::string s = store_.string(), t = (dir_ / "tmp").string(), b = input.string();
      ::execl(kTinstream.c_str(), kTinstream.c_str(), "ingest", "--store", s.c_str(), "--layer",
              layer.c_str(), "--crs", "EPSG:4326", "--max-points", "2000", "--threads", "1",
              "--tmp", t.c_str(), b.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    return pid;
  }
  Outcome verify(const std::string& layer) {
    return run({kTinstream.string(), "verify", "--store", store_.string(), "--layer", layer, "-q"});
  }
  fs::path dir_, store_;
};

// Hilly terrain near Lausanne as lon/lat/height text.
void write_xyz(const fs::path& path, std::size_t n, std::uint64_t seed) {
  std::ofstream out(path);
  out.precision(12);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double lon = 6.6 + 0.05 * u(rng), lat = 46.5 + 0.05 * u(rng);
    out << lon << " " << lat << " " << 500 + 120 * std::sin(lon * 200) * std::cos(lat * 170)
        << "\n";
  }
}

TEST_F(Cli, EveryCommandHasHelp) {
  for (const char* cmd : {"ingest", "verify", "info", "export", "triangulate", "sample"}) {
    const Outcome r = run({kTinstream.string(), cmd, "--help"});
    EXPECT_EQ(r.status, 0) << cmd;
    EXPECT_NE(r.out.find("--"), std::string::npos) << cmd;
  }
  const Outcome ingest_help = run({kTinstream.string(), "ingest", "--help"});
  EXPECT_NE(ingest_help.out.find("class 2"), std::string::npos)
      << "the class filter rule is in --help";
}

// The synthetic LAS of `tinstream sample` (demo and benchmark input) spreads its points over the
// whole square: no strip is clipped, so no line of points piles up on an edge (once, 13–60 % of
// the last strip's points shared the north edge's y, a degenerate input the benchmarks then
// measured by accident).
TEST_F(Cli, SampleSpreadsItsPointsOverTheSquare) {
  const fs::path las = dir_ / "sample.las";
  // 30000 points at 4 per m²: an 86.6 m square, narrower than one 100 m flight strip.
  const Outcome r = run({kTinstream.string(), "sample", "--out", las.string(), "--points", "30000",
                         "--density", "4"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream in(las, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GE(bytes.size(), 227u);
  std::uint32_t offset = 0, count = 0;
  std::uint16_t record = 0;
  std::memcpy(&offset, bytes.data() + 96, 4);
  std::memcpy(&record, bytes.data() + 105, 2);
  std::memcpy(&count, bytes.data() + 107, 4);
  ASSERT_EQ(count, 30000u);
  ASSERT_EQ(bytes.size(), offset + std::size_t{count} * record);
  std::map<std::int32_t, int> per_y;
  std::int32_t min_y = INT32_MAX, max_y = INT32_MIN;
  for (std::uint32_t i = 0; i < count; ++i) {
    std::int32_t y = 0;
    std::memcpy(&y, bytes.data() + offset + std::size_t{i} * record + 4, 4);
    ++per_y[y];
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
  }
  int most = 0;
  for (const auto& [y, n] : per_y) most = std::max(most, n);
  // Uniform over 86,600 distinct millimetre rows: a handful of points per row at most.
  EXPECT_LT(most, 20) << "a line of points shares one y";
  EXPECT_GT(max_y - min_y, 80000) << "the points span the square";
}

TEST_F(Cli, LidarLasIngestVerifiesAndExports) {
  REQUIRE_DATA("autzen_trim.las");
  const Outcome r = ingest("autzen", {"--json", "-q", (kData / "autzen_trim.las").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  // SOURCES.md: 110,000 points of which 26,107 ground (class 2) — the default filter keeps ground.
  EXPECT_EQ(summary["records_read"], 110000);
  EXPECT_EQ(summary["points_accepted"], 26107);
  EXPECT_EQ(summary["min_level"], 0);
  EXPECT_GE(summary["finest_level"], 14);

  const Outcome v = verify("autzen");
  EXPECT_EQ(v.status, 0) << v.out << v.err;
  EXPECT_EQ(nlohmann::json::parse(v.out)["ok"], true);
  // Every level's stored error bounds the finest surface, also when every finest tile is sampled.
  const Outcome all = run({kTinstream.string(), "verify", "--store", store_.string(), "--layer",
                           "autzen", "-q", "--error-samples", "all"});
  ASSERT_EQ(all.status, 0) << all.out << all.err;
  const auto all_report = nlohmann::json::parse(all.out);
  EXPECT_GT(all_report["error_checks"], 0);
  EXPECT_LE(all_report["worst_error_ratio"], 1.0);
  // --surface-error adds the overlay check and its ratio; the exit status follows its verdict
  // (stored errors bound the finest data points, so the surface may be further; README).
  const Outcome surface = run({kTinstream.string(), "verify", "--store", store_.string(), "--layer",
                               "autzen", "-q", "--surface-error"});
  ASSERT_NE(surface.status, 2) << surface.err;
  const auto surface_report = nlohmann::json::parse(surface.out);
  EXPECT_GT(surface_report["worst_surface_ratio"], 0.0);
  EXPECT_EQ(surface.status == 0, surface_report["ok"] == true);
  EXPECT_FALSE(nlohmann::json::parse(v.out).contains("worst_surface_ratio"));
  const Outcome typo = run({kTinstream.string(), "verify", "--store", store_.string(), "--layer",
                            "autzen", "--error-samples", "lots"});
  EXPECT_EQ(typo.status, 2);
  EXPECT_NE(typo.err.find("--error-samples"), std::string::npos) << typo.err;

  const Outcome info =
      run({kTinstream.string(), "info", "--store", store_.string(), "--layer", "autzen"});
  ASSERT_EQ(info.status, 0) << info.err;
  const auto layer = nlohmann::json::parse(info.out);
  // Autzen Stadium, Eugene, Oregon (SOURCES.md: lon -123.0734..-123.0690, lat 44.0499..44.0516).
  const std::string text = layer.dump();
  EXPECT_NE(text.find("-123.07"), std::string::npos) << text;

  // A finest tile as OBJ: lon/lat/height vertices near Eugene, heights in metres (ft → m).
  auto store =
      tinstream::store::TileStore::open(store_, tinstream::store::TileStore::Mode::read_only);
  ASSERT_TRUE(store.ok());
  const auto finest = store->tile_ids("autzen", summary["finest_level"].get<std::uint32_t>());
  ASSERT_TRUE(finest.ok());
  ASSERT_FALSE(finest->empty());
  const Outcome obj = run({kTinstream.string(), "export", "--store", store_.string(), "--layer",
                           "autzen", "--tile", finest->front().quadkey(), "--format", "obj"});
  ASSERT_EQ(obj.status, 0) << obj.err;
  std::istringstream lines(obj.out);
  std::string kind;
  int vertices = 0, faces = 0;
  double min_h = 1e9, max_h = -1e9;
  for (std::string line; std::getline(lines, line);) {
    std::istringstream ls(line);
    ls >> kind;
    if (kind == "v") {
      double lon, lat, h;
      ls >> lon >> lat >> h;
      EXPECT_NEAR(lon, -123.071, 0.01);
      EXPECT_NEAR(lat, 44.051, 0.01);
      ++vertices;
      min_h = std::min(min_h, h);
      max_h = std::max(max_h, h);
    } else if (kind == "f") {
      ++faces;
    }
  }
  EXPECT_GT(vertices, 100);
  EXPECT_GT(faces, vertices);
  EXPECT_LT(max_h, 140.0);
  EXPECT_GE(min_h, 0.0);  // NODATA corners are at 0

  // The JSON form flags NODATA corners; every vertex with data is ground: 406.26–434.06 ft
  // = 123.8–132.3 m (heights taken as ellipsoidal: the file states no vertical datum).
  const Outcome js = run({kTinstream.string(), "export", "--store", store_.string(), "--layer",
                          "autzen", "--tile", finest->front().quadkey(), "--format", "json"});
  ASSERT_EQ(js.status, 0) << js.err;
  const auto mesh = nlohmann::json::parse(js.out);
  ASSERT_EQ(mesh["vertices"].size(), static_cast<std::size_t>(vertices));
  int with_data = 0;
  for (const auto& vertex : mesh["vertices"]) {
    if (vertex["nodata"].get<bool>()) {
      EXPECT_EQ(vertex["role"], "corner");
      continue;
    }
    ++with_data;
    EXPECT_GE(vertex["height"].get<double>(), 123.8 - 1e-6);
    EXPECT_LE(vertex["height"].get<double>(), 132.31);
  }
  EXPECT_GT(with_data, 100);
}

TEST_F(Cli, TriangulateLasGivesAnOffMeshOfTheDistinctPoints) {
  REQUIRE_DATA("autzen_trim.las");
  const fs::path off = dir_ / "autzen.off";
  const Outcome r = run({kTinstream.string(), "triangulate", "--in",
                         (kData / "autzen_trim.las").string(), "--out", off.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  // SOURCES.md: 110,000 points, 7 pairs share the same XY.
  const auto stats = nlohmann::json::parse(r.err.substr(r.err.find('{')));
  EXPECT_EQ(stats["points"], 109993);
  EXPECT_EQ(stats["duplicates"], 7);
  std::ifstream in(off);
  std::string magic;
  std::size_t nv = 0, nf = 0, ne = 0;
  in >> magic >> nv >> nf >> ne;
  EXPECT_EQ(magic, "OFF");
  EXPECT_EQ(nv, 109993u);
  EXPECT_EQ(nf, stats["triangles"].get<std::size_t>());
  // Euler: a triangulation of n points with h on the hull has 2n − 2 − h triangles.
  EXPECT_LT(nf, 2 * nv);
  EXPECT_GT(nf, 2 * nv - 2 - 2000);
}

TEST_F(Cli, GeoTiffWithNodataIngestsAndVerifies) {
  REQUIRE_DATA("luxembourg_elev.tif");
  const Outcome r = ingest(
      "lux", {"--json", "-q", "--max-points", "1000", (kData / "luxembourg_elev.tif").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  // SOURCES.md: 95 × 90 cells, 3,942 NoData → 4,608 points.
  EXPECT_EQ(summary["points"], 4608);
  EXPECT_EQ(summary["points_rejected"], 3942);
  const Outcome v = verify("lux");
  EXPECT_EQ(v.status, 0) << v.out;
}

TEST_F(Cli, MixedInputsInOneIngest) {
  REQUIRE_DATA("luxembourg_elev.tif");
  const fs::path xyz = dir_ / "extra.xyz";
  {
    std::ofstream out(xyz);
    out << "6.0 49.8 300\n6.1 49.85 320\n6.2 49.9 310\n";
  }
  const Outcome r = ingest("mixed", {"--json", "-q", "--crs", "EPSG:4326",
                                     (kData / "luxembourg_elev.tif").string(), xyz.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["points"], 4611);
  EXPECT_EQ(verify("mixed").status, 0);
}

TEST_F(Cli, JsonSummaryReportsTheTimeOfEveryPhase) {
  const fs::path xyz = dir_ / "phases.xyz";
  write_xyz(xyz, 5000, 4);
  const Outcome r =
      ingest("phases", {"--json", "-q", "--crs", "EPSG:4326", "--max-points", "500", xyz.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const std::vector<std::string> expected = {"transform", "sort", "triangulate", "lod", "publish"};
  ASSERT_EQ(j["phases"].size(), expected.size()) << j["phases"].dump();
  double wall = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const auto& p = j["phases"][i];
    EXPECT_EQ(p["phase"], expected[i]);
    EXPECT_GE(p["seconds"].get<double>(), 0.0);
    EXPECT_GE(p["cpu_seconds"].get<double>(), 0.0);
    wall += p["seconds"].get<double>();
  }
  // The phases cover the run: their sum is the total up to opening the store and the clock reads.
  EXPECT_LE(wall, j["seconds"].get<double>() + 1e-3);
  EXPECT_GE(wall, 0.5 * j["seconds"].get<double>());
  // Triangulating and thinning 5000 points takes measurable CPU.
  EXPECT_GT(
      j["phases"][2]["cpu_seconds"].get<double>() + j["phases"][3]["cpu_seconds"].get<double>(),
      0.0);
}

TEST_F(Cli, BadInputsGiveClearErrorsAndLeaveTheStoreUnchanged) {
  const fs::path good = dir_ / "good.xyz";
  write_xyz(good, 3000, 1);
  ASSERT_EQ(ingest("t", {"-q", "--crs", "EPSG:4326", good.string()}).status, 0);
  const std::string before = sql_value(store_, "SELECT group_concat(version) FROM layers");

  // Truncated LAS: a header that promises more points than the file holds.
  const fs::path las = dir_ / "truncated.las";
  {
    std::ofstream out(las, std::ios::binary);
    std::array<char, 227> header{};
    std::memcpy(header.data(), "LASF", 4);
    header[24] = 1;  // version 1.2
    header[25] = 2;
    header[94] = static_cast<char>(227);  // header size
    header[96] = static_cast<char>(227);  // offset to points
    header[104] = 0;                      // point format 0
    header[105] = 20;                     // record length
    header[107] = 100;                    // 100 points
    const double scale = 0.01;
    for (std::size_t i = 0; i < 3; ++i) std::memcpy(header.data() + 131 + 8 * i, &scale, 8);
    out.write(header.data(), header.size());
    out.write("short", 5);
  }
  Outcome r = ingest("t", {"-q", "--crs", "EPSG:32632", las.string()});
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("truncated.las"), std::string::npos) << r.err;

  // Unknown CRS.
  r = ingest("t", {"-q", "--crs", "EPSG:999999", good.string()});
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("999999"), std::string::npos) << r.err;

  // Wrong CRS: projected metres read as degrees fall off the globe.
  const fs::path utm = dir_ / "utm.xyz";
  {
    std::ofstream out(utm);
    out << "376313.6 3788627.8 500\n376343.6 3788657.8 510\n";
  }
  r = ingest("t", {"-q", "--crs", "EPSG:4326", utm.string()});
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("utm.xyz"), std::string::npos) << r.err;

  // NaN in text.
  const fs::path nan = dir_ / "nan.xyz";
  {
    std::ofstream out(nan);
    out << "6.6 46.5 500\n6.61 46.51 nan\n";
  }
  r = ingest("t", {"-q", "--crs", "EPSG:4326", nan.string()});
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("nan.xyz"), std::string::npos) << r.err;

  EXPECT_EQ(sql_value(store_, "SELECT group_concat(version) FROM layers"), before);
  EXPECT_EQ(verify("t").status, 0);
  EXPECT_EQ(sql_value(store_, "PRAGMA integrity_check"), "ok");
}

// Temporary directories of ingests (`tinstream-ingest-*`) under `tmp`.
std::size_t scratch_dirs(const fs::path& tmp) {
  std::size_t n = 0;
  std::error_code ec;
  for (fs::directory_iterator it(tmp, ec), end; !ec && it != end; it.increment(ec)) {
    n += it->path().filename().string().rfind("tinstream-ingest-", 0) == 0 ? 1 : 0;
  }
  return n;
}

// Kills and reaps a child the test leaves early (a failed ASSERT), so none outlives it.
struct ChildGuard {
  pid_t pid = 0;
  ~ChildGuard() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
  }
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

TEST_F(Cli, KilledIngestLeavesThePreviousLayerReadableAndCanBeRerun) {
  const fs::path small = dir_ / "small.xyz";
  write_xyz(small, 2000, 2);
  ASSERT_EQ(ingest("k", {"-q", "--crs", "EPSG:4326", small.string()}).status, 0);
  auto store =
      tinstream::store::TileStore::open(store_, tinstream::store::TileStore::Mode::read_only);
  ASSERT_TRUE(store.ok());
  const auto before = store->layer("k");
  ASSERT_TRUE(before.ok());
  const auto ids = store->tile_ids("k");
  ASSERT_TRUE(ids.ok());
  std::vector<std::vector<std::uint8_t>> before_bytes;
  for (const auto& id : *ids) before_bytes.push_back((*store->tile("k", id))->compressed);

  const fs::path big = dir_ / "big.xyz";
  write_xyz(big, 400000, 3);
  // A replacing ingest stops itself (SIGSTOP, fault point store.commit) right after committing
  // its first batch of tiles; it is SIGKILLed there. (Before: a poll of the store that could kill
  // before any tile was written, or let the ingest finish first.)
  const pid_t pid = spawn_ingest("k", big, dir_ / "killed.err", "store.commit@0:stop");
  ChildGuard guard{pid};
  int wstatus = 0;
  ASSERT_EQ(::waitpid(pid, &wstatus, WUNTRACED), pid);
  ASSERT_TRUE(WIFSTOPPED(wstatus))
      << "the ingest ended before committing a batch: " << slurp(dir_ / "killed.err");
  EXPECT_EQ(
      sql_value(store_,
                "SELECT count(*) FROM tiles WHERE version NOT IN (SELECT version FROM layers)"),
      "256");  // one batch of the new version, unpublished
  ::kill(pid, SIGKILL);
  ASSERT_EQ(::waitpid(pid, &wstatus, 0), pid);
  guard.pid = 0;
  ASSERT_TRUE(WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGKILL);

  // The previous version is intact, byte for byte, and the file is consistent.
  EXPECT_EQ(sql_value(store_, "PRAGMA integrity_check"), "ok");
  auto after_store =
      tinstream::store::TileStore::open(store_, tinstream::store::TileStore::Mode::read_only);
  ASSERT_TRUE(after_store.ok());
  const auto after = after_store->layer("k");
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(after->version, before->version);
  for (std::size_t i = 0; i < ids->size(); ++i) {
    const auto t = after_store->tile("k", (*ids)[i]);
    ASSERT_TRUE(t.ok() && t->has_value());
    EXPECT_EQ((*t)->compressed, before_bytes[i]);
  }
  EXPECT_EQ(verify("k").status, 0);
  // The killed ingest could not remove its temporary directory.
  EXPECT_EQ(scratch_dirs(dir_ / "tmp"), 1u);

  // Re-running the ingest succeeds, replaces the layer, and removes the abandoned directory.
  const Outcome rerun =
      ingest("k", {"-q", "--crs", "EPSG:4326", "--max-points", "2000", small.string()});
  EXPECT_EQ(rerun.status, 0) << rerun.err;
  EXPECT_EQ(verify("k").status, 0);
  EXPECT_EQ(scratch_dirs(dir_ / "tmp"), 0u);
}

TEST_F(Cli, StoredErrorsBoundTheFinestSurfaceAtTheDataEdge) {
  // The demo's sparse sample: coarse tiles' NODATA fans reach over data that finer levels
  // triangulate (the NODATA band, lod/parent.hpp); their stored errors must still bound the
  // finest surface there, as verify measures it. (Before the band term, levels 0-2 stored
  // 34.2 m where 40.8 m was measured.)
  const fs::path las = dir_ / "sparse.las";
  ASSERT_EQ(run({kTinstream.string(), "sample", "--out", las.string(), "--points", "300000",
                 "--density", "0.05"})
                .status,
            0);
  const Outcome in = ingest("edge", {"-q", "--epsilon", "0.5", las.string()});
  ASSERT_EQ(in.status, 0) << in.err;
  const Outcome v = verify("edge");
  EXPECT_EQ(v.status, 0) << v.out;
  const auto report = nlohmann::json::parse(v.out);
  EXPECT_GT(report["error_checks"], 10);
  EXPECT_LE(report["worst_error_ratio"], 1.0);
}

TEST_F(Cli, InterruptedIngestCancelsCleanly) {
  const fs::path big = dir_ / "big.xyz";
  write_xyz(big, 400000, 4);
  // The ingest stops itself as its first sorted spill starts (it has its temporary directory);
  // SIGINT arrives while it is stopped and is handled once it continues. (Before: a poll of the
  // temporary directory, racing the ingest.)
  const pid_t pid = spawn_ingest("i", big, dir_ / "interrupted.err", "pass2.spill@0:stop");
  ChildGuard guard{pid};
  int wstatus = 0;
  ASSERT_EQ(::waitpid(pid, &wstatus, WUNTRACED), pid);
  ASSERT_TRUE(WIFSTOPPED(wstatus))
      << "the ingest ended before its first spill: " << slurp(dir_ / "interrupted.err");
  EXPECT_EQ(scratch_dirs(dir_ / "tmp"), 1u);
  ::kill(pid, SIGINT);
  ::kill(pid, SIGCONT);
  ASSERT_EQ(::waitpid(pid, &wstatus, 0), pid);
  guard.pid = 0;
  // A clean exit with 128 + SIGINT, a message, nothing published, nothing left behind.
  ASSERT_TRUE(WIFEXITED(wstatus)) << "killed by the signal instead of cancelling";
  EXPECT_EQ(WEXITSTATUS(wstatus), 128 + SIGINT);
  std::ifstream err(dir_ / "interrupted.err");
  const std::string message((std::istreambuf_iterator<char>(err)), {});
  EXPECT_NE(message.find("stopped by signal"), std::string::npos) << message;
  EXPECT_EQ(scratch_dirs(dir_ / "tmp"), 0u);
  EXPECT_EQ(sql_value(store_, "PRAGMA integrity_check"), "ok");
  EXPECT_EQ(sql_value(store_, "SELECT count(*) FROM layers WHERE name = 'i'"), "0");
}

}  // namespace
