// store_impl.hpp — what the store's source files share (private to core/store): the SQLite
// handles, the prepared-statement helper Query, TileStore::Impl (one connection and its
// statement cache) and the writer-liveness checks. tile_store.cpp holds the terrain tables,
// imagery_store.cpp the imagery tables (docs/store-format.md).
#pragma once

#include <sqlite3.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::store {

// Batched writes: a transaction is committed after this many tiles or bytes, whichever first.
constexpr std::size_t kBatchTiles = 256;
constexpr std::size_t kBatchBytes = 8u << 20;  // bounds the ingest's memory (was 32 MiB)

struct DbCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
struct StmtFinalizer {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using DbHandle = std::unique_ptr<sqlite3, DbCloser>;
using StmtHandle = std::unique_ptr<sqlite3_stmt, StmtFinalizer>;

// One use of a cached prepared statement: binds, steps, and resets it when it goes out of scope.
class Query {
 public:
  explicit Query(sqlite3_stmt* s) : s_(s) {}
  Query(Query&& other) noexcept : s_(std::exchange(other.s_, nullptr)) {}
  Query& operator=(Query&&) = delete;
  ~Query() {
    if (s_ != nullptr) {
      sqlite3_reset(s_);
      sqlite3_clear_bindings(s_);
    }
  }

  Query& bind(int i, std::int64_t v) {
    (void)sqlite3_bind_int64(s_, i, v);
    return *this;
  }
  Query& bind(int i, std::uint64_t v) { return bind(i, static_cast<std::int64_t>(v)); }
  Query& bind(int i, std::uint32_t v) { return bind(i, static_cast<std::int64_t>(v)); }
  Query& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Query& bind(int i, double v) {
    (void)sqlite3_bind_double(s_, i, v);
    return *this;
  }
  Query& bind(int i, std::string_view v) {
    (void)sqlite3_bind_text(s_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Query& bind_blob(int i, std::span<const std::uint8_t> v) {
    (void)sqlite3_bind_blob64(s_, i, v.data(), v.size(), SQLITE_STATIC);
    return *this;
  }
  Query& bind_null(int i) {
    (void)sqlite3_bind_null(s_, i);
    return *this;
  }

  int step() { return sqlite3_step(s_); }
  // Makes the statement reusable within the same Query (new bindings, new step).
  void reset() {
    sqlite3_reset(s_);
    sqlite3_clear_bindings(s_);
  }

  std::int64_t i64(int c) const { return sqlite3_column_int64(s_, c); }
  std::uint32_t u32(int c) const {
    const std::int64_t v = i64(c);
    return v < 0 || v > 0xFFFFFFFFll ? 0u : static_cast<std::uint32_t>(v);
  }
  std::uint64_t u64(int c) const {
    const std::int64_t v = i64(c);
    return v < 0 ? 0u : static_cast<std::uint64_t>(v);
  }
  double f64(int c) const { return sqlite3_column_double(s_, c); }
  bool is_null(int c) const { return sqlite3_column_type(s_, c) == SQLITE_NULL; }
  std::string text(int c) const {
    const auto* p = sqlite3_column_text(s_, c);
    return p == nullptr ? std::string()
                        : std::string(reinterpret_cast<const char*>(p),
                                      static_cast<std::size_t>(sqlite3_column_bytes(s_, c)));
  }
  std::vector<std::uint8_t> blob(int c) const {
    const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(s_, c));
    const auto n = static_cast<std::size_t>(sqlite3_column_bytes(s_, c));
    return p == nullptr ? std::vector<std::uint8_t>() : std::vector<std::uint8_t>(p, p + n);
  }

 private:
  sqlite3_stmt* s_;
};

// Every versions table stores a layer's bounds as eight adjacent columns, in this order: min_x,
// min_y, max_x, max_y (Mercator), west, south, east, north (degrees). These bind them to the
// parameters first … first + 7, read them from the columns first … first + 7, and check them.
inline void bind_bounds(Query& q, int first, const geo::MercatorRect& m, const geo::LonLatRect& g) {
  q.bind(first, m.min_x).bind(first + 1, m.min_y).bind(first + 2, m.max_x);
  q.bind(first + 3, m.max_y).bind(first + 4, g.west).bind(first + 5, g.south);
  q.bind(first + 6, g.east).bind(first + 7, g.north);
}
inline void read_bounds(const Query& q, int first, geo::MercatorRect& m, geo::LonLatRect& g) {
  m = {q.f64(first), q.f64(first + 1), q.f64(first + 2), q.f64(first + 3)};
  g = {q.f64(first + 4), q.f64(first + 5), q.f64(first + 6), q.f64(first + 7)};
}
bool finite_bounds(const geo::MercatorRect& m, const geo::LonLatRect& g);

std::int64_t now_unix();
std::string host_name();
// The start time of a process (clock ticks since boot, /proc/<pid>/stat field 22), or -1 when
// unknown. Together with the pid it identifies a process across pid reuse.
std::int64_t process_start(long pid);
// True when the process recorded as (pid, start time) still runs and is not a zombie.
bool process_alive(long pid, std::int64_t recorded_start);

// The tables of one kind of layer (terrain: layers, layer_versions, tiles; imagery:
// imagery_layers, imagery_versions, imagery_tiles), for what the kinds' writers share.
struct VersionKind {
  const char* noun;  // "layer", "imagery layer": how messages name it
  // Columns id, writer_pid, writer_host, writer_start of the 'building' versions of ?1 (a name).
  const char* select_building;
  const char* count_tiles;       // the tiles of version ?1
  const char* select_published;  // the published version of name ?1
  const char* upsert_published;  // name ?1 now publishes version ?2
  // Deletes a version's tiles and its row (inside a transaction).
  Status (TileStore::Impl::*drop)(std::int64_t version);
};

struct TileStore::Impl {
  std::filesystem::path path;
  Mode mode = Mode::read_only;
  DbHandle db;
  // Prepared statements, keyed by their SQL text (the text is a literal in this file).
  std::unordered_map<std::string, StmtHandle> statements;

  Error sql_error(const std::string& what) const {
    const int code = db ? sqlite3_errcode(db.get()) : SQLITE_ERROR;
    std::string message =
        path.string() + ": " + what + ": " + (db ? sqlite3_errmsg(db.get()) : sqlite3_errstr(code));
    switch (code) {
      case SQLITE_NOTADB:
      case SQLITE_CORRUPT:
        return corrupt_data(std::move(message));
      case SQLITE_CANTOPEN:
      case SQLITE_PERM:
      case SQLITE_READONLY:
      case SQLITE_BUSY:
      case SQLITE_LOCKED:
      case SQLITE_IOERR:
      case SQLITE_FULL:
      default:
        return io_error(std::move(message));
    }
  }

  Result<Query> query(const char* sql) {
    auto it = statements.find(sql);
    if (it == statements.end()) {
      sqlite3_stmt* s = nullptr;
      if (sqlite3_prepare_v3(db.get(), sql, -1, SQLITE_PREPARE_PERSISTENT, &s, nullptr) !=
          SQLITE_OK) {
        sqlite3_finalize(s);
        return sql_error("preparing a statement");
      }
      it = statements.emplace(sql, StmtHandle(s)).first;
    }
    return Query(it->second.get());
  }

  Status exec(const char* sql, const char* what) {
    char* message = nullptr;
    if (sqlite3_exec(db.get(), sql, nullptr, nullptr, &message) != SQLITE_OK) {
      sqlite3_free(message);
      return sql_error(what);
    }
    return {};
  }

  // Runs a statement that returns no rows.
  static bool done(Query& q) { return q.step() == SQLITE_DONE; }

  Status require_writable() const {
    if (mode != Mode::read_write) {
      return invalid_argument(path.string() + ": the tile store is open read-only");
    }
    return {};
  }

  // Runs body inside its own short write transaction (BEGIN IMMEDIATE … COMMIT).
  template <typename Body>
  Status transaction(const char* what, Body&& body) {
    if (Status s = exec("BEGIN IMMEDIATE", what); !s) return s;
    Status s = body();
    if (!s) {
      (void)exec("ROLLBACK", what);
      return s;
    }
    if (Status c = exec("COMMIT", what); !c) {
      (void)exec("ROLLBACK", what);
      return c;
    }
    return {};
  }

  // The published version of a layer; not_found when the layer does not exist.
  Result<std::int64_t> published_version(std::string_view name) {
    if (Status s = validate_layer_name(name); !s) return s.error();
    auto q = query("SELECT version FROM layers WHERE name = ?1");
    if (!q) return q.error();
    q->bind(1, name);
    const int rc = q->step();
    if (rc == SQLITE_ROW) return q->i64(0);
    if (rc == SQLITE_DONE) {
      return not_found(path.string() + ": no layer '" + std::string(name) + "'");
    }
    return sql_error("looking up layer '" + std::string(name) + "'");
  }

  Result<std::optional<StoredTile>> stored_tile(std::int64_t version, const geo::TileId& id,
                                                const std::string& what);

  Result<std::vector<geo::TileId>> ids(std::int64_t version, std::optional<std::uint32_t> level,
                                       const std::string& what) {
    auto q = level
                 ? query("SELECT z, x, y FROM tiles WHERE version = ?1 AND z = ?2 ORDER BY z, x, y")
                 : query("SELECT z, x, y FROM tiles WHERE version = ?1 ORDER BY z, x, y");
    if (!q) return q.error();
    q->bind(1, version);
    if (level) q->bind(2, *level);
    std::vector<geo::TileId> out;
    int rc = 0;
    while ((rc = q->step()) == SQLITE_ROW) {
      auto id = geo::TileId::from_zxy(q->i64(0), q->i64(1), q->i64(2));
      if (!id) return corrupt_data(path.string() + ": " + what + ": " + id.error().message);
      out.push_back(*id);
    }
    if (rc != SQLITE_DONE) return sql_error("listing the tiles of " + what);
    return out;
  }

  // Deletes a version's tiles and its row. Inside a transaction.
  Status drop_version(std::int64_t version) {
    auto tiles = query("DELETE FROM tiles WHERE version = ?1");
    if (!tiles) return tiles.error();
    tiles->bind(1, version);
    if (!done(*tiles)) return sql_error("deleting the tiles of version " + std::to_string(version));
    auto row = query("DELETE FROM layer_versions WHERE id = ?1");
    if (!row) return row.error();
    row->bind(1, version);
    if (!done(*row)) return sql_error("deleting version " + std::to_string(version));
    return {};
  }

  Status create_or_check_schema();

  // Inside a write transaction: the 'building' versions of `name` that `select_building` lists
  // (columns id, writer_pid, writer_host, writer_start; ?1 = the name) whose writer is gone.
  // invalid_argument when a live process is still writing one (one writer per name and kind).
  Result<std::vector<std::int64_t>> stale_versions(const char* select_building,
                                                   const std::string& name, std::string_view kind);

  // Inside a write transaction: points the published row of `name` (`select_published` reads
  // its version, ?1 = name; `upsert_published` writes it, ?2 = version) at `version`, and returns
  // the version it replaced, if any.
  Result<std::optional<std::int64_t>> switch_published(const char* select_published,
                                                       const char* upsert_published,
                                                       const std::string& name,
                                                       std::int64_t version,
                                                       const std::string& what);

  // Inside begin_layer/begin_imagery: collects the stale 'building' versions of `name`, inserts
  // the new version's row with `insert` (?1 = name, ?2..?4 = the writer's pid, host and start
  // time; `bind(query)` binds the rest) and returns its id.
  template <typename Bind>
  Result<std::int64_t> begin_version(const VersionKind& kind, const std::string& name,
                                     const char* insert, Bind&& bind) {
    const long pid = static_cast<long>(getpid());
    std::int64_t version = 0;
    const std::string doing = std::string("starting a version of ") + kind.noun;
    Status s = transaction(doing.c_str(), [&]() -> Status {
      auto stale = stale_versions(kind.select_building, name, kind.noun);
      if (!stale) return stale.error();
      for (const std::int64_t id : *stale) {
        if (Status d = (this->*kind.drop)(id); !d) return d;
      }
      auto q = query(insert);
      if (!q) return q.error();
      q->bind(1, name).bind(2, static_cast<std::int64_t>(pid)).bind(3, host_name());
      if (const std::int64_t start = process_start(pid); start >= 0) {
        q->bind(4, start);
      } else {
        q->bind_null(4);
      }
      bind(*q);
      if (!done(*q)) {
        return sql_error("creating a version of " + std::string(kind.noun) + " '" + name + "'");
      }
      version = sqlite3_last_insert_rowid(db.get());
      return {};
    });
    if (!s) return s.error();
    return version;
  }

  // The imagery tables (imagery_store.cpp). A file written before they existed has none until a
  // read-write open adds them; a read-only connection looks again on each use until it sees them
  // (another process may add them while this one serves).
  bool imagery_tables = false;
  Result<bool> has_imagery_tables();
  Status create_imagery_tables();  // read-write opens; idempotent
  // Deletes an imagery version's tiles and its row. Inside a transaction.
  Status drop_imagery_version(std::int64_t version);
};

// What LayerWriter::Impl and ImageryWriter::Impl share: one 'building' version of a named layer,
// its state, and the rows batched in memory that write_pending() writes in one short transaction
// (so the file's write lock is held only while rows are inserted, never across the caller's
// computation between puts: other writers and publishes on the same file wait at most one flush).
template <typename Row>
struct VersionBatch {
  const VersionKind* kind = nullptr;
  TileStore::Impl* store = nullptr;
  std::string name;
  std::int64_t version = 0;
  enum class State { building, published, abandoned } state = State::building;
  std::vector<Row> pending;  // put, waiting for the next flush
  std::size_t pending_bytes = 0;

  std::string what() const {
    return std::string(kind->noun) + " '" + name + "' version " + std::to_string(version);
  }
  Status usable() const {
    if (state == State::published) return invalid_argument(what() + " is already published");
    if (state == State::abandoned) return invalid_argument(what() + " was abandoned");
    return {};
  }

  // Queues a row of `bytes`; calls `flush` when the batch holds kBatchTiles rows or kBatchBytes.
  template <typename Flush>
  Status add(Row&& row, std::size_t bytes, Flush&& flush) {
    pending_bytes += bytes;
    pending.push_back(std::move(row));
    if (pending.size() >= kBatchTiles || pending_bytes >= kBatchBytes) {
      return flush();  // on failure the rows stay pending: a later put/flush retries
    }
    return {};
  }

  // The latest pending row of the id (the latest put wins), or null.
  const Row* find_pending(const geo::TileId& id) const {
    // Not std::views::reverse: clang-tidy 14 (clang 14) cannot parse libstdc++ 12's ranges.
    // NOLINTNEXTLINE(modernize-loop-convert)
    for (auto it = pending.rbegin(); it != pending.rend(); ++it) {
      if (it->id == id) return &*it;
    }
    return nullptr;
  }

  // Writes the pending rows in one transaction with `insert` (?1 = version, ?2..?4 = z, x, y;
  // `bind(query, row)` binds the rest). On failure they stay pending (a flush may be retried,
  // e.g. after SQLITE_BUSY); on success the batch is durable.
  template <typename Bind>
  Status write_pending(const char* insert, Bind&& bind) {
    if (pending.empty()) return {};
    TileStore::Impl& db = *store;
    const std::string doing = std::string("writing a batch of tiles of ") + kind->noun;
    Status s = db.transaction(doing.c_str(), [&]() -> Status {
      auto q = db.query(insert);
      if (!q) return q.error();
      for (const Row& r : pending) {
        q->bind(1, version).bind(2, r.id.z).bind(3, r.id.x).bind(4, r.id.y);
        bind(*q, r);
        if (!TileStore::Impl::done(*q)) {
          return db.sql_error("writing " + what() + " tile " + r.id.to_string());
        }
        q->reset();
      }
      return {};
    });
    if (s) {
      pending.clear();
      pending_bytes = 0;
    }
    return s;
  }

  // After the caller's flush: counts the version's tiles, sets its row 'ready' with `update`
  // (?1 = version; `bind(query, tile_count)` binds the rest; the statement must match only a
  // 'building' row), points the name at it and deletes the version it replaces, all in one
  // transaction.
  template <typename Bind>
  Status publish(const char* update, Bind&& bind) {
    TileStore::Impl& db = *store;
    const std::string doing = std::string("publishing ") + kind->noun + " '" + name + "'";
    Status s = db.transaction(doing.c_str(), [&]() -> Status {
      auto count = db.query(kind->count_tiles);
      if (!count) return count.error();
      count->bind(1, version);
      if (count->step() != SQLITE_ROW) return db.sql_error("counting the tiles of " + what());
      const std::int64_t tiles = count->i64(0);
      auto q = db.query(update);
      if (!q) return q.error();
      q->bind(1, version);
      bind(*q, tiles);
      if (!TileStore::Impl::done(*q)) return db.sql_error("publishing " + what());
      if (sqlite3_changes(db.db.get()) != 1) {
        return Error(ErrorCode::internal,
                     db.path.string() + ": " + what() + " disappeared before it was published");
      }
      auto previous = db.switch_published(kind->select_published, kind->upsert_published, name,
                                          version, what());
      if (!previous) return previous.error();
      if (*previous) return (db.*(kind->drop))(**previous);
      return {};
    });
    if (s) state = State::published;
    return s;
  }

  // Marks the version abandoned and deletes it. Best effort: if that fails (disk full, say),
  // the next begin of the name collects it.
  void abandon() {
    if (state != State::building) return;
    state = State::abandoned;
    pending.clear();
    pending_bytes = 0;
    const std::string doing = std::string("abandoning a version of ") + kind->noun;
    (void)store->transaction(doing.c_str(),
                             [&]() -> Status { return (store->*(kind->drop))(version); });
  }
};

}  // namespace tinstream::store
