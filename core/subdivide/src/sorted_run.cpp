#include "tinstream/subdivide/sorted_run.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <queue>
#include <string>
#include <thread>

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

class RunWriter {
 public:
  static Result<RunWriter> create(const std::filesystem::path& path, std::size_t buffer_records) {
    FilePtr f(std::fopen(path.c_str(), "wb"));
    if (!f) return io_failure("cannot create", path);
    RunWriter w;
    w.file_ = std::move(f);
    w.path_ = path;
    w.buffer_.reserve(std::max<std::size_t>(buffer_records, 256));
    return w;
  }
  Status push(const SortedPoint& p) {
    buffer_.push_back(p);
    ++written_;
    if (buffer_.size() == buffer_.capacity()) return flush();
    return {};
  }
  Status flush() {
    if (!buffer_.empty() && std::fwrite(buffer_.data(), sizeof(SortedPoint), buffer_.size(),
                                        file_.get()) != buffer_.size()) {
      return io_failure("cannot write", path_);
    }
    buffer_.clear();
    return {};
  }
  Status close() {
    if (Status s = flush(); !s) return s;
    if (std::fclose(file_.release()) != 0) return io_failure("cannot close", path_);
    return {};
  }
  std::uint64_t written() const { return written_; }

 private:
  FilePtr file_;
  std::filesystem::path path_;
  std::vector<SortedPoint> buffer_;
  std::uint64_t written_ = 0;
};

class RunCursor {
 public:
  static Result<RunCursor> open(const std::filesystem::path& path, std::size_t buffer_records) {
    FilePtr f(std::fopen(path.c_str(), "rb"));
    if (!f) return io_failure("cannot open", path);
    RunCursor c;
    c.file_ = std::move(f);
    c.path_ = path;
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
    size_ = std::fread(buffer_.data(), sizeof(SortedPoint), buffer_.size(), file_.get());
    pos_ = 0;
    if (size_ == 0 && std::ferror(file_.get())) return io_failure("cannot read", path_);
    return {};
  }
  FilePtr file_;
  std::filesystem::path path_;
  std::vector<SortedPoint> buffer_;
  std::size_t pos_ = 0, size_ = 0;
};

// Tracks, for every level, the largest number of records in one tile of a key-ordered stream.
class LevelCounter {
 public:
  LevelCounter() {
    prefix_.fill(~std::uint64_t{0});
    count_.fill(0);
    max_.fill(0);
  }
  void add(std::uint64_t key) {
    // Tiles nest: once a level's prefix is unchanged, all coarser levels are unchanged too.
    for (int level = static_cast<int>(kKeyLevel); level >= 0; --level) {
      const std::uint64_t prefix = key >> (2 * (kKeyLevel - static_cast<std::uint32_t>(level)));
      auto& c = count_[static_cast<std::size_t>(level)];
      auto& p = prefix_[static_cast<std::size_t>(level)];
      if (prefix == p) {
        for (int l = level; l >= 0; --l) ++count_[static_cast<std::size_t>(l)];
        return;
      }
      close(static_cast<std::size_t>(level));
      p = prefix;
      c = 1;
    }
  }
  std::vector<std::uint64_t> finish() {
    for (std::size_t l = 0; l <= kKeyLevel; ++l) close(l);
    return {max_.begin(), max_.end()};
  }

 private:
  void close(std::size_t level) { max_[level] = std::max(max_[level], count_[level]); }
  std::array<std::uint64_t, kKeyLevel + 1> prefix_{}, count_{}, max_{};
};

// Merges sorted runs into `writer`, dropping duplicate (x, y) (the first, lowest z, survives).
Status merge_runs(const std::vector<std::filesystem::path>& inputs, std::size_t buffer_records,
                  RunWriter& writer, LevelCounter* levels, std::uint64_t& duplicates,
                  const std::function<bool(std::uint64_t)>& tick) {
  std::vector<RunCursor> cursors;
  cursors.reserve(inputs.size());
  for (const auto& p : inputs) {
    auto c = RunCursor::open(p, buffer_records);
    if (!c) return c.error();
    if (!c->done()) cursors.push_back(std::move(*c));
  }
  auto greater = [&](std::size_t a, std::size_t b) {
    return record_less(cursors[b].current(), cursors[a].current());
  };
  std::priority_queue<std::size_t, std::vector<std::size_t>, decltype(greater)> heap(greater);
  for (std::size_t i = 0; i < cursors.size(); ++i) heap.push(i);
  SortedPoint last{};
  bool have_last = false;
  std::uint64_t merged = 0;
  while (!heap.empty()) {
    const std::size_t i = heap.top();
    heap.pop();
    const SortedPoint p = cursors[i].current();
    if (have_last && same_xy(last, p)) {
      ++duplicates;
    } else {
      if (Status s = writer.push(p); !s) return s;
      if (levels) levels->add(p.key);
      last = p;
      have_last = true;
    }
    if (Status s = cursors[i].advance(); !s) return s;
    if (!cursors[i].done()) heap.push(i);
    if ((++merged & 0xFFFF) == 0 && tick && !tick(merged)) {
      return Error(ErrorCode::cancelled, "ingest cancelled while merging sorted runs");
    }
  }
  return {};
}

}  // namespace

std::uint64_t morton_interleave(std::uint32_t x, std::uint32_t y) {
  return spread_bits(x) | (spread_bits(y) << 1);
}

std::uint64_t cell_key(double x, double y) {
  const geo::TileId cell = geo::TileId::containing({x, y}, kKeyLevel);
  return morton_interleave(cell.x, cell.y);
}

geo::TileId tile_of_key(std::uint64_t key, std::uint32_t level) {
  const std::uint64_t prefix = key >> (2 * (kKeyLevel - level));
  return {level, compact_bits(prefix), compact_bits(prefix >> 1)};
}

Result<SortedRun> subdivide(const PointFeed& feed, const SubdivideOptions& options,
                            const ProgressSink& progress) {
  assert(options.max_points >= 1);
  assert(options.min_level <= options.max_level && options.max_level <= kKeyLevel);
  std::error_code ec;
  std::filesystem::create_directories(options.tmp_dir, ec);
  if (ec) return io_error("cannot create temporary directory " + options.tmp_dir.string());

  // Half the budget sorts (two buffers: one is sorted and written on a second thread while the
  // other fills), the other half buffers the merge.
  const std::size_t budget_records =
      std::max<std::size_t>(options.memory_bytes / sizeof(SortedPoint), 4096);
  const std::size_t sort_capacity = budget_records / 4;
  const std::size_t fan_in = 64;
  const std::size_t merge_buffer = std::max<std::size_t>(budget_records / 2 / (fan_in + 1), 256);

  const std::string stem =
      "tinstream-" + std::to_string(reinterpret_cast<std::uintptr_t>(&options)) + "-";
  FileSet temporaries;
  std::size_t next_id = 0;
  auto temp_path = [&] {
    auto p = options.tmp_dir / (stem + std::to_string(next_id++) + ".run");
    temporaries.add(p);
    return p;
  };

  SortedRun result;
  std::vector<SortedPoint> buffer, spilling;
  buffer.reserve(sort_capacity);
  std::vector<InputPoint> batch;
  std::vector<std::filesystem::path> runs;

  // Sorts `chunk` and writes it as a run at `path`, dropping exact duplicates; runs on the spill
  // thread (touches nothing else shared).
  auto write_run = [](std::vector<SortedPoint>& chunk, const std::filesystem::path& path,
                      std::uint64_t& duplicates) -> Status {
    std::sort(chunk.begin(), chunk.end(), record_less);
    auto w = RunWriter::create(path, 1 << 15);
    if (!w) return w.error();
    for (std::size_t i = 0; i < chunk.size(); ++i) {
      if (i > 0 && same_xy(chunk[i - 1], chunk[i])) {
        ++duplicates;
        continue;
      }
      if (Status s = w->push(chunk[i]); !s) return s;
    }
    return w->close();
  };
  std::thread spill_thread;
  Status spill_status;
  std::uint64_t spill_duplicates = 0;
  auto join_spill = [&]() -> Status {
    if (spill_thread.joinable()) spill_thread.join();
    result.duplicates_merged += std::exchange(spill_duplicates, 0);
    return std::exchange(spill_status, Status{});
  };
  // Hands the full buffer to the spill thread (after the previous spill finished) and continues
  // with the other buffer.
  auto spill = [&]() -> Status {
    if (Status s = join_spill(); !s) return s;
    std::swap(buffer, spilling);
    buffer.clear();
    buffer.reserve(sort_capacity);
    auto path = temp_path();
    runs.push_back(path);
    spill_thread =
        std::thread([&, path] { spill_status = write_run(spilling, path, spill_duplicates); });
    return {};
  };
  struct JoinOnExit {
    std::thread& t;
    ~JoinOnExit() {
      if (t.joinable()) t.join();
    }
  } join_on_exit{spill_thread};

  // Phase 1: read, key, sort in memory-sized chunks.
  for (;;) {
    batch.clear();
    auto n = feed(batch);
    if (!n) return n.error();
    if (*n == 0) break;
    for (const InputPoint& p : batch) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.x < -1.0 ||
          p.x > 1.0 || p.y < -1.0 || p.y > 1.0) {
        return invalid_argument("point " + std::to_string(result.input_points) +
                                " is not a finite normalised-Mercator position (x " +
                                std::to_string(p.x) + ", y " + std::to_string(p.y) + ", z " +
                                std::to_string(p.z) + ")");
      }
      buffer.push_back({cell_key(p.x, p.y), p.x, p.y, p.z, p.weight, 0});
      ++result.input_points;
      if (buffer.size() == sort_capacity) {
        if (Status s = spill(); !s) return s.error();
      }
    }
    if (progress && !progress({"sort", result.input_points, 0, "points"})) {
      return Error(ErrorCode::cancelled, "ingest cancelled while sorting");
    }
  }
  if (!buffer.empty() || runs.empty()) {
    if (Status s = spill(); !s) return s.error();
  }
  if (Status s = join_spill(); !s) return s.error();
  std::vector<SortedPoint>().swap(buffer);
  std::vector<SortedPoint>().swap(spilling);

  // Phase 2: merge down to one run (multi-pass when there are more runs than the fan-in).
  auto tick = [&](std::uint64_t done) {
    return !progress || progress({"merge", done, result.input_points, "points"});
  };
  while (runs.size() > fan_in) {
    std::vector<std::filesystem::path> next;
    for (std::size_t i = 0; i < runs.size(); i += fan_in) {
      const std::vector<std::filesystem::path> group(
          runs.begin() + static_cast<std::ptrdiff_t>(i),
          runs.begin() + static_cast<std::ptrdiff_t>(std::min(runs.size(), i + fan_in)));
      auto path = temp_path();
      auto w = RunWriter::create(path, merge_buffer);
      if (!w) return w.error();
      if (Status s = merge_runs(group, merge_buffer, *w, nullptr, result.duplicates_merged, tick);
          !s)
        return s.error();
      if (Status s = w->close(); !s) return s.error();
      for (const auto& g : group) std::filesystem::remove(g, ec);
      next.push_back(path);
    }
    runs = std::move(next);
  }
  result.path = options.output.empty() ? temp_path() : options.output;
  temporaries.add(result.path);  // removed unless everything succeeds
  LevelCounter levels;
  {
    auto w = RunWriter::create(result.path, merge_buffer);
    if (!w) return w.error();
    if (Status s = merge_runs(runs, merge_buffer, *w, &levels, result.duplicates_merged, tick); !s)
      return s.error();
    if (Status s = w->close(); !s) return s.error();
    result.points = w->written();
  }
  result.max_tile_points = levels.finish();

  // Finest level: the smallest level whose fullest tile fits the budget.
  result.finest_level = options.max_level;
  for (std::uint32_t l = options.min_level; l <= options.max_level; ++l) {
    if (result.max_tile_points[l] <= options.max_points) {
      result.finest_level = l;
      break;
    }
  }

  // Phase 3: the tile index of level L (keys only matter; one sequential pass).
  {
    auto cursor = RunCursor::open(result.path, 1 << 15);
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
      if (Status s = cursor->advance(); !s) return s.error();
    }
  }
  temporaries.release(result.path);
  return result;
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
  if (fseeko(file_, static_cast<off_t>(first * sizeof(SortedPoint)), SEEK_SET) != 0 ||
      std::fread(out.data(), sizeof(SortedPoint), count, file_) != count) {
    return io_failure("cannot read", path_);
  }
  return {};
}

}  // namespace tinstream::subdivide
