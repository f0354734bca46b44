#include "entropy.hpp"

#include <algorithm>

namespace tinstream::laz::detail {

std::uint8_t ByteStream::next_slow() {
  before_window_ += static_cast<std::uint64_t>(cur_ - window_);
  window_ = cur_;
  while (refill_ != nullptr && refill_->next_window(&cur_, &end_)) {
    window_ = cur_;
    if (cur_ != end_) return *cur_++;
  }
  cur_ = end_ = window_ = nullptr;
  ++overrun_;  // past the end: the encoder never needs these, a damaged stream does
  return 0;
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

SymbolModel::SymbolModel(std::uint32_t symbols) : symbols_(symbols), last_symbol_(symbols - 1) {
  assert(symbols >= 2 && symbols <= 2048);
  if (symbols > 16) {
    // LASzip's table has about one slot per 4 symbols; ours has 2 per symbol (at most 1024), so
    // that a slot nearly always holds one symbol and the search after the lookup ends at once.
    // Any table size finds the same symbol: it only brackets the bisection.
    std::uint32_t bits = 2;
    while ((1u << bits) < 2 * symbols && bits < 10) ++bits;
    table_size_ = 1u << bits;
    table_bits_shift_ = kSymbolLengthShift - bits;
  }
  const std::size_t words = 2 * std::size_t{symbols} + (table_size_ ? table_size_ + 2 : 0);
  storage_ = std::make_unique<std::uint32_t[]>(words);
  cumulative_ = storage_.get();
  counts_ = cumulative_ + symbols;
  table_ = table_size_ ? counts_ + symbols : nullptr;
  reset();
}

void SymbolModel::reset() {
  std::fill(counts_, counts_ + symbols_, 1u);
  total_count_ = 0;
  cycle_ = symbols_;
  rebuild();
  cycle_ = until_update_ = (symbols_ + 6) >> 1;
}

void SymbolModel::rebuild() {
  // `cycle_` symbols were counted since the last rebuild, so the total grows by exactly that.
  total_count_ += cycle_;
  if (total_count_ > kSymbolMaxCount) {
    total_count_ = 0;
    for (std::uint32_t s = 0; s < symbols_; ++s) {
      counts_[s] = (counts_[s] + 1) >> 1;
      total_count_ += counts_[s];
    }
  }
  const std::uint32_t scale = 0x80000000u / total_count_;
  std::uint32_t sum = 0;
  if (table_size_ == 0) {
    for (std::uint32_t s = 0; s < symbols_; ++s) {
      cumulative_[s] = (scale * sum) >> (31 - kSymbolLengthShift);
      sum += counts_[s];
    }
  } else {
    // table_[slot] = the last symbol whose cumulative value starts at or below slot's first
    // value; [table_[slot], table_[slot + 1]] brackets every symbol the slot can decode to.
    std::uint32_t slot = 0;
    for (std::uint32_t s = 0; s < symbols_; ++s) {
      cumulative_[s] = (scale * sum) >> (31 - kSymbolLengthShift);
      sum += counts_[s];
      const std::uint32_t first_slot = cumulative_[s] >> table_bits_shift_;
      while (slot < first_slot) table_[++slot] = s - 1;
    }
    table_[0] = 0;
    while (slot <= table_size_) table_[++slot] = symbols_ - 1;
  }
  cycle_ = std::min((5 * cycle_) >> 2, (symbols_ + 6) << 3);
  until_update_ = cycle_;
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

void ArithmeticDecoder::start(ByteStream stream) {
  in_ = stream;
  corrupt_ = false;
  length_ = 0xFFFFFFFFu;
  value_ = 0;
  for (int i = 0; i < 4; ++i) value_ = (value_ << 8) | in_.next();
}

IntegerDecoder::IntegerDecoder(std::uint32_t bits, std::uint32_t contexts, std::uint32_t high_bits)
    : high_bits_(high_bits) {
  assert(bits >= 1 && bits <= 32 && contexts >= 1);
  if (bits < 32) {
    corr_bits_ = bits;
    range_ = 1u << bits;
    min_correction_ = -static_cast<std::int32_t>(range_ / 2);
  } else {
    corr_bits_ = 32;
    range_ = 0;
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
