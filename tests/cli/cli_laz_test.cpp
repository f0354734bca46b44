// LAZ through the real `tinstream` CLI into a real SQLite store: a LAZ file ingests to exactly
// the tiles of its uncompressed twin, a terrestrial LAZ scan ingests with a CRS override, and
// las-info reports and decodes LAZ files.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const fs::path kTinstream = fs::path(TINSTREAM_BINARY_DIR) / "bin" / "tinstream";
const fs::path kData = TINSTREAM_SHARED_DATA;

struct Outcome {
  int status = -1;
  std::string out, err;
};

Outcome run(const std::vector<std::string>& args, const fs::path& dir) {
  const fs::path out_file = dir / "stdout", err_file = dir / "stderr";
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
  return r;
}

// Every published tile of a layer: "z/x/y etag", in (z, x, y) order. The ETag is a hash of the
// stored bytes, so equal lists mean byte-identical tiles.
std::vector<std::string> tiles_of(const fs::path& store, const std::string& layer) {
  std::vector<std::string> out;
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(store.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) return out;
  sqlite3_stmt* st = nullptr;
  const char* sql =
      "SELECT z || '/' || x || '/' || y || ' ' || etag FROM published_tiles WHERE layer = ?1 "
      "ORDER BY z, x, y";
  if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) == SQLITE_OK) {
    sqlite3_bind_text(st, 1, layer.c_str(), -1, SQLITE_TRANSIENT);
    while (sqlite3_step(st) == SQLITE_ROW) {
      out.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
    }
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return out;
}

#define REQUIRE_DATA(name)                                                   \
  do {                                                                       \
    if (!fs::exists(kData / (name))) {                                       \
      GTEST_SKIP() << "real dataset " << (kData / (name)) << " not present"; \
    }                                                                        \
  } while (false)

class CliLaz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tinstream-cli-laz-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    store_ = dir_ / "tiles.sqlite";
  }
  void TearDown() override { fs::remove_all(dir_); }
  Outcome ingest(const std::string& layer, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {
        kTinstream.string(), "ingest", "--store", store_.string(),         "--layer", layer,
        "--threads",         "2",      "--tmp",   (dir_ / "tmp").string(), "--json",  "-q"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run(args, dir_);
  }
  fs::path dir_, store_;
};

TEST_F(CliLaz, AutzenLazIngestsToTheTilesOfAutzenLas) {
  REQUIRE_DATA("autzen_trim.laz");
  REQUIRE_DATA("autzen_trim.las");
  const Outcome a = ingest("from_las", {(kData / "autzen_trim.las").string()});
  ASSERT_EQ(a.status, 0) << a.err;
  const Outcome b = ingest("from_laz", {(kData / "autzen_trim.laz").string()});
  ASSERT_EQ(b.status, 0) << b.err;
  const auto sa = nlohmann::json::parse(a.out), sb = nlohmann::json::parse(b.out);
  EXPECT_EQ(sb["records_read"], 110000);
  EXPECT_EQ(sb["points_accepted"], sa["points_accepted"]);
  EXPECT_EQ(sb["finest_level"], sa["finest_level"]);
  const auto ta = tiles_of(store_, "from_las"), tb = tiles_of(store_, "from_laz");
  EXPECT_GT(ta.size(), 10u);
  EXPECT_EQ(ta, tb);
  const Outcome v =
      run({kTinstream.string(), "verify", "--store", store_.string(), "--layer", "from_laz", "-q"},
          dir_);
  EXPECT_EQ(v.status, 0) << v.out << v.err;
}

// lone_star_tls.laz's GeoKeys say EPSG:4326 for UTM metres (SOURCES.md): read as degrees its
// points fall outside the Mercator square, with --crs EPSG:32612 it is Lone Star Geyser.
TEST_F(CliLaz, LoneStarLazIngestsWithTheCrsOverride) {
  REQUIRE_DATA("lone_star_tls.laz");
  const Outcome wrong = ingest("wrong", {(kData / "lone_star_tls.laz").string()});
  EXPECT_NE(wrong.status, 0);
  EXPECT_NE(wrong.err.find("lone_star_tls.laz"), std::string::npos) << wrong.err;
  const Outcome r = ingest("lone_star", {"--crs", "EPSG:32612", "--max-points", "30000",
                                         "--no-pyramid", (kData / "lone_star_tls.laz").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto s = nlohmann::json::parse(r.out);
  EXPECT_EQ(s["records_read"], 518862);
  EXPECT_EQ(s["points_accepted"], 518862);  // class 0 everywhere: no ground, nothing dropped
  EXPECT_FALSE(tiles_of(store_, "lone_star").empty());
}

TEST_F(CliLaz, LasInfoReportsTheLaszipVlrAndDecodes) {
  REQUIRE_DATA("laz_simple.copc.laz");
  const Outcome r = run({kTinstream.string(), "las-info", "--decode", "--chunks",
                         (kData / "laz_simple.copc.laz").string()},
                        dir_);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["format"], "LAZ");
  EXPECT_EQ(j["point_format"], 7);
  EXPECT_EQ(j["laszip"]["compressor"], "layered chunked");
  EXPECT_EQ(j["laszip"]["chunk_size"], "variable");
  EXPECT_EQ(j["laszip"]["items"][1]["type"], "RGB14");
  EXPECT_EQ(j["chunks"]["count"], 65);
  EXPECT_EQ(j["chunks"]["table"].size(), 65u);
  EXPECT_EQ(j["decoded"]["records"], 1065);
  EXPECT_EQ(j["decoded"]["records_sha256"],
            "361eda6829430490b1bba3a2665408642d16211f6c349b2f11edf451c8164422");
  const Outcome bad = run({kTinstream.string(), "las-info", (dir_ / "none.laz").string()}, dir_);
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("none.laz"), std::string::npos);
}

}  // namespace
