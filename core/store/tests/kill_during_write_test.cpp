// A writer process killed in the middle of writing a new version must leave the published
// version intact and the file uncorrupted; the next writer cleans up and publishes.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <map>
#include <random>

#include "store_test_util.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::store {
namespace {

using testing::basic_info;
using testing::sql_value;
using testing::TempDir;
using tile::TinTile;
using tile::testing::make_grid_tile;

std::vector<TinTile> level_tiles(std::uint32_t z, std::uint64_t seed, std::size_t count) {
  std::mt19937_64 rng(seed);
  std::vector<TinTile> out;
  const std::uint32_t n = 1u << z;
  for (std::size_t i = 0; i < count; ++i) {
    const auto k = static_cast<std::uint32_t>(i);
    out.push_back(make_grid_tile({z, k % n, (k / n) % n}, 4, 4, rng));
  }
  return out;
}

// Everything the published layer serves, as raw stored bytes per tile.
std::map<geo::TileId, std::vector<std::uint8_t>> snapshot(TileStore& store,
                                                          const std::string& layer) {
  std::map<geo::TileId, std::vector<std::uint8_t>> out;
  auto ids = store.tile_ids(layer);
  if (!ids) return out;
  for (const auto& id : *ids) {
    auto t = store.tile(layer, id);
    if (t.ok() && t->has_value()) out[id] = (*t)->compressed;
  }
  return out;
}

enum class Death { sigkill, exit_in_transaction };

// Where the child dies, found through SQLite's own statement trace (installed on every
// connection the child opens, with sqlite3_auto_extension), so the store needs no test hook: it
// counts the tile rows of each write transaction, and when the third transaction that writes
// tiles starts its 101st row (100 rows written, the transaction open) it tells the parent
// through the pipe and then either blocks until SIGKILLed or _exits on the spot.
struct DeathPoint {
  int pipe_fd = -1;
  Death death = Death::sigkill;
  int tile_transactions = 0;
  int rows = 0;  // tile rows in the current transaction
};
DeathPoint death_point;  // set in the child only

int on_statement(unsigned, void*, void*, void* sql_text) {
  const char* sql = static_cast<const char*>(sql_text);  // SQLITE_TRACE_STMT: the SQL text
  if (std::strncmp(sql, "BEGIN", 5) == 0) death_point.rows = 0;
  if (std::strstr(sql, "INSERT OR REPLACE INTO tiles") == nullptr) return 0;
  if (++death_point.rows == 1) ++death_point.tile_transactions;
  if (death_point.tile_transactions == 3 && death_point.rows == 101) {
    const char byte = 'w';
    if (write(death_point.pipe_fd, &byte, 1) != 1) _exit(13);
    if (death_point.death == Death::exit_in_transaction) _exit(0);  // no destructors, tx open
    for (;;) pause();  // hold the transaction until killed
  }
  return 0;
}

extern "C" int trace_tile_rows(sqlite3* db, const char**, const sqlite3_api_routines*) {
  sqlite3_trace_v2(db, SQLITE_TRACE_STMT, on_statement, nullptr);
  return SQLITE_OK;
}

// The child: opens the store, starts a new version of `layer` and writes tiles; two batches
// (512 tiles) are committed before the death point in the third.
[[noreturn]] void child_writer(const std::filesystem::path& path, int pipe_fd, Death death) {
  death_point = {pipe_fd, death, 0, 0};
  if (sqlite3_auto_extension(reinterpret_cast<void (*)()>(trace_tile_rows)) != SQLITE_OK) _exit(9);
  auto store = TileStore::open(path, TileStore::Mode::read_write);
  if (!store) _exit(10);
  auto writer = store->begin_layer(basic_info("dem"));
  if (!writer) _exit(11);
  std::mt19937_64 rng(99);
  for (std::size_t i = 0; i < 5000; ++i) {
    const auto k = static_cast<std::uint32_t>(i);
    const TinTile t = make_grid_tile({14, k % 16384, (k / 16384) % 16384}, 3, 3, rng);
    if (!(*writer)->put(t).ok()) _exit(12);
  }
  _exit(14);  // never reached: the death point is in the third batch
}

// Kills and reaps the child if the parent leaves the test early (a failed ASSERT).
struct ChildGuard {
  pid_t pid = 0;
  ~ChildGuard() {
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

void kill_writer_and_check(Death death) {
  TempDir dir;
  const auto path = dir / "store.tinstream";
  const auto v1_tiles = level_tiles(6, 1, 40);
  std::map<geo::TileId, std::vector<std::uint8_t>> before;
  std::int64_t v1_version = 0;
  {
    auto store = TileStore::open(path, TileStore::Mode::read_write);
    ASSERT_TRUE(store.ok()) << store.error().message;
    auto writer = store->begin_layer(basic_info("dem"));
    ASSERT_TRUE(writer.ok());
    for (const auto& t : v1_tiles) ASSERT_TRUE((*writer)->put(t).ok());
    ASSERT_TRUE((*writer)->publish(basic_info("dem")).ok());
    before = snapshot(*store, "dem");
    v1_version = store->layer("dem")->version;
  }  // closed before fork: the child must not inherit an open SQLite connection
  ASSERT_EQ(before.size(), v1_tiles.size());

  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    close(fds[0]);
    child_writer(path, fds[1], death);
  }
  close(fds[1]);
  ChildGuard guard{pid};
  char byte = 0;
  const ssize_t got = read(fds[0], &byte, 1);  // blocks until the child has written enough
  close(fds[0]);
  ASSERT_EQ(got, 1) << "the child writer failed before writing its tiles";
  if (death == Death::sigkill) {
    // The child holds an open write transaction with 100 rows of its third batch: a read-only
    // reader in this process still sees version 1, unchanged.
    auto reader = TileStore::open(path, TileStore::Mode::read_only);
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    EXPECT_EQ(reader->layer("dem")->version, v1_version);
    EXPECT_EQ(snapshot(*reader, "dem"), before);
    kill(pid, SIGKILL);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  guard.pid = 0;
  if (death == Death::sigkill) {
    ASSERT_TRUE(WIFSIGNALED(status));
  } else {
    ASSERT_TRUE(WIFEXITED(status));
    ASSERT_EQ(WEXITSTATUS(status), 0);
  }

  // The child's committed batches are in the file, unpublished.
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM layer_versions WHERE status = 'building'"), "1");
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles WHERE z = 14"), "512");
  EXPECT_EQ(sql_value(path, "PRAGMA integrity_check"), "ok");

  auto store = TileStore::open(path, TileStore::Mode::read_write);
  ASSERT_TRUE(store.ok()) << store.error().message;
  auto layer = store->layer("dem");
  ASSERT_TRUE(layer.ok());
  EXPECT_EQ(layer->version, v1_version);
  EXPECT_EQ(layer->tile_count, v1_tiles.size());
  EXPECT_EQ(snapshot(*store, "dem"), before);
  for (const auto& t : v1_tiles) {
    auto back = store->read_tile("dem", t.id);
    ASSERT_TRUE(back.ok() && back->has_value());
    EXPECT_TRUE(tile::testing::same_tile(t, **back));
  }

  // A new writer collects the dead writer's version and publishes.
  auto writer = store->begin_layer(basic_info("dem"));
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles WHERE z = 14"), "0");
  const auto v2_tiles = level_tiles(7, 2, 30);
  for (const auto& t : v2_tiles) ASSERT_TRUE((*writer)->put(t).ok());
  ASSERT_TRUE((*writer)->publish(basic_info("dem")).ok());
  auto v2 = store->layer("dem");
  ASSERT_TRUE(v2.ok());
  EXPECT_GT(v2->version, v1_version);
  EXPECT_EQ(v2->tile_count, v2_tiles.size());
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles"), std::to_string(v2_tiles.size()));
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM layer_versions"), "1");
  EXPECT_EQ(sql_value(path, "PRAGMA integrity_check"), "ok");
}

TEST(KillDuringWrite, SigkilledWriterLeavesThePublishedVersionIntact) {
  kill_writer_and_check(Death::sigkill);
}

TEST(KillDuringWrite, WriterExitingInsideATransactionLeavesThePublishedVersionIntact) {
  kill_writer_and_check(Death::exit_in_transaction);
}

}  // namespace
}  // namespace tinstream::store
