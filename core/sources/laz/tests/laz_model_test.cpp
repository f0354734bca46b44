// The adaptive symbol model's decode lookup table (entropy.hpp, SymbolModel) against its own
// cumulative counts, directly after each rebuild: every scaled value the decoder can meet maps,
// through the table's slot (its symbol, the step to the next symbol, or the search a marked slot
// asks for), to the symbol whose cumulative range holds it. The reference sha256 checks of whole
// files cover the models only through the symbols real files happen to decode; these drive
// models of 2 to 2048 symbols through many rebuilds on random streams, and through count
// distributions built to leave narrow symbols (one that starts and ends inside a slot, which
// only a search mark finds).
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "../src/entropy.hpp"

namespace tinstream::laz::detail {

// Reads and sets a model's private state (a friend of SymbolModel).
struct SymbolModelProbe {
  // The symbol whose cumulative range [c[s], c[s + 1]) holds `scaled` (the last symbol takes
  // everything from its start on), from the cumulative values alone.
  static std::uint32_t by_counts(const SymbolModel& m, std::uint32_t scaled) {
    std::uint32_t s = 0;
    while (s + 1 < m.symbols_ && m.cumulative_[s + 1] <= scaled) ++s;
    return s;
  }
  // What decode_symbol's lookup finds for `scaled`: the slot's symbol, or the next one when the
  // value lies past the slot symbol's end, or a search in a marked slot.
  static std::uint32_t by_table(SymbolModel& m, std::uint32_t scaled) {
    const std::uint64_t entry = m.table_[scaled >> m.table_shift_];
    auto symbol = static_cast<std::uint32_t>(entry & 0xFFFF);
    if ((symbol & SymbolModel::kSearchSlot) != 0) return m.search(scaled);
    const auto c1 = static_cast<std::uint32_t>((entry >> 32) & 0xFFFF);
    return scaled >= c1 ? symbol + 1 : symbol;
  }
  // Empty when the state is consistent; else what is wrong (the first finding).
  static std::string check(SymbolModel& m) {
    if (m.table_ != m.slots_.get()) return "tables not built";
    std::uint32_t total = 0;
    for (std::uint32_t s = 0; s < m.symbols_; ++s) total += m.counts_[s];
    if (total != m.total_count_) {
      return "total " + std::to_string(m.total_count_) + ", counts sum to " + std::to_string(total);
    }
    // The cumulative distribution of the counts, scaled to 2^15 as the format defines it.
    const std::uint32_t scale = 0x80000000u / total;
    std::uint32_t sum = 0;
    for (std::uint32_t s = 0; s < m.symbols_; ++s) {
      if (m.cumulative_[s] != (scale * sum) >> (31 - kSymbolLengthShift)) {
        return "cumulative[" + std::to_string(s) + "] does not match the counts";
      }
      sum += m.counts_[s];
    }
    // Every value decode_symbol can look up: below 2^15 + 64 (see decode_symbol).
    for (std::uint32_t scaled = 0; scaled < kSymbolMaxCount + 64; ++scaled) {
      const std::uint32_t want = by_counts(m, scaled), got = by_table(m, scaled);
      if (want != got) {
        return "scaled value " + std::to_string(scaled) + " (slot " +
               std::to_string(scaled >> m.table_shift_) + ") of symbol " + std::to_string(want) +
               " found symbol " + std::to_string(got);
      }
    }
    return {};
  }
  static bool just_rebuilt(const SymbolModel& m) {
    return m.table_ == m.slots_.get() && m.until_update_ == m.cycle_;
  }
  // Sets the counts and builds the tables from them, as a rebuild does.
  static void set_counts(SymbolModel& m, const std::vector<std::uint16_t>& counts) {
    std::uint32_t total = 0;
    for (std::uint32_t s = 0; s < m.symbols_; ++s) {
      m.counts_[s] = counts[s];
      total += counts[s];
    }
    m.total_count_ = total;
    m.table_ = m.slots_.get();
    m.build_tables();
  }
  // How many slots are marked for a search (so that a test can tell it met some).
  static std::uint32_t marked_slots(const SymbolModel& m) {
    std::uint32_t n = 0;
    for (std::uint32_t j = 0; j < m.table_size_; ++j) {
      if ((m.table_[j] & SymbolModel::kSearchSlot) != 0) ++n;
    }
    return n;
  }
};

namespace {

// One window of seeded random bytes: a stream that decodes to symbols drawn roughly by the
// model's own probabilities, so the counts drift into uneven distributions.
class RandomBytes : public ByteSource {
 public:
  RandomBytes(std::size_t size, std::uint32_t seed) : bytes_(size) {
    std::mt19937 rng(seed);
    for (auto& b : bytes_) b = static_cast<std::uint8_t>(rng());
  }
  bool next_window(const std::uint8_t** begin, const std::uint8_t** end) override {
    if (given_) return false;
    given_ = true;
    *begin = bytes_.data();
    *end = bytes_.data() + bytes_.size();
    return true;
  }
  bool failed() const override { return false; }

 private:
  std::vector<std::uint8_t> bytes_;
  bool given_ = false;
};

constexpr std::uint32_t kSymbolCounts[] = {2, 3, 5, 16, 17, 33, 255, 256, 257, 1000, 2048};

TEST(LazSymbolModel, TableFindsEverySymbolAfterEachRebuildOfADecodedStream) {
  for (const std::uint32_t symbols : kSymbolCounts) {
    SCOPED_TRACE("symbols " + std::to_string(symbols));
    SymbolModel model(symbols);
    RandomBytes bytes(1 << 18, symbols);
    ArithmeticDecoder dec;
    dec.start(&bytes);
    // Rebuilds come after cycles growing by 5/4 up to 8 * (symbols + 6): a few dozen each.
    int rebuilds = 0;
    for (int i = 0; i < 200000 && rebuilds < 40; ++i) {
      const std::uint32_t s = dec.decode_symbol(model);
      ASSERT_LT(s, symbols);
      if (SymbolModelProbe::just_rebuilt(model)) {
        ++rebuilds;
        const std::string error = SymbolModelProbe::check(model);
        ASSERT_EQ(error, "") << "after rebuild " << rebuilds;
      }
    }
    EXPECT_GE(rebuilds, 10);
  }
}

TEST(LazSymbolModel, TableFindsNarrowSymbolsThatOnlyASearchMarkReaches) {
  std::mt19937 rng(7);
  std::uint32_t marked = 0;
  for (const std::uint32_t symbols : kSymbolCounts) {
    SCOPED_TRACE("symbols " + std::to_string(symbols));
    SymbolModel model(symbols);
    for (int round = 0; round < 20; ++round) {
      // Mostly count-1 symbols (narrower than a slot once the total is large) beside a few wide
      // ones, at random places; the total stays within a rebuild's 2^15 + 16432.
      std::vector<std::uint16_t> counts(symbols, 1);
      const std::uint32_t wide = 1 + rng() % 4;
      for (std::uint32_t w = 0; w < wide; ++w) {
        counts[rng() % symbols] = static_cast<std::uint16_t>(1 + rng() % (30000 / wide));
      }
      if (round % 2 == 1) {  // a run of small, unequal counts
        for (std::uint32_t s = 0; s < symbols; ++s) {
          if (counts[s] == 1) counts[s] = static_cast<std::uint16_t>(1 + rng() % 3);
        }
      }
      SymbolModelProbe::set_counts(model, counts);
      marked += SymbolModelProbe::marked_slots(model);
      const std::string error = SymbolModelProbe::check(model);
      ASSERT_EQ(error, "") << "round " << round;
    }
  }
  EXPECT_GT(marked, 0u);  // the distributions did need search marks
}

}  // namespace
}  // namespace tinstream::laz::detail
