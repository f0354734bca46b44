// The entropy decoding layer of LAZ: a byte stream with a hard end, the range decoder (Said's
// FastAC as LASzip adapted it: 32-bit interval, renormalised a byte at a time), its adaptive bit
// and symbol models, and the integer decoder that LASzip builds from them.
//
// Everything here must reproduce the encoder's arithmetic to the bit: the model update rules
// (when counts are halved, how the cumulative table is scaled, how often it is rebuilt) are part
// of the format, not tuning. They are written from the LAZ specification and from reading
// LASzip's arithmeticmodel.cpp; the structure and the hostile-input guards are ours.
//
// Hostile input: a stream may hold any bytes. The decoder never reads outside its stream (bytes
// past the end read as 0 and are counted in overrun()), never loops without bound, never indexes
// a table out of range, and reports impossible values (a raw bit field wider than asked) through
// corrupt(). Callers check overrun()/corrupt()/consumed() after a chunk and turn them into errors.
//
// Threads: none of these types is shared; each chunk decoder owns its own.
#pragma once

#include <bit>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace tinstream::laz::detail {

// Where the bytes of one arithmetic-coded stream come from once its first window is used up:
// the reader refills windows from the file for chunks too large to hold in memory.
class StreamRefill {
 public:
  virtual ~StreamRefill() = default;
  // Points [*begin, *end) at the next bytes of the stream; false at the stream's end or on an
  // I/O error (failed() then says which). Called once per window, never per byte.
  virtual bool next_window(const std::uint8_t** begin, const std::uint8_t** end) = 0;
  virtual bool failed() const = 0;
};

// The bytes of one stream, window by window. Bytes are counted by position, not one by one:
// consumed = bytes of earlier windows + (cur - window start).
class ByteStream {
 public:
  ByteStream() = default;
  explicit ByteStream(StreamRefill* refill) : refill_(refill) {}
  ByteStream(const std::uint8_t* begin, const std::uint8_t* end)
      : cur_(begin), end_(end), window_(begin) {}

  std::uint8_t next() {
    if (cur_ != end_) [[likely]]
      return *cur_++;
    return next_slow();
  }
  // Shifts the next `bytes` (0..3) bytes into `value`, big-endian first, with one 4-byte load
  // when at least 4 bytes remain in the window.
  std::uint32_t shift_in(std::uint32_t value, std::uint32_t bytes) {
    if (end_ - cur_ >= 4) [[likely]] {
      const std::uint32_t next4 = (static_cast<std::uint32_t>(cur_[0]) << 24) |
                                  (static_cast<std::uint32_t>(cur_[1]) << 16) |
                                  (static_cast<std::uint32_t>(cur_[2]) << 8) | cur_[3];
      cur_ += bytes;
      const std::uint32_t bits = 8 * bytes;
      return static_cast<std::uint32_t>((static_cast<std::uint64_t>(value) << bits) |
                                        (static_cast<std::uint64_t>(next4) >> (32 - bits)));
    }
    for (std::uint32_t i = 0; i < bytes; ++i) value = (value << 8) | next();
    return value;
  }
  std::uint64_t consumed() const {
    return before_window_ + static_cast<std::uint64_t>(cur_ - window_);
  }
  std::uint64_t overrun() const { return overrun_; }  // bytes asked for past its end
  bool io_failed() const { return refill_ != nullptr && refill_->failed(); }

 private:
  std::uint8_t next_slow();

  const std::uint8_t* cur_ = nullptr;
  const std::uint8_t* end_ = nullptr;
  const std::uint8_t* window_ = nullptr;  // start of the current window
  StreamRefill* refill_ = nullptr;
  std::uint64_t before_window_ = 0;
  std::uint64_t overrun_ = 0;
};

inline constexpr std::uint32_t kRenormBelow = 1u << 24;  // interval length that forces a byte in
inline constexpr std::uint32_t kBitLengthShift = 13;     // bit models: probability resolution
inline constexpr std::uint32_t kBitMaxCount = 1u << kBitLengthShift;
inline constexpr std::uint32_t kSymbolLengthShift = 15;  // symbol models: cumulative resolution
inline constexpr std::uint32_t kSymbolMaxCount = 1u << kSymbolLengthShift;

// Adaptive binary model. Starts equiprobable, re-estimates after 4, 5, 6, ... up to 64 bits.
struct BitModel {
  std::uint32_t zero_count = 1;
  std::uint32_t total_count = 2;
  std::uint32_t zero_probability = 1u << (kBitLengthShift - 1);
  std::uint32_t cycle = 4;
  std::uint32_t until_update = 4;

  void reset() { *this = BitModel{}; }
  void update();
};

// Adaptive model over `symbols` symbols (2..2048). The cumulative distribution is rebuilt every
// `cycle` decoded symbols; the cycle grows by 5/4 up to 8 * (symbols + 6). Models of more than
// 16 symbols also keep a lookup table from the top bits of the scaled value to a symbol range.
class SymbolModel {
 public:
  explicit SymbolModel(std::uint32_t symbols);
  SymbolModel(SymbolModel&&) noexcept = default;
  SymbolModel& operator=(SymbolModel&&) noexcept = default;

  void reset();  // every count back to 1: the state at the start of a chunk
  std::uint32_t symbols() const { return symbols_; }

 private:
  friend class ArithmeticDecoder;
  void rebuild();

  std::uint32_t symbols_ = 0;
  std::uint32_t last_symbol_ = 0;
  std::uint32_t table_bits_shift_ = 0;  // cumulative value >> this = table slot
  std::uint32_t table_size_ = 0;        // 0: no table (small alphabets)
  std::uint32_t total_count_ = 0;
  std::uint32_t cycle_ = 0;
  std::uint32_t until_update_ = 0;
  std::unique_ptr<std::uint32_t[]> storage_;  // cumulative | counts | table
  std::uint32_t* cumulative_ = nullptr;       // symbols_ entries, scaled to 2^15
  std::uint32_t* counts_ = nullptr;           // symbols_ entries
  std::uint32_t* table_ = nullptr;            // table_size_ + 2 entries
};

// Models created the first time their context is used, and reset on their first use in each
// chunk (the state LASzip's "create or re-initialise" gives). `generation` moves on per chunk.
class LazyModels {
 public:
  LazyModels(std::size_t contexts, std::uint32_t symbols)
      : models_(contexts), used_in_(contexts, 0), symbols_(symbols) {}
  void next_chunk() { ++generation_; }
  SymbolModel& at(std::size_t context) {
    assert(context < models_.size());
    if (used_in_[context] != generation_) [[unlikely]]
      return first_use(context);
    return *models_[context];
  }

 private:
  SymbolModel& first_use(std::size_t context);

  std::vector<std::unique_ptr<SymbolModel>> models_;
  std::vector<std::uint32_t> used_in_;
  std::uint32_t generation_ = 1;
  std::uint32_t symbols_;
};

class ArithmeticDecoder {
 public:
  // Reads the 4 bytes that prime the interval.
  void start(ByteStream stream);

  std::uint32_t decode_bit(BitModel& m) {
    const std::uint32_t split = m.zero_probability * (length_ >> kBitLengthShift);
    std::uint32_t bit;
    if (value_ < split) {
      bit = 0;
      length_ = split;
      ++m.zero_count;
    } else {
      bit = 1;
      value_ -= split;
      length_ -= split;
    }
    if (length_ < kRenormBelow) renormalise();
    if (--m.until_update == 0) m.update();
    return bit;
  }

  std::uint32_t decode_symbol(SymbolModel& m) {
    std::uint32_t low, high = length_, symbol;
    length_ >>= kSymbolLengthShift;
    if (m.table_size_ != 0) {
      std::uint32_t scaled = value_ / length_;
      // A valid stream keeps value < length, so `scaled` exceeds 2^15 by a few at most, and
      // every such value falls in the last symbol; clamping keeps the table index in range for
      // hostile streams without changing any valid decode.
      if (scaled >= kSymbolMaxCount) scaled = kSymbolMaxCount - 1;
      const std::uint32_t slot = scaled >> m.table_bits_shift_;
      symbol = m.table_[slot];
      std::uint32_t above = m.table_[slot + 1] + 1;
      while (above > symbol + 1) {  // bisection inside the slot's symbol range, branch-free
        const std::uint32_t mid = (symbol + above) >> 1;
        const bool below = m.cumulative_[mid] > scaled;
        above = below ? mid : above;
        symbol = below ? symbol : mid;
      }
      low = m.cumulative_[symbol] * length_;
      if (symbol != m.last_symbol_) high = m.cumulative_[symbol + 1] * length_;
    } else {
      low = symbol = 0;
      std::uint32_t above = m.symbols_;
      std::uint32_t mid = above >> 1;
      do {  // bisection, branch-free
        const std::uint32_t bound = length_ * m.cumulative_[mid];
        const bool below = bound > value_;
        above = below ? mid : above;
        high = below ? bound : high;
        symbol = below ? symbol : mid;
        low = below ? low : bound;
      } while ((mid = (symbol + above) >> 1) != symbol);
    }
    value_ -= low;
    length_ = high - low;
    if (length_ < kRenormBelow) renormalise();
    ++m.counts_[symbol];
    if (--m.until_update_ == 0) m.rebuild();
    return symbol;
  }

  // Raw (equiprobable) fields of 1..32 bits.
  std::uint32_t read_bits(std::uint32_t bits) {
    assert(bits >= 1 && bits <= 32);
    if (bits > 19) {
      const std::uint32_t low = read_short();
      return (read_bits(bits - 16) << 16) | low;
    }
    length_ >>= bits;
    std::uint32_t v = value_ / length_;
    value_ -= length_ * v;
    if (length_ < kRenormBelow) renormalise();
    if (v >> bits) [[unlikely]] {
      corrupt_ = true;
      v &= (1u << bits) - 1;
    }
    return v;
  }
  std::uint32_t read_short() { return read_bits(16); }
  std::uint32_t read_int() {
    const std::uint32_t low = read_short();
    return (read_short() << 16) | low;
  }
  std::uint64_t read_int64() {
    const std::uint64_t low = read_int();
    return (static_cast<std::uint64_t>(read_int()) << 32) | low;
  }

  const ByteStream& stream() const { return in_; }
  bool corrupt() const { return corrupt_; }
  void mark_corrupt() { corrupt_ = true; }

 private:
  // Brings length back to >= 2^24 a byte at a time: 1, 2 or 3 bytes for lengths in
  // [2^16, 2^24), [2^8, 2^16), [1, 2^8) (length is never 0), i.e. clz(length) / 8 bytes.
  void renormalise() {
    const auto bytes = static_cast<std::uint32_t>(std::countl_zero(length_)) >> 3;
    value_ = in_.shift_in(value_, bytes);
    length_ <<= 8 * bytes;
  }

  std::uint32_t value_ = 0;
  std::uint32_t length_ = 0;
  ByteStream in_;
  bool corrupt_ = false;
};

// LASzip's integer "compressor" on the decoding side: a correction c is added to a prediction.
// c's magnitude class k (0..corr_bits) is a symbol in one of `contexts` models; within class k,
// c is a symbol of up to `high_bits` bits followed by k - high_bits raw bits. Results wrap
// modulo 2^bits (no wrap for 32 bits).
class IntegerDecoder {
 public:
  IntegerDecoder(std::uint32_t bits, std::uint32_t contexts, std::uint32_t high_bits = 8);

  void reset();
  std::int32_t decode(ArithmeticDecoder& dec, std::int32_t predicted, std::uint32_t context) {
    assert(context < magnitude_.size());
    const std::int32_t correction = decode_correction(dec, magnitude_[context]);
    std::int32_t real = static_cast<std::int32_t>(static_cast<std::uint32_t>(predicted) +
                                                  static_cast<std::uint32_t>(correction));
    if (range_ != 0) {
      if (real < 0) {
        real = static_cast<std::int32_t>(static_cast<std::uint32_t>(real) + range_);
      } else if (static_cast<std::uint32_t>(real) >= range_) {
        real = static_cast<std::int32_t>(static_cast<std::uint32_t>(real) - range_);
      }
    }
    return real;
  }
  // The magnitude class of the last correction: item decoders use it to pick later contexts.
  std::uint32_t last_k() const { return k_; }

 private:
  std::int32_t decode_correction(ArithmeticDecoder& dec, SymbolModel& magnitude) {
    k_ = dec.decode_symbol(magnitude);
    if (k_ == 0) return static_cast<std::int32_t>(dec.decode_bit(zero_or_one_));  // 0 or 1
    if (k_ >= 32) return min_correction_;
    std::uint32_t c = dec.decode_symbol(within_class_[k_]);
    if (k_ > high_bits_) {
      const std::uint32_t low_bits = k_ - high_bits_;
      c = (c << low_bits) | dec.read_bits(low_bits);
    }
    // Class k holds [-(2^k - 1), -2^(k-1)] and [2^(k-1) + 1, 2^k], mapped onto [0, 2^k).
    const std::uint32_t half = 1u << (k_ - 1);
    if (c >= half) return static_cast<std::int32_t>(c + 1);
    return static_cast<std::int32_t>(static_cast<std::int64_t>(c) - ((std::int64_t{1} << k_) - 1));
  }

  std::uint32_t corr_bits_;
  std::uint32_t range_;  // 2^bits, or 0 for 32 bits (no wrap)
  std::int32_t min_correction_;
  std::uint32_t high_bits_;
  std::uint32_t k_ = 0;
  std::vector<SymbolModel> magnitude_;     // one per context, corr_bits + 1 symbols
  BitModel zero_or_one_;                   // class 0
  std::vector<SymbolModel> within_class_;  // index 1..corr_bits (0 unused)
};

}  // namespace tinstream::laz::detail
