#include "entropy.hpp"

#include <algorithm>
#include <array>

namespace tinstream::laz::detail {

ByteSource::Shifted ByteSource::shift_in(std::uint32_t value, std::uint32_t bytes, Cursor at) {
  for (std::uint32_t i = 0; i < bytes; ++i) {
    while (at.cur == at.end) {
      if (window_ != nullptr) before_window_ += static_cast<std::uint64_t>(at.end - window_);
      if (!next_window(&at.cur, &at.end)) {
        // Past the end: the encoder never needs these bytes, a damaged stream does.
        window_ = at.cur = at.end = nullptr;
        ++overrun_;
        break;
      }
      window_ = at.cur;
    }
    value = (value << 8) | (at.cur != at.end ? *at.cur++ : 0u);
  }
  return {value, at};
}

void BitModel::update() {
  // Halve the counts when they reach the resolution limit, then re-estimate.
  total_count += cycle;
  if (total_count > kBitMaxCount) {
    total_count = (total_count + 1) >> 1;
    zero_count = (zero_count + 1) >> 1;
    if (zero_count == total_count) ++total_count;
  }
  const std::uint32_t scale = 0x80000000u / total_count;
  zero_probability = (zero_count * scale) >> (31 - kBitLengthShift);
  cycle = std::min<std::uint32_t>((5 * cycle) >> 2, 64);
  until_update = cycle;
}

SymbolModel::SymbolModel(std::uint32_t symbols) : last_symbol_(symbols - 1), symbols_(symbols) {
  assert(symbols >= 2 && symbols <= 2048);
  std::uint32_t bits = 4;
  while ((1u << bits) < 2 * symbols && (1u << bits) < kMaxTableSize) ++bits;
  table_size_ = 1u << bits;
  table_shift_ = kSymbolLengthShift - bits;
  storage_ = std::make_unique<std::uint16_t[]>((symbols + 3) + symbols);
  // + 2 slots past the table (see decode_symbol), + 2 that build_tables() may write and drop.
  slots_ = std::make_unique<std::uint64_t[]>(table_size_ + 4);
  std::uint16_t* cumulative = storage_.get();
  // Bounds past the last symbol, read by the 4-value loads: above any scaled value, so that
  // decoding never steps past the last symbol (whose decode uses the length instead).
  std::fill(cumulative + symbols, cumulative + symbols + 3, std::uint16_t{0xFFFF});
  cumulative_ = cumulative;
  counts_ = cumulative + symbols + 3;
  reset();
}

const std::uint64_t* SymbolModel::pending_table() {
  // Indexed like any table: by scaled >> table_shift_, at most table_size + 1.
  static constexpr auto kPending = [] {
    std::array<std::uint64_t, kMaxTableSize + 2> t{};
    t.fill(kSearchSlot);
    return t;
  }();
  return kPending.data();
}

void SymbolModel::reset() {
  std::fill(counts_, counts_ + symbols_, std::uint16_t{1});
  // The state a rebuild of these counts leaves (symbols_ <= 2048: no halving), tables pending.
  total_count_ = symbols_;
  cycle_ = until_update_ = (symbols_ + 6) >> 1;
  table_ = pending_table();
}

void SymbolModel::rebuild() {
  // `cycle_` symbols were counted since the last rebuild, so the total grows by exactly that.
  total_count_ += cycle_;
  if (total_count_ > kSymbolMaxCount) {
    total_count_ = 0;
    for (std::uint32_t s = 0; s < symbols_; ++s) {
      counts_[s] = static_cast<std::uint16_t>((counts_[s] + 1) >> 1);
      total_count_ += counts_[s];
    }
  }
  build_tables();
  cycle_ = std::min((5 * cycle_) >> 2, (symbols_ + 6) << 3);
  until_update_ = cycle_;
}

void SymbolModel::build_tables() {
  const std::uint32_t scale = 0x80000000u / total_count_;
  auto* cumulative = const_cast<std::uint16_t*>(cumulative_);
  std::uint32_t sum = 0;
  for (std::uint32_t s = 0; s < symbols_; ++s) {
    cumulative[s] = static_cast<std::uint16_t>((scale * sum) >> (31 - kSymbolLengthShift));
    sum += counts_[s];
  }
  // Slot j covers scaled values [j << shift, (j + 1) << shift): it gets the symbol its first
  // value falls in (and its bounds), marked for a search when the symbol after next starts
  // inside it too. cumulative[symbols_ ..] holds 0xFFFF, so the bounds past the last symbol are
  // those too.
  //
  // Symbol s owns the slots from ceil(c[s] / width) up to ceil(c[s + 1] / width). Most symbols
  // own 0, 1 or 2 slots in no predictable order, so each symbol writes its entry to the first
  // four slots from its own first one whatever it owns (a later symbol overwrites those that are
  // not its), and only a wider symbol loops. Its last slot gets the mark when c[s + 2] lies
  // before that slot's end (a plain store, not a read-modify-write: a symbol that owns no slot
  // stores to a spare slot past the table instead).
  auto slot_of = [cumulative](std::uint32_t s) {
    return s | (std::uint64_t{cumulative[s]} << 16) | (std::uint64_t{cumulative[s + 1]} << 32) |
           (std::uint64_t{cumulative[s + 2]} << 48);
  };
  std::uint64_t* table = slots_.get();
  const std::uint32_t round_up = (1u << table_shift_) - 1;
  std::uint32_t slot = 0;  // the first slot of symbol s: ceil(c[s] / width) <= table_size_
  const std::uint32_t spare = table_size_ + 3;  // where a symbol that owns no slot writes
  auto fill = [&](std::uint32_t s, std::uint32_t end) TINSTREAM_LAZ_LAMBDA {
    const std::uint32_t next = (end + round_up) >> table_shift_;
    const std::uint64_t entry = slot_of(s);
    table[slot] = table[slot + 1] = table[slot + 2] = table[slot + 3] = entry;
    for (std::uint32_t j = slot + 4; j < next; ++j) table[j] = entry;
    const std::uint64_t mark = cumulative[s + 2] < (next << table_shift_) ? kSearchSlot : 0;
    table[next > slot ? next - 1 : spare] = entry | mark;
    slot = next;
  };
  for (std::uint32_t s = 0; s < last_symbol_; ++s) fill(s, cumulative[s + 1]);
  fill(last_symbol_, kSymbolMaxCount);  // the rest of the table
  // Scaled values just past 2^15 (see decode_symbol) fall in the last symbol.
  table[table_size_] = table[table_size_ + 1] = slot_of(last_symbol_);
}

std::uint32_t SymbolModel::search(std::uint32_t scaled) {
  if (table_ == pending_table()) {  // the first decode since reset()
    table_ = slots_.get();
    build_tables();
  }
  // The symbol lies between the slot's first symbol and the next slot's (a search works in any
  // slot, marked or not).
  const std::uint32_t slot = scaled >> table_shift_;
  auto low = static_cast<std::uint32_t>(table_[slot] & (kSearchSlot - 1u));
  auto high = static_cast<std::uint32_t>(table_[slot + 1] & (kSearchSlot - 1u));
  while (low < high) {  // the last symbol in [low, high] whose cumulative value <= scaled
    const std::uint32_t mid = (low + high + 1) >> 1;
    if (cumulative_[mid] <= scaled) {
      low = mid;
    } else {
      high = mid - 1;
    }
  }
  return low;
}

SymbolModel& LazyModels::first_use(std::size_t context) {
  if (!models_[context]) {
    models_[context] = std::make_unique<SymbolModel>(symbols_);
  } else {
    models_[context]->reset();
  }
  used_in_[context] = generation_;
  return *models_[context];
}

void ArithmeticDecoder::start(ByteSource* source) {
  source_ = source;
  corrupt_ = false;
  length_ = 0xFFFFFFFFu;
  source->restart();
  const ByteSource::Shifted s = source->shift_in(0, 4, {nullptr, nullptr});
  value_ = s.value;
  at_ = s.at;
  // Every step keeps value < length once it holds (the decode steps rely on it), and a valid
  // stream starts with it; a damaged one that does not is marked and made to.
  if (value_ >= length_) {
    corrupt_ = true;
    value_ = length_ - 1;
  }
}

IntegerDecoder::IntegerDecoder(std::uint32_t bits, std::uint32_t contexts, std::uint32_t high_bits)
    : high_bits_(high_bits) {
  assert(bits >= 1 && bits <= 32 && contexts >= 1);
  if (bits < 32) {
    corr_bits_ = bits;
    mask_ = (1u << bits) - 1;
    min_correction_ = -static_cast<std::int32_t>(1u << (bits - 1));
  } else {
    corr_bits_ = 32;
    mask_ = 0xFFFFFFFFu;
    min_correction_ = INT32_MIN;
  }
  magnitude_.reserve(contexts);
  for (std::uint32_t c = 0; c < contexts; ++c) magnitude_.emplace_back(corr_bits_ + 1);
  // Class 32 (32-bit decoders) is the minimum itself and needs no model.
  const std::uint32_t classes = std::min<std::uint32_t>(corr_bits_, 31);
  within_class_.reserve(classes + 1);
  within_class_.emplace_back(2);  // unused slot 0 keeps indices equal to k
  for (std::uint32_t k = 1; k <= classes; ++k) {
    within_class_.emplace_back(1u << std::min(k, high_bits_));
  }
}

void IntegerDecoder::reset() {
  for (auto& m : magnitude_) m.reset();
  zero_or_one_.reset();
  for (std::size_t k = 1; k < within_class_.size(); ++k) within_class_[k].reset();
  k_ = 0;
}

}  // namespace tinstream::laz::detail
