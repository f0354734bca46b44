// Runs the built `tinstream` binary (info, export) on a store written with the library and parses
// its output independently of the code that wrote it.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <sstream>

#include "store_test_util.hpp"

namespace tinstream::store {
namespace {

using testing::basic_info;
using testing::TempDir;
using tile::TinTile;

const std::filesystem::path kBinary = TINSTREAM_BINARY_DIR "/bin/tinstream";

struct ProcessResult {
  int status = -1;
  std::string out, err;
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

ProcessResult run(const TempDir& dir, const std::vector<std::string>& args) {
  std::string command = quote(kBinary.string());
  for (const auto& a : args) command += " " + quote(a);
  const auto out = dir / "stdout.txt";
  const auto err = dir / "stderr.txt";
  command += " >" + quote(out.string()) + " 2>" + quote(err.string());
  ProcessResult r;
  const int raw = std::system(command.c_str());
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kBinary)) GTEST_SKIP() << kBinary << " not built";
    std::mt19937_64 rng(42);
    tile_ = tile::testing::make_grid_tile({12, 2145, 1434}, 6, 5, rng, false);
    tile_.corner_nodata[3] = true;
    tile_.corners[3].z = 0;
    tile_.update_z_range();
    world_ = tile::testing::make_grid_tile({0, 0, 0}, 2, 2, rng, false);
    path_ = dir_ / "store.tinstream";
    auto store = TileStore::open(path_, TileStore::Mode::read_write);
    ASSERT_TRUE(store.ok());
    auto writer = store->begin_layer(basic_info("dem"));
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->put(tile_).ok());
    ASSERT_TRUE((*writer)->put(world_).ok());
    ASSERT_TRUE((*writer)->publish(basic_info("dem")).ok());
    auto other = store->begin_layer(basic_info("other"));
    ASSERT_TRUE((*other)->publish(basic_info("other")).ok());
  }

  TempDir dir_;
  std::filesystem::path path_;
  TinTile tile_, world_;
};

// Spherical Mercator inverse, written independently of core/geo.
double lat_from_y(double y) {
  return std::atan(std::sinh(std::numbers::pi * y)) * 180.0 / std::numbers::pi;
}

std::size_t decimals(const std::string& token) {
  const auto dot = token.find('.');
  return dot == std::string::npos ? 0 : token.size() - dot - 1;
}

TEST_F(CliTest, InfoListsLayers) {
  const ProcessResult r = run(dir_, {"info", "--store", path_.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["layers"].size(), 2u);
  EXPECT_EQ(j["layers"][0]["name"], "dem");
  EXPECT_EQ(j["layers"][0]["tile_count"], 2);
  EXPECT_EQ(j["layers"][1]["name"], "other");
}

TEST_F(CliTest, InfoShowsOneLayer) {
  const ProcessResult r = run(dir_, {"info", "--store", path_.string(), "--layer", "dem"});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["name"], "dem");
  EXPECT_EQ(j["projection"], "spherical");
  EXPECT_EQ(j["max_level"], 4);
  EXPECT_EQ(j["options"]["max_points"], 1000);
  EXPECT_EQ(j["level_max_error"].size(), 5u);
  EXPECT_EQ(j["bounds"]["lonlat"]["south"], -22.0);
}

TEST_F(CliTest, InfoShowsOneTile) {
  const std::string qk = tile_.id.quadkey();
  const ProcessResult r =
      run(dir_, {"info", "--store", path_.string(), "--layer", "dem", "--tile", qk});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["tile"]["quadkey"], qk);
  EXPECT_EQ(j["tile"]["z"], 12);
  EXPECT_EQ(j["vertex_count"], tile_.vertex_count());
  EXPECT_EQ(j["triangle_count"], tile_.triangles.size());
  EXPECT_EQ(j["roles"]["north"], tile_.north.size());
  EXPECT_EQ(j["roles"]["interior"], tile_.interior.size());
  EXPECT_EQ(j["nodata_corners"], nlohmann::json::array({"SE"}));
  EXPECT_EQ(j["structure"], "ok");
  const auto b = tile_.id.bounds();
  EXPECT_EQ(j["bounds"]["mercator"]["min_x"].get<double>(), b.min_x);
  EXPECT_NEAR(j["bounds"]["lonlat"]["north"].get<double>(), lat_from_y(b.max_y), 1e-9);
  EXPECT_NEAR(j["bounds"]["lonlat"]["west"].get<double>(), 180.0 * b.min_x, 1e-9);
  // The level-0 tile is the empty quadkey.
  const ProcessResult w =
      run(dir_, {"info", "--store", path_.string(), "--layer", "dem", "--tile", ""});
  ASSERT_EQ(w.status, 0) << w.err;
  EXPECT_EQ(nlohmann::json::parse(w.out)["tile"]["z"], 0);
}

TEST_F(CliTest, ExportObjIsParsableCcwAndPrecise) {
  const ProcessResult r = run(dir_, {"export", "--store", path_.string(), "--layer", "dem",
                                     "--tile", tile_.id.quadkey(), "--format", "obj"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::istringstream in(r.out);
  std::string line;
  std::vector<std::array<double, 3>> v;
  std::vector<std::array<long, 3>> f;
  bool faces_started = false;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string kind;
    fields >> kind;
    if (kind == "v") {
      ASSERT_FALSE(faces_started) << "vertex after faces";
      std::string lon, lat, h;
      fields >> lon >> lat >> h;
      EXPECT_GE(decimals(lon), 9u) << line;
      EXPECT_GE(decimals(lat), 9u) << line;
      EXPECT_EQ(decimals(h), 4u) << line;
      v.push_back({std::stod(lon), std::stod(lat), std::stod(h)});
    } else if (kind == "f") {
      faces_started = true;
      std::array<long, 3> t{};
      fields >> t[0] >> t[1] >> t[2];
      ASSERT_FALSE(fields.fail()) << line;
      f.push_back(t);
    } else {
      FAIL() << "unexpected line: " << line;
    }
  }
  ASSERT_EQ(v.size(), tile_.vertex_count());
  ASSERT_EQ(f.size(), tile_.triangles.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    const auto& src = tile_.vertex(i);
    EXPECT_NEAR(v[i][0], 180.0 * src.x, 1e-9);
    EXPECT_NEAR(v[i][1], lat_from_y(src.y), 1e-9);
    EXPECT_NEAR(v[i][2], src.z, 5e-5);
  }
  for (const auto& t : f) {
    for (const long k : t) {
      ASSERT_GE(k, 1);
      ASSERT_LE(k, static_cast<long>(v.size()));
    }
    const auto& a = v[static_cast<std::size_t>(t[0] - 1)];
    const auto& b = v[static_cast<std::size_t>(t[1] - 1)];
    const auto& c = v[static_cast<std::size_t>(t[2] - 1)];
    const double area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    EXPECT_GT(area, 0) << "clockwise face in lon/lat";
  }
}

TEST_F(CliTest, ExportObjDropNodataLeavesOutTheCornerAndItsTriangles) {
  const ProcessResult r =
      run(dir_, {"export", "--store", path_.string(), "--layer", "dem", "--tile",
                 tile_.id.quadkey(), "--format", "obj", "--drop-nodata"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::istringstream in(r.out);
  std::string line;
  std::vector<double> heights;
  std::vector<std::array<long, 3>> faces;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string kind;
    fields >> kind;
    if (kind == "v") {
      double lon = 0, lat = 0, h = 0;
      fields >> lon >> lat >> h;
      heights.push_back(h);
    } else if (kind == "f") {
      std::array<long, 3> t{};
      fields >> t[0] >> t[1] >> t[2];
      faces.push_back(t);
    }
  }
  // Corner 3 (SE) is NODATA in the fixture: one vertex fewer, the others in order.
  ASSERT_EQ(heights.size(), tile_.vertex_count() - 1);
  for (std::size_t i = 0, k = 0; i < tile_.vertex_count(); ++i) {
    if (i == 3) continue;
    EXPECT_NEAR(heights[k++], tile_.vertex(i).z, 5e-5) << "vertex " << i;
  }
  // The faces: the tile's triangles without corner 3, in order, renumbered (1-based, the
  // vertices after the dropped corner move down by one).
  std::vector<std::array<long, 3>> expected;
  for (const auto& t : tile_.triangles) {
    if (t[0] == 3 || t[1] == 3 || t[2] == 3) continue;
    std::array<long, 3> f{};
    for (std::size_t k = 0; k < 3; ++k) f[k] = t[k] < 3 ? t[k] + 1 : t[k];
    expected.push_back(f);
  }
  ASSERT_LT(expected.size(), tile_.triangles.size());  // the corner had triangles
  EXPECT_EQ(faces, expected);
}

TEST_F(CliTest, ExportJsonCarriesRolesNodataAndMercator) {
  const auto out = dir_ / "tile.json";
  const ProcessResult r =
      run(dir_, {"export", "--store", path_.string(), "--layer", "dem", "--tile",
                 tile_.id.quadkey(), "--format", "json", "--out", out.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
  const auto j = nlohmann::json::parse(slurp(out));
  ASSERT_EQ(j["vertices"].size(), tile_.vertex_count());
  ASSERT_EQ(j["triangles"].size(), tile_.triangles.size());
  std::map<std::string, std::size_t> roles;
  for (std::size_t i = 0; i < j["vertices"].size(); ++i) {
    const auto& jv = j["vertices"][i];
    roles[jv["role"].get<std::string>()]++;
    EXPECT_EQ(jv["x"].get<double>(), tile_.vertex(i).x);  // exact: full double precision
    EXPECT_EQ(jv["y"].get<double>(), tile_.vertex(i).y);
    EXPECT_EQ(jv["height"].get<double>(), tile_.vertex(i).z);
    EXPECT_EQ(jv["nodata"].get<bool>(), i == 3);
    EXPECT_NEAR(jv["lon"].get<double>(), 180.0 * tile_.vertex(i).x, 1e-9);
  }
  EXPECT_EQ(roles["corner"], 4u);
  EXPECT_EQ(roles["north"], tile_.north.size());
  EXPECT_EQ(roles["east"], tile_.east.size());
  EXPECT_EQ(roles["south"], tile_.south.size());
  EXPECT_EQ(roles["west"], tile_.west.size());
  EXPECT_EQ(roles["interior"], tile_.interior.size());
  EXPECT_EQ(j["vertices"][0]["role"], "corner");
  EXPECT_EQ(j["vertices"][4]["role"], "north");
  for (const auto& t : j["triangles"]) {
    for (const auto& k : t) EXPECT_LT(k.get<std::size_t>(), tile_.vertex_count());
  }
}

TEST_F(CliTest, ErrorsAreOneLineAndNonZero) {
  const std::vector<std::vector<std::string>> cases = {
      {"export", "--store", path_.string(), "--layer", "nope", "--tile", "0"},
      {"export", "--store", path_.string(), "--layer", "dem", "--tile", "0123"},
      {"export", "--store", path_.string(), "--layer", "dem", "--tile", "04"},
      {"export", "--store", (dir_ / "missing.tinstream").string(), "--layer", "dem", "--tile", "0"},
      {"export", "--store", path_.string(), "--layer", "dem"},
      {"info", "--store", path_.string(), "--layer", "nope"},
      {"info", "--store", path_.string(), "--tile", "0"},
      {"info", "--store", path_.string(), "--layer", "dem", "--tile", "33333"},
  };
  for (const auto& args : cases) {
    const ProcessResult r = run(dir_, args);
    EXPECT_NE(r.status, 0) << args[4];
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind("tinstream ", 0), 0u) << r.err;
  }
  const auto notes = dir_ / "notes.txt";
  std::ofstream(notes) << std::string(4096, 'x');
  const ProcessResult bad = run(dir_, {"info", "--store", notes.string()});
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find(notes.string()), std::string::npos) << bad.err;
  EXPECT_NE(run(dir_, {"export", "--store", path_.string(), "--layer", "dem", "--tile", "0",
                       "--format", "ply"})
                .status,
            0);
}

TEST_F(CliTest, HelpTexts) {
  for (const char* command : {"info", "export"}) {
    const ProcessResult r = run(dir_, {command, "--help"});
    EXPECT_EQ(r.status, 0);
    EXPECT_NE(r.out.find("--store"), std::string::npos);
  }
}

}  // namespace
}  // namespace tinstream::store
