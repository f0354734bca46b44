#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <random>
#include <thread>

#include "store_test_util.hpp"
#include "tinstream/base/fault.hpp"
#include "tinstream/store/queued_writer.hpp"
#include "tinstream/tile/codec.hpp"

namespace tinstream::store {
namespace {

using testing::basic_info;
using testing::sql_value;
using testing::TempDir;
using tile::TinTile;
using tile::testing::make_grid_tile;
using tile::testing::same_tile;

TileStore open_rw(const std::filesystem::path& p) {
  auto s = TileStore::open(p, TileStore::Mode::read_write);
  if (!s) throw std::runtime_error(s.error().message);
  return std::move(*s);
}

TileStore open_ro(const std::filesystem::path& p) {
  auto s = TileStore::open(p, TileStore::Mode::read_only);
  if (!s) throw std::runtime_error(s.error().message);
  return std::move(*s);
}

// Tiles of levels 0..3 along a diagonal, with content depending on `seed`.
std::vector<TinTile> some_tiles(std::uint64_t seed, int count = 12) {
  std::mt19937_64 rng(seed);
  std::vector<TinTile> out;
  for (int i = 0; i < count; ++i) {
    const auto z = static_cast<std::uint32_t>(i < 8 ? i % 4 : 12);
    const std::uint32_t n = 1u << z;
    const geo::TileId id{z, static_cast<std::uint32_t>(i * 13) % n,
                         static_cast<std::uint32_t>(i * 7 / 4) % n};
    bool duplicate = false;
    for (const auto& t : out) duplicate |= t.id == id;
    if (duplicate) continue;
    out.push_back(make_grid_tile(id, 1 + static_cast<std::uint32_t>(rng() % 6),
                                 1 + static_cast<std::uint32_t>(rng() % 6), rng));
  }
  return out;
}

void write_layer(TileStore& store, const std::string& name, const std::vector<TinTile>& tiles) {
  auto writer = store.begin_layer(basic_info(name));
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  for (const auto& t : tiles) ASSERT_TRUE((*writer)->put(t).ok());
  const Status s = (*writer)->publish(basic_info(name));
  ASSERT_TRUE(s.ok()) << s.error().message;
}

TEST(TileStore, PutGetPublishReadRoundTrip) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  const auto tiles = some_tiles(1);
  auto writer = store.begin_layer(basic_info("dem"));
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  for (const auto& t : tiles) ASSERT_TRUE((*writer)->put(t).ok());
  for (const auto& t : tiles) {
    auto back = (*writer)->get(t.id);
    ASSERT_TRUE(back.ok()) << back.error().message;
    ASSERT_TRUE(back->has_value());
    EXPECT_TRUE(same_tile(t, **back));
  }
  auto absent = (*writer)->get({10, 1, 1});
  ASSERT_TRUE(absent.ok());
  EXPECT_FALSE(absent->has_value());
  auto ids = (*writer)->tile_ids();
  ASSERT_TRUE(ids.ok());
  EXPECT_EQ(ids->size(), tiles.size());
  EXPECT_TRUE(std::is_sorted(ids->begin(), ids->end()));
  // Not visible before publish.
  EXPECT_EQ(store.layer("dem").error().code, ErrorCode::not_found);
  ASSERT_TRUE((*writer)->publish(basic_info("dem")).ok());

  for (const auto& t : tiles) {
    auto read = store.read_tile("dem", t.id);
    ASSERT_TRUE(read.ok()) << read.error().message;
    ASSERT_TRUE(read->has_value());
    EXPECT_TRUE(same_tile(t, **read));
    auto stored = store.tile("dem", t.id);
    ASSERT_TRUE(stored.ok() && stored->has_value());
    const StoredTile& s = **stored;
    EXPECT_EQ(s.id, t.id);
    EXPECT_EQ(*tile::decompress(s.compressed), tile::encode(t));
    EXPECT_EQ(s.vertex_count, t.vertex_count());
    EXPECT_EQ(s.triangle_count, t.triangles.size());
    EXPECT_EQ(s.min_z, t.min_z);
    EXPECT_EQ(s.max_z, t.max_z);
    EXPECT_EQ(s.geometric_error, t.geometric_error);
    ASSERT_GE(s.etag.size(), 3u);
    EXPECT_EQ(s.etag.front(), '"');
    EXPECT_EQ(s.etag.back(), '"');
  }
  auto level2 = store.tile_ids("dem", 2);
  ASSERT_TRUE(level2.ok());
  for (const auto& id : *level2) EXPECT_EQ(id.z, 2u);
  EXPECT_FALSE(level2->empty());
  auto missing = store.tile("dem", {12, 0, 0});
  ASSERT_TRUE(missing.ok());
  EXPECT_FALSE(missing->has_value());
}

TEST(TileStore, LayerMetadataRoundTrips) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  LayerInfo info = basic_info("meta.Layer-1");
  info.projection = geo::Projection::ellipsoidal;
  info.vertical_datum = "EGM2008";
  auto writer = store.begin_layer(info);
  ASSERT_TRUE(writer.ok());
  const auto tiles = some_tiles(2, 5);
  for (const auto& t : tiles) ASSERT_TRUE((*writer)->put(t).ok());
  info.point_count = 123456789012;
  info.source_points = 223456789012;
  info.min_z = -12.5;
  info.max_z = 4807.25;
  info.tile_count = 999;  // the store counts for itself
  info.attribution = "© Somebody, CC-BY 4.0 \"quoted\"";
  info.level_max_error = {100.5, 50.25, 0.125};
  // Eight different bounds, so that two columns bound in each other's place are seen.
  info.mercator_bounds = {-0.5, -0.125, 0.375, 0.25};
  info.bounds = {-80.5, -22.0, 90.0, 33.25};
  ASSERT_TRUE((*writer)->publish(info).ok());

  auto back = store.layer("meta.Layer-1");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->name, info.name);
  EXPECT_EQ(back->projection, geo::Projection::ellipsoidal);
  EXPECT_EQ(back->vertical_datum, "EGM2008");
  EXPECT_EQ(back->mercator_bounds.min_x, -0.5);
  EXPECT_EQ(back->mercator_bounds.min_y, -0.125);
  EXPECT_EQ(back->mercator_bounds.max_x, 0.375);
  EXPECT_EQ(back->mercator_bounds.max_y, 0.25);
  EXPECT_EQ(back->bounds.west, -80.5);
  EXPECT_EQ(back->bounds.south, -22.0);
  EXPECT_EQ(back->bounds.east, 90.0);
  EXPECT_EQ(back->bounds.north, 33.25);
  EXPECT_EQ(back->max_level, 4u);
  EXPECT_EQ(back->max_points, 1000u);
  EXPECT_EQ(back->tile_count, tiles.size());
  EXPECT_EQ(back->point_count, 123456789012u);
  EXPECT_EQ(back->source_points, 223456789012u);
  EXPECT_EQ(back->min_z, -12.5);
  EXPECT_EQ(back->max_z, 4807.25);
  EXPECT_EQ(back->level_max_error, info.level_max_error);
  EXPECT_EQ(back->options_json, info.options_json);
  EXPECT_EQ(back->attribution, info.attribution);
  EXPECT_GT(back->created_unix, 1600000000);
  EXPECT_GT(back->version, 0);
  auto all = store.layers();
  ASSERT_TRUE(all.ok());
  ASSERT_EQ(all->size(), 1u);
  EXPECT_EQ((*all)[0].name, info.name);
}

TEST(TileStore, UnknownLayerIsNotFound) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  EXPECT_EQ(store.layer("nope").error().code, ErrorCode::not_found);
  EXPECT_EQ(store.tile("nope", {1, 0, 0}).error().code, ErrorCode::not_found);
  EXPECT_EQ(store.read_tile("nope", {1, 0, 0}).error().code, ErrorCode::not_found);
  EXPECT_EQ(store.tile_ids("nope").error().code, ErrorCode::not_found);
  EXPECT_EQ(store.delete_layer("nope").error().code, ErrorCode::not_found);
  const auto e = store.layer("nope").error().message;
  EXPECT_NE(e.find("nope"), std::string::npos);
  EXPECT_NE(e.find("a.tinstream"), std::string::npos);
  EXPECT_EQ(store.tile("../etc", {1, 0, 0}).error().code, ErrorCode::invalid_argument);
  EXPECT_EQ(store.tile("dem", {1, 2, 0}).error().code, ErrorCode::invalid_argument);
  auto layers = store.layers();
  ASSERT_TRUE(layers.ok());
  EXPECT_TRUE(layers->empty());
}

TEST(TileStore, PublishIsAtomicForReadersBeforeAndAfter) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto writer_store = open_rw(path);
  write_layer(writer_store, "dem", some_tiles(3));
  auto reader_before = open_ro(path);
  const auto v1 = reader_before.layer("dem");
  ASSERT_TRUE(v1.ok());

  const auto new_tiles = some_tiles(4, 600);  // more than one batch
  auto writer = writer_store.begin_layer(basic_info("dem"));
  ASSERT_TRUE(writer.ok());
  for (std::size_t i = 0; i < new_tiles.size(); ++i) {
    ASSERT_TRUE((*writer)->put(new_tiles[i]).ok());
    if (i == 300) {
      // Some batches committed, one open: readers still see version 1 only.
      auto mid = reader_before.layer("dem");
      ASSERT_TRUE(mid.ok()) << mid.error().message;
      EXPECT_EQ(mid->version, v1->version);
      auto t = reader_before.read_tile("dem", new_tiles[0].id);
      ASSERT_TRUE(t.ok());
      auto opened_now = open_ro(path);
      EXPECT_EQ(opened_now.layer("dem")->version, v1->version);
    }
  }
  ASSERT_TRUE((*writer)->flush().ok());
  EXPECT_EQ(reader_before.layer("dem")->version, v1->version);
  ASSERT_TRUE((*writer)->publish(basic_info("dem")).ok());

  auto reader_after = open_ro(path);
  for (TileStore* reader : {&reader_before, &reader_after}) {
    auto v2 = reader->layer("dem");
    ASSERT_TRUE(v2.ok());
    EXPECT_GT(v2->version, v1->version);
    EXPECT_EQ(v2->tile_count, new_tiles.size());
    auto ids = reader->tile_ids("dem");
    ASSERT_TRUE(ids.ok());
    EXPECT_EQ(ids->size(), new_tiles.size());
    auto t = reader->read_tile("dem", new_tiles[17].id);
    ASSERT_TRUE(t.ok()) << t.error().message;
    ASSERT_TRUE(t->has_value());
    EXPECT_TRUE(same_tile(**t, new_tiles[17]));
  }
}

TEST(TileStore, AbandonedWriterLeavesThePreviousVersionIntact) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto store = open_rw(path);
  const auto v1_tiles = some_tiles(5);
  write_layer(store, "dem", v1_tiles);
  const auto v1 = store.layer("dem");
  {
    auto writer = store.begin_layer(basic_info("dem"));
    ASSERT_TRUE(writer.ok());
    for (const auto& t : some_tiles(6, 300)) ASSERT_TRUE((*writer)->put(t).ok());
  }  // destroyed without publish
  {
    auto writer = store.begin_layer(basic_info("dem"));
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->put(some_tiles(7)[0]).ok());
    (*writer)->abandon();
    EXPECT_FALSE((*writer)->put(some_tiles(7)[1]).ok());
    EXPECT_FALSE((*writer)->publish(basic_info("dem")).ok());
  }
  EXPECT_EQ(store.layer("dem")->version, v1->version);
  for (const auto& t : v1_tiles) {
    auto back = store.read_tile("dem", t.id);
    ASSERT_TRUE(back.ok() && back->has_value());
    EXPECT_TRUE(same_tile(t, **back));
  }
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM layer_versions"), "1");
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles"), std::to_string(v1_tiles.size()));
}

TEST(TileStore, ReingestReplacesTheLayerAndDropsTheOldVersion) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto store = open_rw(path);
  write_layer(store, "dem", some_tiles(8));
  write_layer(store, "other", some_tiles(9, 3));
  const auto v1 = store.layer("dem");
  std::mt19937_64 rng(10);
  const TinTile only = make_grid_tile({5, 7, 7}, 3, 3, rng);
  write_layer(store, "dem", {only});
  const auto v2 = store.layer("dem");
  ASSERT_TRUE(v2.ok());
  EXPECT_GT(v2->version, v1->version);
  EXPECT_EQ(v2->tile_count, 1u);
  auto ids = store.tile_ids("dem");
  ASSERT_TRUE(ids.ok());
  ASSERT_EQ(ids->size(), 1u);
  EXPECT_EQ((*ids)[0], only.id);
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM layer_versions"), "2");
  EXPECT_EQ(
      sql_value(path, "SELECT count(*) FROM tiles WHERE version = " + std::to_string(v1->version)),
      "0");
  EXPECT_EQ(store.tile_ids("other")->size(), 3u);
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM published_tiles WHERE layer = 'dem'"), "1");
}

// Two connections (as two ingest jobs would have) write different layers of one file, their puts
// interleaved: batches are written in short transactions, so neither waits for the other's work.
TEST(TileStore, ConcurrentWritersOfDifferentLayers) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto a = open_rw(path);
  auto b = open_rw(path);
  auto wa = a.begin_layer(basic_info("alpha"));
  auto wb = b.begin_layer(basic_info("beta"));
  ASSERT_TRUE(wa.ok() && wb.ok());
  const auto ta = some_tiles(30, 700);
  const auto tb = some_tiles(31, 700);
  for (std::size_t i = 0; i < std::max(ta.size(), tb.size()); ++i) {
    if (i < ta.size()) {
      ASSERT_TRUE((*wa)->put(ta[i]).ok());
    }
    if (i < tb.size()) {
      ASSERT_TRUE((*wb)->put(tb[i]).ok());
    }
  }
  // Reads through the writer see batched and flushed tiles alike.
  auto first = (*wa)->get(ta.front().id);
  auto last = (*wa)->get(ta.back().id);
  ASSERT_TRUE(first.ok() && first->has_value() && last.ok() && last->has_value());
  EXPECT_TRUE(same_tile(**first, ta.front()));
  EXPECT_TRUE(same_tile(**last, ta.back()));
  ASSERT_TRUE((*wb)->publish(basic_info("beta")).ok());
  ASSERT_TRUE((*wa)->publish(basic_info("alpha")).ok());
  EXPECT_EQ(a.layer("beta")->tile_count, tb.size());
  EXPECT_EQ(b.layer("alpha")->tile_count, ta.size());
  EXPECT_EQ(sql_value(path, "PRAGMA integrity_check"), "ok");
}

TEST(TileStore, PutOfTheSameIdReplacesTheTile) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  auto w = store.begin_layer(basic_info("dem"));
  std::mt19937_64 rng(32);
  const TinTile first = make_grid_tile({6, 1, 2}, 2, 2, rng);
  const TinTile second = make_grid_tile({6, 1, 2}, 3, 3, rng);
  ASSERT_TRUE((*w)->put(first).ok());
  ASSERT_TRUE((*w)->flush().ok());
  ASSERT_TRUE((*w)->put(second).ok());
  EXPECT_TRUE(same_tile(**(*w)->get(second.id), second));  // pending beats flushed
  ASSERT_TRUE((*w)->put(first).ok());
  EXPECT_TRUE(same_tile(**(*w)->get(first.id), first));  // latest pending wins
  ASSERT_TRUE((*w)->publish(basic_info("dem")).ok());
  EXPECT_TRUE(same_tile(**store.read_tile("dem", first.id), first));
  EXPECT_EQ(store.layer("dem")->tile_count, 1u);
}

TEST(TileStore, PreparedTilesOnOtherThreadsStoreAsPutDoes) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  const auto tiles = some_tiles(41);
  // Prepared on worker threads, put by this one: the same rows as put(TinTile) writes.
  std::vector<Result<StoredTile>> prepared(tiles.size(), Error(ErrorCode::internal, "unset"));
  {
    std::vector<std::jthread> workers;  // joined at the end of the block
    for (std::size_t w = 0; w < 2; ++w) {
      workers.emplace_back([&, w] {
        for (std::size_t i = w; i < tiles.size(); i += 2) prepared[i] = prepare_tile(tiles[i]);
      });
    }
  }
  write_layer(store, "direct", tiles);
  auto writer = store.begin_layer(basic_info("prepared"));
  ASSERT_TRUE(writer.ok());
  for (auto& p : prepared) {
    ASSERT_TRUE(p.ok()) << p.error().message;
    ASSERT_TRUE((*writer)->put(std::move(*p)).ok());
  }
  for (const auto& t : tiles) {
    auto pending = (*writer)->get_stored(t.id);  // still in the writer's batch
    ASSERT_TRUE(pending.ok() && pending->has_value());
    auto decoded = decode_tile(**pending);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_TRUE(same_tile(*decoded, t));
  }
  ASSERT_TRUE((*writer)->publish(basic_info("prepared")).ok());
  for (const auto& t : tiles) {
    const StoredTile a = **store.tile("direct", t.id);
    const StoredTile b = **store.tile("prepared", t.id);
    EXPECT_EQ(a.compressed, b.compressed);
    EXPECT_EQ(a.etag, b.etag);
    EXPECT_EQ(a.vertex_count, b.vertex_count);
    EXPECT_EQ(a.triangle_count, b.triangle_count);
    EXPECT_EQ(a.geometric_error, b.geometric_error);
  }
  // A blob holding another tile than its row says is refused by decode_tile.
  StoredTile moved = **store.tile("direct", tiles[0].id);
  moved.id = tiles[1].id;
  auto wrong = decode_tile(moved);
  ASSERT_FALSE(wrong.ok());
  EXPECT_EQ(wrong.error().code, ErrorCode::corrupt_data);
  EXPECT_NE(wrong.error().message.find(tiles[0].id.to_string()), std::string::npos);
  // An invalid id is refused before any encoding.
  TinTile bad = tiles[0];
  bad.id = {3, 9, 0};
  EXPECT_EQ(prepare_tile(bad).error().code, ErrorCode::invalid_argument);
}

StoredTile prepared(const TinTile& t) {
  auto r = prepare_tile(t);
  if (!r) throw std::runtime_error(r.error().message);
  return std::move(*r);
}

TEST(QueuedWriter, TilesPushedFromSeveralThreadsAreAllStored) {
  std::vector<TinTile> tiles;
  std::mt19937_64 rng(51);
  for (std::uint32_t i = 0; i < 300; ++i) {
    tiles.push_back(make_grid_tile({10, i % 32, i / 32}, 2 + i % 3, 2, rng));
  }
  const std::size_t one_tile = prepared(tiles[0]).compressed.size();
  // (tiles, bytes) bounds smaller than the tiles in flight, so push() waits on each: the count;
  // a byte budget below one tile (one tile at a time, let in once the queue is empty); about
  // three tiles' bytes.
  const std::pair<std::size_t, std::size_t> bounds[] = {
      {3, static_cast<std::size_t>(-1)}, {1000, 1}, {1000, 3 * one_tile}};
  for (const auto& [capacity, max_bytes] : bounds) {
    SCOPED_TRACE("capacity " + std::to_string(capacity) + ", bytes " + std::to_string(max_bytes));
    TempDir dir;
    auto store = open_rw(dir / "a.tinstream");
    auto writer = store.begin_layer(basic_info("q"));
    ASSERT_TRUE(writer.ok());
    {
      QueuedWriter queue(**writer, capacity, max_bytes);
      // Each worker keeps its first failure; the test asserts on this thread once all are joined
      // (an ASSERT in a worker would only end that worker).
      std::vector<Status> results(3);
      {
        std::vector<std::jthread> workers;  // joined however this block is left
        for (std::size_t w = 0; w < 3; ++w) {
          workers.emplace_back([&, w] {
            for (std::size_t i = w; i < tiles.size() && results[w].ok(); i += 3) {
              auto p = prepare_tile(tiles[i]);
              results[w] = p ? queue.push(std::move(*p)) : Status(p.error());
            }
          });
        }
      }
      for (const Status& r : results) ASSERT_TRUE(r.ok()) << r.error().message;
      ASSERT_TRUE(queue.finish().ok());
      EXPECT_LE(queue.peak().tiles, capacity);
      EXPECT_LE(queue.peak().bytes, std::max(max_bytes, one_tile * 2));
      EXPECT_EQ(queue.stored(), tiles.size());
      EXPECT_EQ(queue.push(prepared(tiles[0])).error().code,
                ErrorCode::invalid_argument);  // after finish()
    }
    ASSERT_TRUE((*writer)->publish(basic_info("q")).ok());
    EXPECT_EQ(store.layer("q")->tile_count, tiles.size());
    for (const auto& t : tiles) EXPECT_TRUE(same_tile(**store.read_tile("q", t.id), t));
  }
}

// The bounds, observed: the queue's thread is held at its first put (fault point "store.queue",
// pause) while one thread pushes; the queue fills to exactly its bound and no further, whichever
// (tiles or bytes) binds first. Before, the bounds were only set, never seen to hold.
TEST(QueuedWriter, TheQueueFillsToItsBoundAndNoFurtherWhileTheStoreIsBusy) {
  ASSERT_TRUE(fault::enabled()) << "fault points are not compiled into this test build";
  std::vector<StoredTile> tiles;
  std::mt19937_64 rng(53);
  for (std::uint32_t i = 0; i < 12; ++i) {
    tiles.push_back(prepared(make_grid_tile({10, i, 7}, 2 + i % 4, 2, rng)));
  }
  std::vector<std::size_t> sizes;
  sizes.reserve(tiles.size());
  for (const auto& t : tiles) sizes.push_back(t.compressed.size());
  // Tiles after the first (held by the paused thread) that fit `max_bytes` one after another.
  auto fitting = [&](std::size_t capacity, std::size_t max_bytes) {
    std::size_t n = 0, bytes = 0;
    while (1 + n < tiles.size() && n < capacity && (n == 0 || bytes + sizes[1 + n] <= max_bytes)) {
      bytes += sizes[1 + n];
      ++n;
    }
    return std::pair{n, bytes};
  };
  const std::size_t two_to_four = sizes[1] + sizes[2] + sizes[3];
  const std::pair<std::size_t, std::size_t> bounds[] = {
      {4, static_cast<std::size_t>(-1)}, {1000, two_to_four}, {1000, 1}, {2, two_to_four}};
  for (const auto& [capacity, max_bytes] : bounds) {
    SCOPED_TRACE("capacity " + std::to_string(capacity) + ", bytes " + std::to_string(max_bytes));
    const auto [expect_tiles, expect_bytes] = fitting(capacity, max_bytes);
    TempDir dir;
    auto store = open_rw(dir / "a.tinstream");
    auto writer = store.begin_layer(basic_info("q"));
    ASSERT_TRUE(writer.ok());
    fault::Arm hold("store.queue", 0, fault::Kind::pause);
    QueuedWriter queue(**writer, capacity, max_bytes);
    std::atomic<std::size_t> pushed{0};
    Status result;
    {
      std::jthread producer([&] {
        for (const auto& t : tiles) {
          result = queue.push(StoredTile(t));
          if (!result.ok()) return;
          // The rest only once the thread holds the first: the queue then fills from empty.
          if (++pushed == 1 && !hold.wait_paused()) return;
        }
      });
      ASSERT_TRUE(hold.wait_paused()) << "the queue's thread never took a tile";
      // The producer pushes until the bound stops it; wait for that state (no sleep-and-assert:
      // it must come, and with the thread held nothing can leave the queue).
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(1);
      while (pushed.load() < 1 + expect_tiles && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::yield();
      }
      EXPECT_EQ(pushed.load(), 1 + expect_tiles);
      EXPECT_EQ(queue.queued().tiles, expect_tiles);
      EXPECT_EQ(queue.queued().bytes, expect_bytes);
      EXPECT_EQ(queue.peak().tiles, expect_tiles);  // never more, on the way there
      EXPECT_EQ(queue.peak().bytes, expect_bytes);
      hold.release();
    }  // the producer finishes once the thread goes on
    ASSERT_TRUE(result.ok()) << result.error().message;
    ASSERT_TRUE(queue.finish().ok());
    EXPECT_EQ(queue.stored(), tiles.size());
    // Draining and refilling, the bounds held throughout (a tile above the byte bound goes alone).
    EXPECT_LE(queue.peak().tiles, capacity);
    EXPECT_LE(queue.peak().bytes,
              std::max(max_bytes, *std::max_element(sizes.begin(), sizes.end())));
  }
}

TEST(QueuedWriter, TheFirstStoreErrorStopsItAndIsReturned) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  const auto tiles = some_tiles(52);
  auto writer = store.begin_layer(basic_info("q"));
  ASSERT_TRUE(writer.ok());
  ASSERT_TRUE((*writer)->publish(basic_info("q")).ok());  // every later put() fails
  QueuedWriter queue(**writer, 1);
  Status first;
  for (const auto& t : tiles) {  // the queue's thread fails on the first; a later push says so
    first = queue.push(prepared(t));
    if (!first.ok()) break;
  }
  const Status end = queue.finish();
  ASSERT_FALSE(end.ok());
  EXPECT_NE(end.error().message.find("already published"), std::string::npos)
      << end.error().message;
  EXPECT_EQ(queue.stored(), 0u);
  if (!first.ok()) {
    EXPECT_EQ(first.error().message, end.error().message);
  }
}

TEST(TileStore, PublishedTilesViewHasQuadkeyAndTmsRow) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto store = open_rw(path);
  std::mt19937_64 rng(33);
  std::vector<TinTile> tiles;
  for (const geo::TileId id : {geo::TileId{0, 0, 0}, geo::TileId{3, 3, 5},
                               geo::TileId{30, (1u << 30) - 1, 12345}, geo::TileId{17, 70000, 1}}) {
    tiles.push_back(make_grid_tile(id, 1, 1, rng));
  }
  write_layer(store, "dem", tiles);
  for (const auto& t : tiles) {
    const std::string where =
        " FROM published_tiles WHERE layer = 'dem' AND z = " + std::to_string(t.id.z) +
        " AND x = " + std::to_string(t.id.x) + " AND y = " + std::to_string(t.id.y);
    EXPECT_EQ(sql_value(path, "SELECT quadkey" + where), t.id.quadkey()) << t.id.to_string();
    EXPECT_EQ(sql_value(path, "SELECT tms_y" + where), std::to_string(t.id.tms_row()));
  }
  EXPECT_EQ(sql_value(path, "SELECT z FROM published_tiles WHERE quadkey = '213'"), "3");
}

TEST(TileStore, DeleteLayerRemovesItAndItsTiles) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto store = open_rw(path);
  write_layer(store, "dem", some_tiles(11));
  write_layer(store, "keep", some_tiles(12, 2));
  ASSERT_TRUE(store.delete_layer("dem").ok());
  EXPECT_EQ(store.layer("dem").error().code, ErrorCode::not_found);
  EXPECT_EQ(store.delete_layer("dem").error().code, ErrorCode::not_found);
  EXPECT_EQ(store.layers()->size(), 1u);
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles"), "2");
  write_layer(store, "dem", some_tiles(13, 2));
  EXPECT_EQ(store.tile_ids("dem")->size(), 2u);
}

TEST(TileStore, OneLiveWriterPerLayer) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  auto first = store.begin_layer(basic_info("dem"));
  ASSERT_TRUE(first.ok());
  auto second = store.begin_layer(basic_info("dem"));
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.error().message.find("being written"), std::string::npos);
  auto other = store.begin_layer(basic_info("other"));
  ASSERT_TRUE(other.ok());
  (*first)->abandon();
  EXPECT_TRUE(store.begin_layer(basic_info("dem")).ok());
}

TEST(TileStore, StaleBuildingVersionOfADeadWriterIsCollected) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  {
    auto store = open_rw(path);
    write_layer(store, "dem", some_tiles(14, 3));
  }
  // A version left by a writer that no longer exists (pid beyond any pid_max).
  EXPECT_EQ(sql_value(path,
                      "INSERT INTO layer_versions SELECT 1000, name, 'building', 2147483000, "
                      "writer_host, writer_start, projection, vertical_datum, min_x, min_y, "
                      "max_x, max_y, west, south, east, north, min_level, max_level, max_points, "
                      "tile_count, point_count, source_points, min_z, max_z, level_max_error, "
                      "options, attribution, started_unix, NULL FROM layer_versions",
                      false),
            "");
  EXPECT_EQ(sql_value(path,
                      "INSERT INTO tiles SELECT 1000, z, x, y, data, etag, min_z, max_z, "
                      "geometric_error, vertex_count, triangle_count FROM tiles",
                      false),
            "");
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles WHERE version = 1000"), "3");
  auto store = open_rw(path);
  auto writer = store.begin_layer(basic_info("dem"));
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM tiles WHERE version = 1000"), "0");
  EXPECT_EQ(sql_value(path, "SELECT count(*) FROM layer_versions WHERE id = 1000"), "0");
}

TEST(TileStore, EtagsAreContentDerived) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  std::mt19937_64 rng(15);
  const TinTile a = make_grid_tile({3, 1, 1}, 3, 3, rng);
  TinTile b = a;
  b.id = {3, 2, 1};
  const auto r = b.id.bounds();
  const auto ra = a.id.bounds();
  for (auto* list : {&b.north, &b.south, &b.interior}) {
    for (auto& v : *list) v.x = v.x - ra.min_x + r.min_x;
  }
  for (auto& c : b.corners) c.x = c.x == ra.min_x ? r.min_x : r.max_x;
  for (auto& v : b.east) v.x = r.max_x;
  for (auto& v : b.west) v.x = r.min_x;
  auto writer = store.begin_layer(basic_info("dem"));
  ASSERT_TRUE((*writer)->put(a).ok());
  ASSERT_TRUE((*writer)->put(b).ok());
  TinTile a2 = a;
  a2.id = {4, 0, 0};  // same geometry, different id: different bytes
  ASSERT_TRUE((*writer)->put(a2).ok());
  ASSERT_TRUE((*writer)->publish(basic_info("dem")).ok());
  const auto ea = (*store.tile("dem", a.id))->etag;
  const auto eb = (*store.tile("dem", b.id))->etag;
  EXPECT_NE(ea, eb);
  // Re-ingesting identical content gives identical ETags (caches stay valid).
  write_layer(store, "dem", {a});
  EXPECT_EQ((*store.tile("dem", a.id))->etag, ea);
}

TEST(TileStore, CorruptBlobIsAnErrorNamingLayerAndTile) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  auto store = open_rw(path);
  const auto tiles = some_tiles(16, 2);
  write_layer(store, "dem", tiles);
  const auto& id = tiles[1].id;
  EXPECT_EQ(sql_value(path,
                      "UPDATE tiles SET data = x'789c0300' WHERE z = " + std::to_string(id.z) +
                          " AND x = " + std::to_string(id.x) + " AND y = " + std::to_string(id.y),
                      false),
            "");
  auto r = store.read_tile("dem", id);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::corrupt_data);
  EXPECT_NE(r.error().message.find("dem"), std::string::npos);
  EXPECT_NE(r.error().message.find(id.to_string()), std::string::npos);
}

TEST(TileStore, NonSqliteFileIsAClearError) {
  TempDir dir;
  const auto path = dir / "notes.txt";
  {
    std::ofstream out(path);
    for (int i = 0; i < 200; ++i) out << "this is not a database, line " << i << "\n";
  }
  for (auto mode : {TileStore::Mode::read_only, TileStore::Mode::read_write}) {
    auto s = TileStore::open(path, mode);
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.error().code, ErrorCode::corrupt_data) << s.error().message;
    EXPECT_NE(s.error().message.find(path.string()), std::string::npos) << s.error().message;
  }
  // An SQLite database of some other application.
  const auto other = dir / "other.db";
  sql_value(other, "", true);
  {
    sqlite3* db = nullptr;
    sqlite3_open(other.c_str(), &db);
    sqlite3_exec(db, "CREATE TABLE t (a)", nullptr, nullptr, nullptr);
    sqlite3_close(db);
  }
  for (auto mode : {TileStore::Mode::read_only, TileStore::Mode::read_write}) {
    auto s = TileStore::open(other, mode);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find("not a tinstream tile store"), std::string::npos)
        << s.error().message;
  }
}

TEST(TileStore, ReadOnlyOpenOfAMissingFileIsNotFound) {
  TempDir dir;
  const auto path = dir / "missing.tinstream";
  auto s = TileStore::open(path, TileStore::Mode::read_only);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::not_found);
  EXPECT_NE(s.error().message.find(path.string()), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(path));
  auto in_missing_dir =
      TileStore::open(dir / "no/such/dir/a.tinstream", TileStore::Mode::read_write);
  ASSERT_FALSE(in_missing_dir.ok());
  EXPECT_NE(in_missing_dir.error().message.find("no/such/dir"), std::string::npos);
}

TEST(TileStore, ReadOnlyStoreRefusesWrites) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  {
    auto store = open_rw(path);
    write_layer(store, "dem", some_tiles(17, 2));
  }
  auto ro = open_ro(path);
  EXPECT_FALSE(ro.begin_layer(basic_info("x")).ok());
  EXPECT_FALSE(ro.delete_layer("dem").ok());
  EXPECT_EQ(ro.tile_ids("dem")->size(), 2u);
}

TEST(TileStore, ReopenKeepsEverythingAndTheFileIsInWalMode) {
  TempDir dir;
  const auto path = dir / "a.tinstream";
  const auto tiles = some_tiles(18);
  {
    auto store = open_rw(path);
    write_layer(store, "dem", tiles);
  }
  EXPECT_EQ(sql_value(path, "PRAGMA journal_mode"), "wal");
  EXPECT_EQ(sql_value(path, "SELECT value FROM metadata WHERE name = 'format'"), "tinstream-store");
  auto store = open_rw(path);
  for (const auto& t : tiles) EXPECT_TRUE(same_tile(t, **store.read_tile("dem", t.id)));
  EXPECT_EQ(sql_value(path, "PRAGMA integrity_check"), "ok");
}

TEST(TileStore, RejectsBadLayerInfo) {
  TempDir dir;
  auto store = open_rw(dir / "a.tinstream");
  LayerInfo info = basic_info("dem");
  info.options_json = "{not json";
  EXPECT_EQ(store.begin_layer(info).error().code, ErrorCode::invalid_argument);
  info = basic_info("dem");
  info.max_level = 31;
  EXPECT_FALSE(store.begin_layer(info).ok());
  info = basic_info("dem");
  info.min_z = std::nan("");
  EXPECT_FALSE(store.begin_layer(info).ok());
  info = basic_info("a/b");
  EXPECT_FALSE(store.begin_layer(info).ok());
  auto writer = store.begin_layer(basic_info("dem"));
  ASSERT_TRUE(writer.ok());
  EXPECT_FALSE((*writer)->publish(basic_info("other")).ok());  // metadata of another layer
  TinTile bad_id;
  bad_id.id = {2, 4, 4};
  EXPECT_FALSE((*writer)->put(bad_id).ok());
  EXPECT_TRUE((*writer)->publish(basic_info("dem")).ok());
}

TEST(LayerName, Validation) {
  for (const char* good : {"dem", "swiss_alti3d-2024.v2", "A", "a.b", "0123456789"}) {
    EXPECT_TRUE(validate_layer_name(good).ok()) << good;
  }
  EXPECT_TRUE(validate_layer_name(std::string(64, 'x')).ok());
  for (const char* bad :
       {"", ".hidden", "..", "a/b", "a\\b", "a b", "dem?", "ä", "a:b", "%2e%2e"}) {
    EXPECT_FALSE(validate_layer_name(bad).ok()) << bad;
  }
  EXPECT_FALSE(validate_layer_name(std::string(65, 'x')).ok());
  EXPECT_FALSE(validate_layer_name(std::string_view("a\0b", 3)).ok());
}

}  // namespace
}  // namespace tinstream::store
