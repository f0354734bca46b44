#include "tinstream/subdivide/sorted_run.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>
#include <thread>

#include "tinstream/base/worker_threads.hpp"

namespace tinstream::subdivide {
namespace {

constexpr std::uint32_t kKeyLevel = 30;

std::uint64_t spread_bits(std::uint32_t v) {
  std::uint64_t x = v;
  x = (x | (x << 16)) & 0x0000FFFF0000FFFFull;
  x = (x | (x << 8)) & 0x00FF00FF00FF00FFull;
  x = (x | (x << 4)) & 0x0F0F0F0F0F0F0F0Full;
  x = (x | (x << 2)) & 0x3333333333333333ull;
  x = (x | (x << 1)) & 0x5555555555555555ull;
  return x;
}

std::uint32_t compact_bits(std::uint64_t x) {
  x &= 0x5555555555555555ull;
  x = (x | (x >> 1)) & 0x3333333333333333ull;
  x = (x | (x >> 2)) & 0x0F0F0F0F0F0F0F0Full;
  x = (x | (x >> 4)) & 0x00FF00FF00FF00FFull;
  x = (x | (x >> 8)) & 0x0000FFFF0000FFFFull;
  x = (x | (x >> 16)) & 0x00000000FFFFFFFFull;
  return static_cast<std::uint32_t>(x);
}

// The run order: (key, x, y), then the lowest z (and on equal z the highest weight) first, so
// that the first of a run of duplicates is the one kept. A function object, so that std::sort
// inlines it (through a function pointer it was a call per comparison).
struct RecordLess {
  bool operator()(const SortedPoint& a, const SortedPoint& b) const {
    if (a.key != b.key) return a.key < b.key;
    if (a.x != b.x) return a.x < b.x;
    if (a.y != b.y) return a.y < b.y;
    if (a.z != b.z) return a.z < b.z;
    return a.weight > b.weight;
  }
};
constexpr RecordLess record_less{};

bool same_xy(const SortedPoint& a, const SortedPoint& b) {
  return a.key == b.key && a.x == b.x && a.y == b.y;
}

// A record of the temporary runs (sorted_run.hpp): the SortedPoint without its key, which is a
// function of (x, y) — 32 bytes instead of 40 written and read per record.
struct StoredRecord {
  double x, y, z;
  float weight;
  std::uint32_t reserved;
};
static_assert(sizeof(StoredRecord) == kSpillRecordBytes);

StoredRecord to_stored(const SortedPoint& p) { return {p.x, p.y, p.z, p.weight, p.reserved}; }

// Turns the first n records of `records`, which hold n StoredRecords as read (packed at the
// front), into SortedPoints in place, computing their keys. Back to front: record i's stored
// bytes [32i, 32i + 32) are read before its 40 bytes [40i, 40i + 40) are written, and those
// cover no stored record j < i (32j + 32 ≤ 40i).
void decode_stored(SortedPoint* records, std::size_t n) {
  const auto* bytes = reinterpret_cast<const unsigned char*>(records);
  for (std::size_t i = n; i-- > 0;) {
    StoredRecord r;
    std::memcpy(&r, bytes + i * sizeof(StoredRecord), sizeof r);
    records[i] = {cell_key(r.x, r.y), r.x, r.y, r.z, r.weight, r.reserved};
  }
}

struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f) std::fclose(f);
  }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

Error io_failure(const std::string& what, const std::filesystem::path& path) {
  return io_error(what + " " + path.string() + ": " + std::strerror(errno));
}

// Removes the files it holds when destroyed (temporary runs; the output on failure).
class FileSet {
 public:
  FileSet() = default;
  FileSet(const FileSet&) = delete;
  FileSet& operator=(const FileSet&) = delete;
  ~FileSet() {
    std::error_code ec;
    for (const auto& p : paths_) std::filesystem::remove(p, ec);
  }
  void add(const std::filesystem::path& p) { paths_.push_back(p); }
  void release(const std::filesystem::path& p) { std::erase(paths_, p); }

 private:
  std::vector<std::filesystem::path> paths_;
};

// Writes records to a run file through a buffer. With `background`, a writer thread writes the
// full buffer while the caller fills a second one (the merge's output: the copy into the page
// cache then runs beside the merge instead of after it).
class RunWriter {
 public:
  // Creates the file (an existing one is cut to empty). `keyed`: SortedPoints as they are, key
  // included (the sorted run, which pass 3 reads many times over); else StoredRecords (the
  // temporary runs, read once).
  static Result<RunWriter> create(const std::filesystem::path& path, std::size_t buffer_records,
                                  bool background = false, bool keyed = false) {
    FilePtr f(std::fopen(path.c_str(), "wb"));
    if (!f) return io_failure("cannot create", path);
    RunWriter w(std::move(f), path, buffer_records, keyed);
    if (background) {
      if (Status s = w.start_background(); !s) return s.error();
    }
    return w;
  }
  // Writes keyed records into the region of an existing file that starts at record `first` (one
  // of the parallel merge's halves of the sorted run).
  static Result<RunWriter> create_region(const std::filesystem::path& path, std::uint64_t first,
                                         std::size_t buffer_records) {
    FilePtr f(std::fopen(path.c_str(), "r+b"));
    if (!f || fseeko(f.get(), static_cast<off_t>(first * sizeof(SortedPoint)), SEEK_SET) != 0) {
      return io_failure("cannot open", path);
    }
    RunWriter w(std::move(f), path, buffer_records, /*keyed=*/true);
    if (Status s = w.start_background(); !s) return s.error();
    return w;
  }
  RunWriter(FilePtr f, const std::filesystem::path& path, std::size_t buffer_records, bool keyed)
      : file_(std::move(f)),
        path_(path),
        record_bytes_(keyed ? sizeof(SortedPoint) : sizeof(StoredRecord)),
        capacity_(std::max<std::size_t>(buffer_records, 256) * record_bytes_) {
    buffer_.reserve(capacity_);
  }
  // Starts the writer thread; an Error (nothing started) when it cannot be created.
  Status start_background() {
    auto background = std::make_unique<Background>(file_.get(), capacity_);
    if (Status s = background->thread.start([b = background.get()] { b->run(); }); !s) return s;
    background_ = std::move(background);
    return {};
  }
  Status push(const SortedPoint& p) {
    const std::size_t at = buffer_.size();
    buffer_.resize(at + record_bytes_);
    if (record_bytes_ == sizeof(SortedPoint)) {
      std::memcpy(buffer_.data() + at, &p, sizeof p);
    } else {
      const StoredRecord r = to_stored(p);
      std::memcpy(buffer_.data() + at, &r, sizeof r);
    }
    ++written_;
    if (buffer_.size() == capacity_) return flush();
    return {};
  }
  Status flush() {
    if (background_) {
      if (Status s = wait_background(); !s) return s;
      background_->hand_over(buffer_);
      return {};
    }
    if (!buffer_.empty() &&
        std::fwrite(buffer_.data(), 1, buffer_.size(), file_.get()) != buffer_.size()) {
      return io_failure("cannot write", path_);
    }
    buffer_.clear();
    return {};
  }
  Status close() {
    if (Status s = flush(); !s) return s;
    if (Status s = wait_background(); !s) return s;
    background_.reset();  // joins the writer thread before the file goes
    if (std::fflush(file_.get()) != 0) return io_failure("cannot write", path_);
    if (std::fclose(file_.release()) != 0) return io_failure("cannot close", path_);
    return {};
  }
  std::uint64_t written() const { return written_; }

 private:
  // The writer thread and the buffer it writes. `writing`, `pending`, `stop` and `error` are
  // guarded by `mutex`; the thread touches the FILE only while `pending`.
  struct Background {
    Background(std::FILE* f, std::size_t capacity) : file(f) { writing.reserve(capacity); }
    Background(const Background&) = delete;
    Background& operator=(const Background&) = delete;
    ~Background() {
      {
        std::lock_guard lock(mutex);
        stop = true;
      }
      wake.notify_all();
      (void)thread.join();
    }
    // Swaps `buffer` (full) with the written one (emptied). Requires: !pending.
    void hand_over(std::vector<unsigned char>& buffer) {
      {
        std::lock_guard lock(mutex);
        writing.swap(buffer);
        buffer.clear();
        pending = true;
      }
      wake.notify_all();
    }
    // Blocks until the buffer handed over is written; the errno of a failed write, else 0.
    int wait_idle() {
      std::unique_lock lock(mutex);
      wake.wait(lock, [&] { return !pending; });
      return error;
    }
    void run() {
      std::unique_lock lock(mutex);
      for (;;) {
        wake.wait(lock, [&] { return pending || stop; });
        if (!pending) return;
        lock.unlock();
        bool ok = false;
        // The barrier keeps `pending` honest: an exception here is a failed write, not a thread
        // gone with the caller waiting on it. Fault point "pass2.writer".
        const bool ran = guarded("pass 2 run writer", [&] {
                           fault::point("pass2.writer");
                           ok = writing.empty() || std::fwrite(writing.data(), 1, writing.size(),
                                                               file) == writing.size();
                         }).ok();
        const int err = ok ? 0 : (!ran || errno == 0 ? EIO : errno);
        lock.lock();
        if (err != 0 && error == 0) error = err;
        pending = false;
        wake.notify_all();
      }
    }
    std::FILE* file;
    std::mutex mutex;
    std::condition_variable wake;
    std::vector<unsigned char> writing;
    bool pending = false, stop = false;
    int error = 0;
    WorkerThreads thread{"pass 2 run writer",
                         "pass2.writer"};  // last: started when the rest exists
  };

  Status wait_background() {
    if (!background_) return {};
    if (const int err = background_->wait_idle(); err != 0) {
      errno = err;
      return io_failure("cannot write", path_);
    }
    return {};
  }

  FilePtr file_;
  std::filesystem::path path_;
  std::size_t record_bytes_ = 0;
  std::size_t capacity_ = 0;  // bytes
  std::vector<unsigned char> buffer_;
  std::uint64_t written_ = 0;
  std::unique_ptr<Background> background_;  // after file_: destroyed (joined) before it
};

// Reads a run sequentially through a buffer. With `release_read` (temporary runs, removed after
// the merge that reads them) the part already read is punched out of the file as it goes: its
// page-cache pages are freed while the merge runs and new writes reuse them, instead of the
// cache growing by the size of everything the ingest wrote (fresh pages cost far more than
// recycled ones on the benchmark machine). Where punching is unsupported it is skipped.
class RunCursor {
 public:
  // Reads records [first, end) of the run (end: ~0 for all); punching stays inside that range
  // (whole 64 KiB blocks), so two cursors may read the two halves of one run.
  // `keyed`: the file holds SortedPoints (the sorted run), else StoredRecords (keys computed).
  static Result<RunCursor> open(const std::filesystem::path& path, std::size_t buffer_records,
                                bool release_read = false, std::uint64_t first = 0,
                                std::uint64_t end = ~std::uint64_t{0}, bool keyed = false) {
    FilePtr f(std::fopen(path.c_str(), release_read ? "r+b" : "rb"));  // punching needs write
    if (!f) return io_failure("cannot open", path);
    const std::uint64_t kRecord = keyed ? sizeof(SortedPoint) : sizeof(StoredRecord);
    if (first > 0 && fseeko(f.get(), static_cast<off_t>(first * kRecord), SEEK_SET) != 0) {
      return io_failure("cannot seek in", path);
    }
    RunCursor c;
    c.file_ = std::move(f);
    c.path_ = path;
    c.release_read_ = release_read;
    c.keyed_ = keyed;
    c.left_ = end - first;
    c.read_bytes_ = first * kRecord;
    c.released_ = (c.read_bytes_ + kReleaseBlock - 1) / kReleaseBlock * kReleaseBlock;
    c.buffer_.resize(std::max<std::size_t>(buffer_records, 64));
    if (Status s = c.refill(); !s) return s.error();
    return c;
  }
  bool done() const { return pos_ == size_; }
  const SortedPoint& current() const { return buffer_[pos_]; }
  Status advance() {
    if (++pos_ == size_) return refill();
    return {};
  }

 private:
  Status refill() {
    if (release_read_) release(read_bytes_);
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(buffer_.size(), left_));
    if (keyed_) {
      size_ = std::fread(buffer_.data(), sizeof(SortedPoint), want, file_.get());
      read_bytes_ += size_ * sizeof(SortedPoint);
    } else {
      size_ = std::fread(buffer_.data(), sizeof(StoredRecord), want, file_.get());
      decode_stored(buffer_.data(), size_);
      read_bytes_ += size_ * sizeof(StoredRecord);
    }
    left_ -= size_;
    pos_ = 0;
    if (size_ == 0 && std::ferror(file_.get())) return io_failure("cannot read", path_);
    return {};
  }
  // Punches [released_, end) out of the file, in whole 64 KiB blocks (a partial block would be
  // zeroed, not freed).
  void release(std::uint64_t end) {
#ifdef FALLOC_FL_PUNCH_HOLE
    end -= end % kReleaseBlock;
    if (end <= released_) return;
    (void)::fallocate(fileno(file_.get()), FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE,
                      static_cast<off_t>(released_), static_cast<off_t>(end - released_));
    released_ = end;
#else
    (void)end;
#endif
  }
  FilePtr file_;
  std::filesystem::path path_;
  std::vector<SortedPoint> buffer_;
  std::size_t pos_ = 0, size_ = 0;
  bool release_read_ = false, keyed_ = false;
  std::uint64_t left_ = 0;  // records of the range not read yet
  std::uint64_t read_bytes_ = 0, released_ = 0;
  static constexpr std::uint64_t kReleaseBlock = 1 << 16;
};

// Tracks, for every level, the largest number of records in one tile of a key-ordered stream.
// Each level remembers where its current tile began; a key closes exactly the levels whose tile
// it leaves (those whose prefix holds the highest bit in which it differs from the last key), so
// a key in the same level-30 cell as the last costs one comparison instead of a pass over all
// 31 levels.
class LevelCounter {
 public:
  LevelCounter() {
    start_.fill(0);
    first_end_.fill(0);
    max_.fill(0);
  }
  void add(std::uint64_t key) {
    if (const std::uint64_t diff = key ^ last_; diff != 0 && added_ > 0) {
      // Level l's prefix is key >> 2(30 - l): it changed iff the highest differing bit h has
      // h >= 2(30 - l), i.e. l >= 30 - h/2.
      const auto high = static_cast<std::uint32_t>(63 - std::countl_zero(diff));
      for (std::uint32_t level = kKeyLevel - high / 2; level <= kKeyLevel; ++level) {
        close(level);
        if (start_[level] == 0) first_end_[level] = added_;  // the level's first tile ends
        start_[level] = added_;
      }
    } else if (added_ == 0) {
      first_key_ = key;
    }
    last_ = key;
    ++added_;
  }
  std::vector<std::uint64_t> finish() {
    for (std::uint32_t l = 0; l <= kKeyLevel; ++l) close(l);
    return {max_.begin(), max_.end()};
  }
  // finish() of this stream followed by `next`'s (every key of `next` at or after this one's
  // last): a tile split between the two counts as one.
  std::vector<std::uint64_t> finish_followed_by(LevelCounter& next) {
    std::array<std::uint64_t, kKeyLevel + 1> joined{};
    for (std::uint32_t l = 0; l <= kKeyLevel; ++l) {
      const std::uint32_t shift = 2 * (kKeyLevel - l);
      if (added_ > 0 && next.added_ > 0 && (last_ >> shift) == (next.first_key_ >> shift)) {
        const std::uint64_t next_first = next.first_end_[l] != 0 ? next.first_end_[l] : next.added_;
        joined[l] = added_ - start_[l] + next_first;
      }
    }
    std::vector<std::uint64_t> out = finish();
    const std::vector<std::uint64_t> after = next.finish();
    for (std::uint32_t l = 0; l <= kKeyLevel; ++l) out[l] = std::max({out[l], after[l], joined[l]});
    return out;
  }

 private:
  void close(std::uint32_t level) { max_[level] = std::max(max_[level], added_ - start_[level]); }
  std::uint64_t first_key_ = 0, last_ = 0, added_ = 0;
  // Per level: index of the current tile's first key; where the first tile ended (0: not yet);
  // the most keys in one closed tile.
  std::array<std::uint64_t, kKeyLevel + 1> start_{}, first_end_{}, max_{};
};

// Keeps, while the final merge streams keys in order, the tile index (first record and count of
// every non-empty tile) at the finest level it can afford: it starts at max_level and, whenever
// `capacity` entries are full, coarsens one level (tiles nest, so neighbours with the same parent
// add up exactly). At the end it answers the index of any level L at or above the one it kept.
class TileTally {
 public:
  TileTally(std::uint32_t max_level, std::uint32_t min_level, std::size_t capacity)
      : level_(max_level), min_level_(min_level), capacity_(std::max<std::size_t>(capacity, 2)) {
    entries_.reserve(std::min<std::size_t>(capacity_, 1 << 12));
  }
  void add(std::uint64_t key) {
    if (given_up_) return;
    const std::uint64_t prefix = key >> shift();
    if (!entries_.empty() && entries_.back().prefix == prefix) {
      ++entries_.back().count;
      return;
    }
    while (entries_.size() == capacity_) {
      if (level_ == min_level_) {  // L is never below min_level: nothing coarser can help
        given_up_ = true;
        std::vector<Entry>().swap(entries_);
        return;
      }
      coarsen_to(level_ - 1);
      if (entries_.back().prefix == (key >> shift())) {
        ++entries_.back().count;
        return;
      }
    }
    entries_.push_back({key >> shift(), 1});
  }
  // Appends the tally of the records that follow this one's (a parallel merge's upper half), so
  // that this one is the tally of both: the tile split between the two adds up.
  void append(TileTally& next) {
    if (given_up_ || next.given_up_) {
      given_up_ = true;
      std::vector<Entry>().swap(entries_);
      return;
    }
    const std::uint32_t level = std::min(level_, next.level_);
    coarsen_to(level);
    next.coarsen_to(level);
    for (const Entry& e : next.entries_) {
      if (!entries_.empty() && entries_.back().prefix == e.prefix) {
        entries_.back().count += e.count;
      } else {
        entries_.push_back(e);
      }
    }
  }
  // The index at `level`; false when the tally kept only coarser tiles (or gave up).
  bool index(std::uint32_t level, std::vector<TileRange>& out) {
    if (given_up_ || level > level_) return false;
    coarsen_to(level);
    out.clear();
    out.reserve(entries_.size());
    std::uint64_t first = 0;
    for (const Entry& e : entries_) {
      out.push_back({tile_of_key(e.prefix << shift(), level), first, e.count});
      first += e.count;
    }
    return true;
  }

 private:
  struct Entry {
    std::uint64_t prefix;  // key >> shift()
    std::uint64_t count;
  };
  std::uint32_t shift() const { return 2 * (kKeyLevel - level_); }
  // Merges the entries (tiles of level_) into tiles of the coarser `level`, in place, in order.
  void coarsen_to(std::uint32_t level) {
    const std::uint32_t by = 2 * (level_ - level);
    std::size_t out = 0;
    // out <= the index of `e`: each write lands on an entry already read (or on `e` itself,
    // after its count was read into the new value).
    for (const Entry& e : entries_) {
      const std::uint64_t parent = e.prefix >> by;
      if (out > 0 && entries_[out - 1].prefix == parent) {
        entries_[out - 1].count += e.count;
      } else {
        entries_[out++] = Entry{parent, e.count};
      }
    }
    entries_.resize(out);
    level_ = level;
  }

  std::uint32_t level_;  // the level of the entries' prefixes
  std::uint32_t min_level_;
  std::size_t capacity_;
  bool given_up_ = false;
  std::vector<Entry> entries_;
};

// A record's place in a chunk being sorted: its key and its index in the chunk.
struct KeyIndex {
  std::uint64_t key;
  std::uint64_t index;
};
static_assert(sizeof(KeyIndex) == 16);

// Fills every record's key and sorts `order` (indexes into `chunk`) into record_less order:
// a stable LSD radix sort on the key (11-bit digits; digits where no two keys differ are
// skipped, so a chunk from a small area costs few passes), then the rare runs of equal keys by
// the rest of record_less. `scratch` is the radix sort's second array.
void sort_chunk(std::vector<SortedPoint>& chunk, std::vector<KeyIndex>& order,
                std::vector<KeyIndex>& scratch) {
  const std::size_t n = chunk.size();
  order.resize(n);
  scratch.resize(n);
  std::uint64_t any = 0, all = ~std::uint64_t{0};
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t key = cell_key(chunk[i].x, chunk[i].y);
    chunk[i].key = key;
    order[i] = {key, i};
    any |= key;
    all &= key;
  }
  const std::uint64_t varying = any ^ all;
  constexpr std::uint32_t kDigitBits = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigitBits;
  std::vector<std::size_t> count(kBuckets);
  for (std::uint32_t shift = 0; shift < 64 && (varying >> shift) != 0; shift += kDigitBits) {
    if (((varying >> shift) & (kBuckets - 1)) == 0) continue;
    std::fill(count.begin(), count.end(), 0);
    for (const KeyIndex& e : order) ++count[(e.key >> shift) & (kBuckets - 1)];
    std::size_t sum = 0;
    for (std::size_t& c : count) sum += std::exchange(c, sum);
    for (const KeyIndex& e : order) scratch[count[(e.key >> shift) & (kBuckets - 1)]++] = e;
    order.swap(scratch);
  }
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i + 1;
    while (j < n && order[j].key == order[i].key) ++j;
    if (j - i > 1) {
      std::sort(order.begin() + static_cast<std::ptrdiff_t>(i),
                order.begin() + static_cast<std::ptrdiff_t>(j),
                [&](const KeyIndex& a, const KeyIndex& b) {
                  return record_less(chunk[a.index], chunk[b.index]);
                });
    }
    i = j;
  }
}

// Sorts `chunk` and writes it as a run at `path`, dropping exact duplicates; runs on the spill
// thread (touches only its arguments).
Status write_run(std::vector<SortedPoint>& chunk, std::vector<KeyIndex>& order,
                 std::vector<KeyIndex>& scratch, const std::filesystem::path& path,
                 std::uint64_t& duplicates) {
  sort_chunk(chunk, order, scratch);
  auto w = RunWriter::create(path, 1 << 15);
  if (!w) return w.error();
  const SortedPoint* last = nullptr;
  // The gather jumps around a chunk far larger than the caches: ask for the record a few steps
  // ahead (both lines: a 40-byte record may straddle two) so the misses overlap.
  constexpr std::size_t kAhead = 16;
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (k + kAhead < order.size()) {
      const char* ahead = reinterpret_cast<const char*>(&chunk[order[k + kAhead].index]);
      __builtin_prefetch(ahead);
      __builtin_prefetch(ahead + sizeof(SortedPoint) - 1);
    }
    const SortedPoint& p = chunk[order[k].index];
    if (last && same_xy(*last, p)) {
      ++duplicates;
      continue;
    }
    if (Status s = w->push(p); !s) return s;
    last = &p;
  }
  return w->close();
}

// Records [first, end) of a run.
struct RunSlice {
  std::filesystem::path path;
  std::uint64_t first = 0, end = ~std::uint64_t{0};
};

std::vector<RunSlice> whole_runs(const std::vector<std::filesystem::path>& runs) {
  std::vector<RunSlice> out;
  out.reserve(runs.size());
  for (const auto& p : runs) out.push_back({p});
  return out;
}

// Merges sorted runs into `writer`, dropping duplicate (x, y) (the first, lowest z, survives).
Status merge_runs(const std::vector<RunSlice>& inputs, std::size_t buffer_records,
                  RunWriter& writer, LevelCounter* levels, TileTally* tally,
                  std::uint64_t& duplicates, const std::function<bool(std::uint64_t)>& tick) {
  std::vector<RunCursor> cursors;
  cursors.reserve(inputs.size());
  for (const auto& in : inputs) {
    // Inputs are temporary: punched as they are read.
    auto c = RunCursor::open(in.path, buffer_records, /*release_read=*/true, in.first, in.end);
    if (!c) return c.error();
    if (!c->done()) cursors.push_back(std::move(*c));
  }
  // A binary min-heap of the cursors, each entry with a copy of its current key so that most
  // comparisons need no trip to the cursor's buffer. The smallest record's cursor is at the top;
  // after it advances, one sift-down restores the heap (a pop and a push cost two).
  struct HeapEntry {
    std::uint64_t key;
    std::size_t cursor;
  };
  auto less = [&](const HeapEntry& a, const HeapEntry& b) {
    if (a.key != b.key) return a.key < b.key;
    return record_less(cursors[a.cursor].current(), cursors[b.cursor].current());
  };
  std::vector<HeapEntry> heap(cursors.size());
  for (std::size_t i = 0; i < heap.size(); ++i) heap[i] = {cursors[i].current().key, i};
  std::make_heap(heap.begin(), heap.end(),
                 [&](const HeapEntry& a, const HeapEntry& b) { return less(b, a); });
  auto sift_down = [&] {
    const std::size_t n = heap.size();
    std::size_t pos = 0;
    for (;;) {
      std::size_t child = 2 * pos + 1;
      if (child >= n) return;
      if (child + 1 < n && less(heap[child + 1], heap[child])) ++child;
      if (!less(heap[child], heap[pos])) return;
      std::swap(heap[child], heap[pos]);
      pos = child;
    }
  };
  SortedPoint last{};
  bool have_last = false;
  std::uint64_t merged = 0;
  while (!heap.empty()) {
    const std::size_t i = heap.front().cursor;
    const SortedPoint& p = cursors[i].current();
    if (have_last && same_xy(last, p)) {
      ++duplicates;
    } else {
      if (Status s = writer.push(p); !s) return s;
      if (levels) levels->add(p.key);
      if (tally) tally->add(p.key);
      last = p;
      have_last = true;
    }
    if (Status s = cursors[i].advance(); !s) return s;
    if (cursors[i].done()) {
      heap.front() = heap.back();
      heap.pop_back();
    } else {
      heap.front().key = cursors[i].current().key;
    }
    sift_down();
    if ((++merged & 0xFFFF) == 0 && tick && !tick(merged)) {
      return Error(ErrorCode::cancelled, "ingest cancelled while merging sorted runs");
    }
  }
  return {};
}

// The final merge on two threads: the runs are cut at one key K (every record with key < K in
// the lower half, the rest in the upper), each half merged on its own thread into its own
// region of the output — the lower from record 0, the upper from the lower half's input count.
// Duplicates share their key, so both halves drop exactly what one merge drops, and the lower
// half's drops leave a gap that is closed afterwards.
struct MergeSplit {
  std::vector<RunSlice> low, high;
  std::uint64_t low_records = 0, high_records = 0;
};

// Keys of a run's records by index, for the split search (a pread per probe).
class RunProbe {
 public:
  static Result<RunProbe> open(const std::filesystem::path& path) {
    RunProbe p;
    p.path_ = path;
    p.fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(path, ec);
    if (p.fd_ < 0 || ec) return io_failure("cannot open", path);
    p.records_ = bytes / sizeof(StoredRecord);
    return p;
  }
  RunProbe(RunProbe&& o) noexcept
      : path_(std::move(o.path_)), fd_(std::exchange(o.fd_, -1)), records_(o.records_) {}
  RunProbe& operator=(RunProbe&&) = delete;
  ~RunProbe() {
    if (fd_ >= 0) ::close(fd_);
  }
  std::uint64_t records() const { return records_; }
  Result<std::uint64_t> key(std::uint64_t index) const {
    StoredRecord r;
    if (::pread(fd_, &r, sizeof r, static_cast<off_t>(index * sizeof r)) !=
        static_cast<ssize_t>(sizeof r)) {
      return io_failure("cannot read", path_);
    }
    return cell_key(r.x, r.y);
  }
  // The first index whose key is at least k (records() when none).
  Result<std::uint64_t> lower_bound(std::uint64_t k) const {
    std::uint64_t lo = 0, hi = records_;
    while (lo < hi) {
      const std::uint64_t mid = lo + (hi - lo) / 2;
      auto m = key(mid);
      if (!m) return m.error();
      if (*m < k) {
        lo = mid + 1;
      } else {
        hi = mid;
      }
    }
    return lo;
  }

 private:
  RunProbe() = default;
  std::filesystem::path path_;
  int fd_ = -1;
  std::uint64_t records_ = 0;
};

// Chooses K among the runs' middle keys so that the lower half holds as close to half of the
// records as those candidates allow. Empty `low` or `high`: no useful split.
Result<MergeSplit> split_runs(const std::vector<std::filesystem::path>& runs) {
  std::vector<RunProbe> probes;
  std::vector<std::uint64_t> candidates;
  std::uint64_t total = 0;
  for (const auto& r : runs) {
    auto p = RunProbe::open(r);
    if (!p) return p.error();
    if (p->records() > 0) {
      auto k = p->key(p->records() / 2);
      if (!k) return k.error();
      candidates.push_back(*k);
    }
    total += p->records();
    probes.push_back(std::move(*p));
  }
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  auto below = [&](std::uint64_t k, std::vector<std::uint64_t>* cuts) -> Result<std::uint64_t> {
    std::uint64_t n = 0;
    for (const RunProbe& p : probes) {
      auto cut = p.lower_bound(k);
      if (!cut) return cut.error();
      n += *cut;
      if (cuts) cuts->push_back(*cut);
    }
    return n;
  };
  // Binary search for the first candidate with at least half the records below it; its
  // predecessor may be closer.
  std::size_t lo = 0, hi = candidates.size();
  while (lo < hi) {
    const std::size_t mid = lo + (hi - lo) / 2;
    auto n = below(candidates[mid], nullptr);
    if (!n) return n.error();
    if (*n < total / 2) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  MergeSplit split;
  if (candidates.empty()) return split;
  std::uint64_t best = candidates[std::min(lo, candidates.size() - 1)];
  if (lo > 0) {
    auto at = below(best, nullptr), before = below(candidates[lo - 1], nullptr);
    if (!at) return at.error();
    if (!before) return before.error();
    const auto distance = [&](std::uint64_t n) {
      return n > total / 2 ? n - total / 2 : total / 2 - n;
    };
    if (lo == candidates.size() || distance(*before) < distance(*at)) best = candidates[lo - 1];
  }
  std::vector<std::uint64_t> cuts;
  auto low = below(best, &cuts);
  if (!low) return low.error();
  if (*low == 0 || *low == total) return split;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    split.low.push_back({runs[i], 0, cuts[i]});
    split.high.push_back({runs[i], cuts[i], probes[i].records()});
  }
  split.low_records = *low;
  split.high_records = total - *low;
  return split;
}

// Moves `count` records from record `from` down to record `to` (to < from) and cuts the file
// after them: the gap the lower half's dropped duplicates left. Front to back in 1 MiB steps
// (the ranges may overlap), rewriting the file's own cached pages.
Status close_gap(const std::filesystem::path& path, std::uint64_t from, std::uint64_t to,
                 std::uint64_t count) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) return io_failure("cannot open", path);
  constexpr std::uint64_t kStep = (1 << 20) / sizeof(SortedPoint);
  std::vector<SortedPoint> buffer(static_cast<std::size_t>(std::min(kStep, count)));
  bool ok = true;
  for (std::uint64_t done = 0; ok && done < count && from != to;) {
    const std::uint64_t n = std::min(kStep, count - done);
    const auto bytes = static_cast<ssize_t>(n * sizeof(SortedPoint));
    ok = ::pread(fd, buffer.data(), static_cast<std::size_t>(bytes),
                 static_cast<off_t>((from + done) * sizeof(SortedPoint))) == bytes &&
         ::pwrite(fd, buffer.data(), static_cast<std::size_t>(bytes),
                  static_cast<off_t>((to + done) * sizeof(SortedPoint))) == bytes;
    done += n;
  }
  ok = ok && ::ftruncate(fd, static_cast<off_t>((to + count) * sizeof(SortedPoint))) == 0;
  const int err = errno;
  ::close(fd);
  if (!ok) {
    errno = err;
    return io_failure("cannot write", path);
  }
  return {};
}

}  // namespace

std::uint64_t morton_interleave(std::uint32_t x, std::uint32_t y) {
  return spread_bits(x) | (spread_bits(y) << 1);
}

namespace {

// The level-30 column of normalised coordinate c ∈ [-1, 1] (the row of y is that of -y), as
// geo::TileId::containing finds it: the largest i < 2^30 whose edge -1 + i·2^-29 is ≤ c. The
// edges are exact doubles (i·2^-29 has ≤ 30 significant bits and the sum is exact), so the
// estimate from (c + 1)·2^29, which may be off by one where c + 1 rounds, is fixed up by exact
// comparisons; the same answer as containing's binary-free search, without its ldexp calls.
std::uint32_t key_column(double c) {
  constexpr std::int64_t n = std::int64_t{1} << kKeyLevel;
  constexpr double step = 0x1p-29;  // 2 / 2^30
  auto edge = [](std::int64_t i) { return -1.0 + static_cast<double>(i) * step; };
  // c + 1 ≥ 0 (c is clamped to the map), so truncation is the floor (std::floor is a libm call
  // on the baseline x86-64 target, and this runs once per record read).
  std::int64_t i =
      std::clamp<std::int64_t>(static_cast<std::int64_t>((c + 1.0) * 0x1p29), 0, n - 1);
  while (i > 0 && c < edge(i)) --i;
  while (i + 1 < n && c >= edge(i + 1)) ++i;
  return static_cast<std::uint32_t>(i);
}

}  // namespace

std::uint64_t cell_key(double x, double y) {
  // As geo::TileId::containing({x, y}, 30): NaN is 0, the rest clamped to the map.
  const double px = std::isnan(x) ? 0.0 : std::clamp(x, -1.0, 1.0);
  const double py = std::isnan(y) ? 0.0 : std::clamp(y, -1.0, 1.0);
  return morton_interleave(key_column(px), key_column(-py));
}

geo::TileId tile_of_key(std::uint64_t key, std::uint32_t level) {
  const std::uint64_t prefix = key >> (2 * (kKeyLevel - level));
  return {level, compact_bits(prefix), compact_bits(prefix >> 1)};
}

// ---- the builder ------------------------------------------------------------------------------
//
// Memory: half of the budget sorts. It holds two chunks of SortedPoints (one fills on the caller's
// thread while the spill thread sorts and writes the other) and the spill thread's two order
// arrays (key + index, 16 bytes each per record): 112 bytes per chunk record. The other half
// buffers the merge: up to kFanIn cursors and the output writer's two buffers.

namespace {

// The merge's progress: points merged so far; false cancels.
using MergeTick = std::function<bool(std::uint64_t)>;

// The finest level: the smallest level whose fullest tile fits the budget (max_level if none),
// but no coarser than the data's extent asks for (extent_level). Within [min_level, max_level].
std::uint32_t finest_level(const std::vector<std::uint64_t>& max_tile_points,
                           const SubdivideOptions& options, std::uint32_t extent_floor) {
  std::uint32_t l = options.min_level;
  while (l < options.max_level && max_tile_points[l] > options.max_points) ++l;
  return std::clamp(std::max(l, extent_floor), options.min_level, options.max_level);
}

}  // namespace

std::uint32_t extent_level(double width, double height) {
  const double extent = std::max(width, height);
  if (!(extent > 0)) return 0;  // one position (or none): the data gives no scale
  // Tiles of level l are 2 / 2^l wide; the deepest level whose tiles are at least `extent` wide.
  std::uint32_t l = 0;
  while (l < kKeyLevel && std::ldexp(2.0, -static_cast<int>(l + 1)) >= extent) ++l;
  return l;
}

namespace {

// The tile index of the finest level: from the merge's tally when it kept a level at least as
// fine (tiles nest, so it coarsens exactly), else one sequential pass over the sorted run's keys.
Status index_tiles(TileTally& tally, SortedRun& result) {
  if (tally.index(result.finest_level, result.tiles)) return {};
  result.tiles.clear();
  auto cursor = RunCursor::open(result.path, 1 << 15, false, 0, ~std::uint64_t{0}, /*keyed=*/true);
  if (!cursor) return cursor.error();
  const std::uint32_t shift = 2 * (kKeyLevel - result.finest_level);
  std::uint64_t index = 0;
  std::uint64_t current = ~std::uint64_t{0};
  while (!cursor->done()) {
    const std::uint64_t prefix = cursor->current().key >> shift;
    if (prefix != current) {
      result.tiles.push_back({tile_of_key(cursor->current().key, result.finest_level), index, 0});
      current = prefix;
    }
    ++result.tiles.back().count;
    ++index;
    if (Status s = cursor->advance(); !s) return s;
  }
  return {};
}

}  // namespace

struct SortedRunBuilder::State {
  explicit State(const SubdivideOptions& o) : options(o) {}
  State(const State&) = delete;
  State& operator=(const State&) = delete;
  ~State() { (void)spill_thread.join(); }

  SubdivideOptions options;
  std::size_t budget_records = 0, sort_capacity = 0, merge_buffer = 0;
  static constexpr std::size_t kFanIn = 128;
  FileSet temporaries;  // declared before the thread: removed after it is joined
  std::string stem;
  std::size_t next_id = 0;
  std::vector<std::filesystem::path> runs;
  std::vector<SortedPoint> buffer, spilling;
  std::uint64_t input_points = 0, duplicates = 0;
  // The points' bounding box (normalised Mercator): extent_level() of the finest level.
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x;
  double min_y = std::numeric_limits<double>::infinity(), max_y = -min_y;
  bool finished = false;

  // Owned by the spill thread while it runs (spilling, order, scratch, spill_*).
  std::vector<KeyIndex> order, scratch;
  WorkerThreads spill_thread{"pass 2 spill", "pass2.spill"};  // one spill at a time
  std::uint64_t spill_duplicates = 0;

  std::filesystem::path temp_path() {
    auto p = options.tmp_dir / (stem + std::to_string(next_id++) + ".run");
    temporaries.add(p);
    return p;
  }
  Status join_spill() {
    Status s = spill_thread.join();  // the spill's Status (or the exception it threw)
    duplicates += std::exchange(spill_duplicates, 0);
    return s;
  }
  // Hands the full buffer to the spill thread (after the previous spill finished) and continues
  // with the other buffer.
  Status spill() {
    if (Status s = join_spill(); !s) return s;
    std::swap(buffer, spilling);
    buffer.clear();
    buffer.reserve(sort_capacity);
    auto path = temp_path();
    runs.push_back(path);
    return spill_thread.start([this, path] {
      fault::point("pass2.spill");
      return write_run(spilling, order, scratch, path, spill_duplicates);
    });
  }

  // Spills what the buffer holds (an empty input still makes one empty run), waits for the spill
  // thread and gives the sort buffers back.
  Status flush() {
    if (!buffer.empty() || runs.empty()) {
      if (Status s = spill(); !s) return s;
    }
    if (Status s = join_spill(); !s) return s;
    std::vector<SortedPoint>().swap(buffer);
    std::vector<SortedPoint>().swap(spilling);
    std::vector<KeyIndex>().swap(order);
    std::vector<KeyIndex>().swap(scratch);
    return {};
  }

  // Merges groups of kFanIn runs into one until at most kFanIn are left (a multi-pass merge when
  // there are more runs than the fan-in).
  Status merge_to_fan_in(std::uint64_t& duplicates_merged, const MergeTick& tick) {
    std::error_code ec;
    while (runs.size() > kFanIn) {
      std::vector<std::filesystem::path> next;
      for (std::size_t i = 0; i < runs.size(); i += kFanIn) {
        const std::vector<std::filesystem::path> group(
            runs.begin() + static_cast<std::ptrdiff_t>(i),
            runs.begin() + static_cast<std::ptrdiff_t>(std::min(runs.size(), i + kFanIn)));
        auto path = temp_path();
        auto w = RunWriter::create(path, merge_buffer, /*background=*/true);
        if (!w) return w.error();
        if (Status s = merge_runs(whole_runs(group), merge_buffer, *w, nullptr, nullptr,
                                  duplicates_merged, tick);
            !s)
          return s;
        if (Status s = w->close(); !s) return s;
        for (const auto& g : group) std::filesystem::remove(g, ec);
        next.push_back(path);
      }
      runs = std::move(next);
    }
    return {};
  }

  // The last merge on this thread: all runs into result.path (keyed), counting the points per
  // tile of every level and tallying the tiles on the way.
  Status merge_whole(SortedRun& result, TileTally& tally, const MergeTick& tick) {
    LevelCounter levels;
    auto w = RunWriter::create(result.path, merge_buffer, /*background=*/true, /*keyed=*/true);
    if (!w) return w.error();
    if (Status s = merge_runs(whole_runs(runs), merge_buffer, *w, &levels, &tally,
                              result.duplicates_merged, tick);
        !s)
      return s;
    if (Status s = w->close(); !s) return s;
    result.points = w->written();
    result.max_tile_points = levels.finish();
    return {};
  }

  // The last merge split at a key (split_runs): the lower half on this thread, the upper on a
  // worker, each into its region of result.path (the cursors, buffers and writers of both halves
  // share the merge's budget: half the buffer each); then the lower half's duplicate gap is closed
  // and the halves' counts and tallies joined.
  Status merge_halves(const MergeSplit& split, std::size_t tally_entries, SortedRun& result,
                      TileTally& tally, const MergeTick& tick) {
    {
      FilePtr f(std::fopen(result.path.c_str(), "wb"));  // the halves write into it (regions)
      if (!f) return io_failure("cannot create", result.path);
    }
    const std::size_t half_buffer = std::max<std::size_t>(merge_buffer / 2, 256);
    auto low_writer = RunWriter::create_region(result.path, 0, half_buffer);
    if (!low_writer) return low_writer.error();
    auto high_writer = RunWriter::create_region(result.path, split.low_records, half_buffer);
    if (!high_writer) return high_writer.error();
    LevelCounter levels, high_levels;
    TileTally high_tally(options.max_level, options.min_level, tally_entries / 2);
    std::uint64_t high_duplicates = 0;
    std::atomic<std::uint64_t> high_done{0};
    std::atomic<bool> stop{false};
    WorkerThreads high("pass 2 merge", "pass2.merge");
    if (Status s = high.start([&]() -> Status {
          fault::point("pass2.merge");
          Status merged = merge_runs(split.high, half_buffer, *high_writer, &high_levels,
                                     &high_tally, high_duplicates, [&](std::uint64_t done) {
                                       high_done = done;
                                       return !stop;
                                     });
          if (!merged) return merged;
          return high_writer->close();
        });
        !s) {
      return s;
    }
    Status low_status = merge_runs(split.low, half_buffer, *low_writer, &levels, &tally,
                                   result.duplicates_merged, [&](std::uint64_t done) {
                                     if (tick(done + high_done)) return true;
                                     stop = true;
                                     return false;
                                   });
    if (low_status) low_status = low_writer->close();
    if (!low_status) stop = true;
    Status high_status = high.join();
    if (!low_status) return low_status;
    if (!high_status) return high_status;
    result.duplicates_merged += high_duplicates;
    const std::uint64_t low_points = low_writer->written();
    const std::uint64_t high_points = high_writer->written();
    if (Status s = close_gap(result.path, split.low_records, low_points, high_points); !s) {
      return s;
    }
    result.points = low_points + high_points;
    result.max_tile_points = levels.finish_followed_by(high_levels);
    tally.append(high_tally);
    return {};
  }
};

SortedRunBuilder::SortedRunBuilder(std::unique_ptr<State> state) : state_(std::move(state)) {}
SortedRunBuilder::SortedRunBuilder(SortedRunBuilder&&) noexcept = default;
SortedRunBuilder& SortedRunBuilder::operator=(SortedRunBuilder&&) noexcept = default;
SortedRunBuilder::~SortedRunBuilder() = default;

Result<SortedRunBuilder> SortedRunBuilder::create(const SubdivideOptions& options) {
  assert(options.max_points >= 1);
  assert(options.min_level <= options.max_level && options.max_level <= kKeyLevel);
  std::error_code ec;
  std::filesystem::create_directories(options.tmp_dir, ec);
  if (ec) return io_error("cannot create temporary directory " + options.tmp_dir.string());
  auto st = std::make_unique<State>(options);
  st->budget_records = std::max<std::size_t>(options.memory_bytes / sizeof(SortedPoint), 4096);
  st->sort_capacity = std::min<std::size_t>(st->budget_records * sizeof(SortedPoint) / 2 /
                                                (2 * sizeof(SortedPoint) + 2 * sizeof(KeyIndex)),
                                            std::numeric_limits<std::uint32_t>::max());
  st->merge_buffer = std::max<std::size_t>(st->budget_records / 2 / (State::kFanIn + 2), 256);
  st->stem = "tinstream-" + std::to_string(reinterpret_cast<std::uintptr_t>(st.get())) + "-";
  st->buffer.reserve(st->sort_capacity);
  return SortedRunBuilder(std::move(st));
}

std::uint64_t SortedRunBuilder::input_points() const { return state_->input_points; }

Status SortedRunBuilder::add(std::span<const InputPoint> points) {
  State& st = *state_;
  assert(!st.finished);
  for (const InputPoint& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.x < -1.0 ||
        p.x > 1.0 || p.y < -1.0 || p.y > 1.0) {
      return invalid_argument("point " + std::to_string(st.input_points) +
                              " is not a finite normalised-Mercator position (x " +
                              std::to_string(p.x) + ", y " + std::to_string(p.y) + ", z " +
                              std::to_string(p.z) + ")");
    }
    // The key is computed by the spill thread (sort_chunk), off this thread.
    st.buffer.push_back({0, p.x, p.y, p.z, p.weight, 0});
    st.min_x = std::min(st.min_x, p.x);
    st.max_x = std::max(st.max_x, p.x);
    st.min_y = std::min(st.min_y, p.y);
    st.max_y = std::max(st.max_y, p.y);
    ++st.input_points;
    if (st.buffer.size() == st.sort_capacity) {
      if (Status s = st.spill(); !s) return s;
    }
  }
  return {};
}

Result<SortedRun> SortedRunBuilder::finish(const ProgressSink& progress) {
  State& st = *state_;
  assert(!st.finished);
  st.finished = true;
  if (Status s = st.flush(); !s) return s.error();
  SortedRun result;
  result.input_points = st.input_points;
  result.duplicates_merged = st.duplicates;
  const MergeTick tick = [&](std::uint64_t done) {
    return !progress || progress({"merge", done, result.input_points, "points"});
  };
  if (Status s = st.merge_to_fan_in(result.duplicates_merged, tick); !s) return s.error();
  result.path = st.options.output.empty() ? st.temp_path() : st.options.output;
  st.temporaries.add(result.path);  // removed unless everything succeeds
  const SubdivideOptions& options = st.options;
  const std::size_t tally_entries =
      options.index_entries != 0
          ? options.index_entries
          : std::max<std::size_t>(options.memory_bytes / 64 / sizeof(TileRange), 4096);
  MergeSplit split;
  if (options.merge_threads >= 2) {
    auto chosen = split_runs(st.runs);
    if (!chosen) return chosen.error();
    split = std::move(*chosen);
  }
  // Two tallies of half the entries each when the merge is split.
  TileTally tally(options.max_level, options.min_level,
                  split.low.empty() ? tally_entries : tally_entries / 2);
  const Status merged = split.low.empty()
                            ? st.merge_whole(result, tally, tick)
                            : st.merge_halves(split, tally_entries, result, tally, tick);
  if (!merged) return merged.error();
  std::error_code ec;
  for (const auto& r : st.runs) std::filesystem::remove(r, ec);
  const std::uint32_t extent_floor =
      st.input_points > 0 ? extent_level(st.max_x - st.min_x, st.max_y - st.min_y) : 0;
  result.finest_level = finest_level(result.max_tile_points, options, extent_floor);
  if (Status s = index_tiles(tally, result); !s) return s.error();
  st.temporaries.release(result.path);
  return result;
}

Result<SortedRun> subdivide(const PointFeed& feed, const SubdivideOptions& options,
                            const ProgressSink& progress) {
  auto builder = SortedRunBuilder::create(options);
  if (!builder) return builder.error();
  std::vector<InputPoint> batch;
  for (;;) {
    batch.clear();
    auto n = feed(batch);
    if (!n) return n.error();
    if (*n == 0) break;
    if (Status s = builder->add(batch); !s) return s.error();
    if (progress && !progress({"sort", builder->input_points(), 0, "points"})) {
      return Error(ErrorCode::cancelled, "ingest cancelled while sorting");
    }
  }
  return builder->finish(progress);
}

SortedRunReader::SortedRunReader(SortedRunReader&& other) noexcept
    : file_(std::exchange(other.file_, nullptr)),
      records_(other.records_),
      path_(std::move(other.path_)) {}

SortedRunReader& SortedRunReader::operator=(SortedRunReader&& other) noexcept {
  if (this != &other) {
    if (file_) std::fclose(file_);
    file_ = std::exchange(other.file_, nullptr);
    records_ = other.records_;
    path_ = std::move(other.path_);
  }
  return *this;
}

SortedRunReader::~SortedRunReader() {
  if (file_) std::fclose(file_);
}

Result<SortedRunReader> SortedRunReader::open(const std::filesystem::path& path) {
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  if (ec) return io_error("cannot stat sorted run " + path.string() + ": " + ec.message());
  if (bytes % sizeof(SortedPoint) != 0) {
    return corrupt_data("sorted run " + path.string() + " has " + std::to_string(bytes) +
                        " bytes, not a multiple of the 40-byte record");
  }
  SortedRunReader r;
  r.file_ = std::fopen(path.c_str(), "rb");
  if (!r.file_) return io_failure("cannot open", path);
  r.records_ = bytes / sizeof(SortedPoint);
  r.path_ = path;
  return r;
}

Status SortedRunReader::read(std::uint64_t first, std::uint64_t count,
                             std::vector<SortedPoint>& out) {
  if (first > records_ || count > records_ - first) {
    return invalid_argument("records [" + std::to_string(first) + ", +" + std::to_string(count) +
                            ") outside sorted run " + path_.string() + " of " +
                            std::to_string(records_));
  }
  out.resize(count);
  if (count == 0) return {};
  if (auto injected = fault::error_at("sorted_run.read")) {
    return io_error("cannot read " + path_.string() + ": " + *injected);
  }
  if (fseeko(file_, static_cast<off_t>(first * sizeof(SortedPoint)), SEEK_SET) != 0 ||
      std::fread(out.data(), sizeof(SortedPoint), count, file_) != count) {
    return io_failure("cannot read", path_);
  }
  return {};
}

}  // namespace tinstream::subdivide
