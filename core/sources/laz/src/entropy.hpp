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
#include <cstring>
#include <memory>
#include <vector>

// The decoding steps are forced inline into the item loops that call them: a call that is not
// inlined would take the address of the loop's local decoder and move its state to memory.
#define TINSTREAM_LAZ_INLINE [[gnu::always_inline]] inline
// The same for a lambda (after its parameter list).
#define TINSTREAM_LAZ_LAMBDA __attribute__((always_inline))

namespace tinstream::laz::detail {

// if_true or if_false for conditions that no predictor guesses (which symbol, which bit): said
// so, the compiler selects (cmov) where a plain ?: may become a branch.
TINSTREAM_LAZ_INLINE std::uint32_t pick(bool condition, std::uint32_t if_true,
                                        std::uint32_t if_false) {
  return __builtin_expect_with_probability(condition, true, 0.5) ? if_true : if_false;
}

// Where the bytes of one arithmetic-coded stream come from, window by window (the reader refills
// windows from the file, so a chunk of any size decodes in bounded memory), and how many of them
// the decoder has taken. The decoder keeps its own cursor into the current window (so that a
// decoding loop can hold it in registers) and comes here only when fewer than 4 bytes are left
// in the window. Bytes are counted by position: consumed = bytes of earlier windows + (cursor -
// window start).
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  // Points [*begin, *end) at the next bytes of the stream; false at the stream's end or on an
  // I/O error (failed() then says which). Called once per window, never per byte.
  virtual bool next_window(const std::uint8_t** begin, const std::uint8_t** end) = 0;
  virtual bool failed() const = 0;

  // A decoder's cursor into the current window.
  struct Cursor {
    const std::uint8_t* cur;
    const std::uint8_t* end;
  };
  // Starts counting a new stream (after the refill has been pointed at it).
  void restart() {
    window_ = nullptr;
    before_window_ = 0;
    overrun_ = 0;
  }
  // Shifts the next `bytes` (0..4) bytes of the stream into `value`, big-endian first, starting
  // at `at` and crossing into the next windows as needed (bytes past the stream's end read as 0
  // and are counted in overrun()).
  struct Shifted {
    std::uint32_t value;
    Cursor at;
  };
  Shifted shift_in(std::uint32_t value, std::uint32_t bytes, Cursor at);
  std::uint64_t consumed(const std::uint8_t* cur) const {
    return before_window_ + static_cast<std::uint64_t>(cur - window_);
  }
  std::uint64_t overrun() const { return overrun_; }  // bytes asked for past the stream's end

 private:
  const std::uint8_t* window_ = nullptr;  // start of the current window
  std::uint64_t before_window_ = 0;
  std::uint64_t overrun_ = 0;
};

inline constexpr std::uint32_t kBitLengthShift = 13;  // bit models: probability resolution
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
// `cycle` decoded symbols; the cycle grows by 5/4 up to 8 * (symbols + 6).
//
// Decoding looks the symbol up in a table indexed by the top bits of the scaled value (LASzip
// keeps one for models of more than 16 symbols, about one slot per 4 symbols; ours has about 2
// slots per symbol, at least 16 and at most 1024, for every model). A slot holds the symbol its
// first value falls in and that symbol's cumulative bounds c[s], c[s + 1], c[s + 2] (16 bits
// each, one 64-bit word: the decode needs one load after its division, not a table load and
// then a dependent load of the bounds); the decoder then steps to the next symbol when the
// value lies beyond this one, without a branch. Only a slot in which a third symbol starts is
// marked (kSearchSlot), and decoding searches there: that takes a symbol narrower than a slot,
// which is rarely decoded. The table only speeds the search up: any table finds the symbols the
// cumulative distribution defines.
//
// Counts fit 16 bits: the total is halved as soon as it passes 2^15 at a rebuild, and at most
// 8 * (2048 + 6) symbols are counted between rebuilds, so no count passes 2^15 + 16432.
class SymbolModel {
 public:
  explicit SymbolModel(std::uint32_t symbols);
  SymbolModel(SymbolModel&&) noexcept = default;
  SymbolModel& operator=(SymbolModel&&) noexcept = default;

  // Every count back to 1: the state at the start of a chunk. The tables of that state are
  // built on the model's first decode (see pending_table()), so that a chunk pays nothing for
  // the many models it never uses (an integer decoder's wide classes, unused contexts).
  void reset();
  std::uint32_t symbols() const { return symbols_; }

 private:
  friend class ArithmeticDecoder;
  friend struct SymbolModelProbe;  // tests/laz_model_test.cpp
  static constexpr std::uint16_t kSearchSlot = 0x8000;
  static constexpr std::uint32_t kMaxTableSize = 1024;
  // What table_ points at while the tables are not built: every slot a search slot, so that
  // the first decode takes the search path, which builds them; the decode's fast path needs
  // no test of its own.
  static const std::uint64_t* pending_table();
  void rebuild();
  void build_tables();  // cumulative_ and the slot table from counts_ and total_count_
  std::uint32_t search(std::uint32_t scaled);  // in a kSearchSlot slot (builds pending tables)

  // Used by every decode, first. A slot: symbol (and kSearchSlot) | c[s] << 16 | c[s + 1] << 32
  // | c[s + 2] << 48, bounds past the last symbol 0xFFFF.
  const std::uint64_t* table_ = nullptr;  // table_size + 2 slots read (the last two: last symbol)
  const std::uint16_t* cumulative_ = nullptr;  // symbols_ entries scaled to 2^15, then 3 bounds
  std::uint16_t* counts_ = nullptr;            // symbols_ entries
  std::uint32_t table_shift_ = 0;              // scaled value >> this = slot
  std::uint32_t last_symbol_ = 0;
  std::uint32_t until_update_ = 0;
  // Used by rebuilds.
  std::uint32_t symbols_ = 0;
  std::uint32_t total_count_ = 0;
  std::uint32_t cycle_ = 0;
  std::uint32_t table_size_ = 0;
  std::unique_ptr<std::uint16_t[]> storage_;  // cumulative | counts
  std::unique_ptr<std::uint64_t[]> slots_;    // table
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

// Big-endian hosts: the four 16-bit values of a 64-bit load in memory order, first lowest.
inline std::uint64_t swap_halves16(std::uint64_t v) {
  return ((v & 0xFFFF) << 48) | ((v & 0xFFFF0000u) << 16) | ((v >> 16) & 0xFFFF0000u) | (v >> 48);
}

// The range decoder. A small value type: a decoding loop copies it into a local, so that the
// interval and the cursor stay in registers (nothing it calls out of line takes its address),
// and copies it back at the end. Renormalisation is branch-free: every step shifts in the
// 0-3 bytes that bring the interval length back to >= 2^24 with one 4-byte load.
class ArithmeticDecoder {
 public:
  // Reads the 4 bytes that prime the interval; `source` must have been pointed at the stream.
  void start(ByteSource* source);

  TINSTREAM_LAZ_INLINE std::uint32_t decode_bit(BitModel& m) {
    const std::uint32_t split = m.zero_probability * (length_ >> kBitLengthShift);
    const bool one = value_ >= split;
    value_ -= pick(one, split, 0);
    length_ = pick(one, length_ - split, split);
    m.zero_count += one ? 0 : 1;
    renormalise();
    if (--m.until_update == 0) [[unlikely]]
      m.update();
    return one ? 1 : 0;
  }

  TINSTREAM_LAZ_INLINE std::uint32_t decode_symbol(SymbolModel& m) {
    const std::uint32_t unit = length_ >> kSymbolLengthShift;  // >= 2^9
    // value < length (see start()), so scaled < 2^15 + 2^15 / unit <= 2^15 + 64: past the
    // last symbol's start by a few at most, which the table's two extra slots cover.
    const std::uint32_t scaled = value_ / unit;
    // The slot: its symbol and cumulative[symbol .. symbol + 2]; the value lies in `symbol` or
    // the next.
    const std::uint64_t entry = m.table_[scaled >> m.table_shift_];
    auto symbol = static_cast<std::uint32_t>(entry & 0xFFFF);
    std::uint64_t bounds = entry >> 16;
    if (symbol & SymbolModel::kSearchSlot) [[unlikely]] {
      symbol = m.search(scaled);
      std::memcpy(&bounds, m.cumulative_ + symbol, sizeof bounds);
      if constexpr (std::endian::native == std::endian::big) bounds = swap_halves16(bounds);
    }
    const auto c1 = static_cast<std::uint32_t>((bounds >> 16) & 0xFFFF);
    const std::uint32_t x0 = static_cast<std::uint32_t>(bounds & 0xFFFF) * unit;
    const std::uint32_t x1 = c1 * unit;
    const std::uint32_t x2 = static_cast<std::uint32_t>((bounds >> 32) & 0xFFFF) * unit;
    const bool next = scaled >= c1;
    symbol += next ? 1 : 0;
    const std::uint32_t low = pick(next, x1, x0);
    // The last symbol takes the rest of the interval, not its scaled share.
    const std::uint32_t high = pick(symbol == m.last_symbol_, length_, pick(next, x2, x1));
    value_ -= low;
    length_ = high - low;
    renormalise();
    ++m.counts_[symbol];
    if (--m.until_update_ == 0) [[unlikely]]
      m.rebuild();
    return symbol;
  }

  // Raw (equiprobable) fields of 1..32 bits; more than 19 bits come as two fields, low 16 first.
  TINSTREAM_LAZ_INLINE std::uint32_t read_bits(std::uint32_t bits) {
    assert(bits >= 1 && bits <= 32);
    if (bits > 19) {
      const std::uint32_t low = read_field(16);
      return (read_field(bits - 16) << 16) | low;
    }
    return read_field(bits);
  }
  TINSTREAM_LAZ_INLINE std::uint32_t read_short() { return read_field(16); }
  TINSTREAM_LAZ_INLINE std::uint32_t read_int() {
    const std::uint32_t low = read_field(16);
    return (read_field(16) << 16) | low;
  }
  TINSTREAM_LAZ_INLINE std::uint64_t read_int64() {
    const std::uint64_t low = read_int();
    return (static_cast<std::uint64_t>(read_int()) << 32) | low;
  }

  // Bytes of the stream taken so far, bytes asked for past its end, and its source's I/O state.
  std::uint64_t consumed() const { return source_->consumed(at_.cur); }
  std::uint64_t overrun() const { return source_->overrun(); }
  bool io_failed() const { return source_->failed(); }
  bool corrupt() const { return corrupt_; }
  void mark_corrupt() { corrupt_ = true; }

 private:
  // One raw field of 1..19 bits.
  TINSTREAM_LAZ_INLINE std::uint32_t read_field(std::uint32_t bits) {
    length_ >>= bits;
    std::uint32_t v = value_ / length_;
    value_ -= length_ * v;
    renormalise();
    if (v >> bits) [[unlikely]] {
      corrupt_ = true;
      v &= (1u << bits) - 1;
    }
    return v;
  }

  // Brings length back to >= 2^24 a byte at a time: 1, 2 or 3 bytes for lengths in
  // [2^16, 2^24), [2^8, 2^16), [1, 2^8) (length is never 0), none above: clz(length) / 8 bytes.
  TINSTREAM_LAZ_INLINE void renormalise() {
    // (length is never 0; `| 1` tells the compiler so, which spares a branch)
    const auto shift = static_cast<std::uint32_t>(std::countl_zero(length_ | 1)) & 24u;
    if (at_.end - at_.cur < 4) [[unlikely]] {
      const ByteSource::Shifted s = source_->shift_in(value_, shift >> 3, at_);
      value_ = s.value;
      at_ = s.at;
    } else {
      std::uint32_t next4;
      std::memcpy(&next4, at_.cur, sizeof next4);
      if constexpr (std::endian::native == std::endian::little) next4 = __builtin_bswap32(next4);
      value_ = (value_ << shift) |
               static_cast<std::uint32_t>(static_cast<std::uint64_t>(next4) >> (32 - shift));
      at_.cur += shift >> 3;
    }
    length_ <<= shift;
  }

  std::uint32_t value_ = 0;
  std::uint32_t length_ = 0;
  ByteSource::Cursor at_{nullptr, nullptr};
  ByteSource* source_ = nullptr;
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
  // For bits < 32 the result is reduced modulo 2^bits. LASzip adds or subtracts 2^bits once
  // instead, which leaves the same low `bits` bits; every caller keeps only those (it stores
  // the result in a field of `bits` bits).
  TINSTREAM_LAZ_INLINE std::int32_t decode(ArithmeticDecoder& dec, std::int32_t predicted,
                                           std::uint32_t context) {
    assert(context < magnitude_.size());
    const std::int32_t correction = decode_correction(dec, magnitude_[context]);
    return static_cast<std::int32_t>(
        (static_cast<std::uint32_t>(predicted) + static_cast<std::uint32_t>(correction)) & mask_);
  }
  // The magnitude class of the last correction: item decoders use it to pick later contexts.
  std::uint32_t last_k() const { return k_; }

  // decode() in its two steps, one symbol each (for loops that alternate two streams symbol by
  // symbol): the correction's magnitude class, then the value from that class.
  // decode(dec, p, ctx) == decode_in_class(dec, p, decode_class(dec, ctx)).
  TINSTREAM_LAZ_INLINE std::uint32_t decode_class(ArithmeticDecoder& dec, std::uint32_t context) {
    assert(context < magnitude_.size());
    return k_ = dec.decode_symbol(magnitude_[context]);
  }
  TINSTREAM_LAZ_INLINE std::int32_t decode_in_class(ArithmeticDecoder& dec, std::int32_t predicted,
                                                    std::uint32_t k) {
    const std::int32_t correction = correction_in_class(dec, k);
    return static_cast<std::int32_t>(
        (static_cast<std::uint32_t>(predicted) + static_cast<std::uint32_t>(correction)) & mask_);
  }

 private:
  TINSTREAM_LAZ_INLINE std::int32_t decode_correction(ArithmeticDecoder& dec,
                                                      SymbolModel& magnitude) {
    const std::uint32_t k = k_ = dec.decode_symbol(magnitude);
    return correction_in_class(dec, k);
  }
  TINSTREAM_LAZ_INLINE std::int32_t correction_in_class(ArithmeticDecoder& dec, std::uint32_t k) {
    if (k == 0) return static_cast<std::int32_t>(dec.decode_bit(zero_or_one_));  // 0 or 1
    if (k >= 32) [[unlikely]]
      return min_correction_;
    std::uint32_t c = dec.decode_symbol(within_class_[k]);
    if (k > high_bits_) {
      const std::uint32_t low_bits = k - high_bits_;
      c = (c << low_bits) | dec.read_bits(low_bits);
    }
    // Class k holds [-(2^k - 1), -2^(k-1)] and [2^(k-1) + 1, 2^k], mapped onto [0, 2^k): the
    // lower half is c - (2^k - 1), the upper c + 1 (arithmetic, not a branch: the halves are
    // about equally likely).
    const std::uint32_t lower_half = c < (1u << (k - 1)) ? 1u : 0u;
    return static_cast<std::int32_t>(c + 1 - (lower_half << k));
  }

  std::uint32_t corr_bits_;
  std::uint32_t mask_;  // 2^bits - 1, or all ones for 32 bits (no wrap)
  std::int32_t min_correction_;
  std::uint32_t high_bits_;
  std::uint32_t k_ = 0;
  std::vector<SymbolModel> magnitude_;     // one per context, corr_bits + 1 symbols
  BitModel zero_or_one_;                   // class 0
  std::vector<SymbolModel> within_class_;  // index 1..corr_bits (0 unused)
};

}  // namespace tinstream::laz::detail
