// tile::compress_runs — a zlib (RFC 1950/1951) stream made without string matching.
//
// Why: the planes of a version-2 tile blob are either near-constant (long runs of one byte) or
// skewed byte distributions without repeated strings, or plain noise. General deflate spends most
// of its time searching for matches that are not there; this encoder only looks for runs of the
// previous byte (distance 1) and Huffman-codes each block on its own statistics, or stores it
// when that would not be smaller. Any inflater reads the result (tile::decompress, zlib).
//
// Per block of kBlockSize input bytes (the last one may be shorter):
//   symbols    literal bytes, and (length 3…258, distance 1) for repeats of the previous byte
//   dynamic    Huffman block (BTYPE 2): literal/length code from the symbol counts (≤ 15 bits),
//              distance code {0, 1} of 1 bit each (complete; only distance 1 is used), code
//              lengths sent with the code-length alphabet including its run symbols 16/17/18
//   stored     BTYPE 0, chosen when its exact size is not larger than the dynamic block's
#include <libdeflate.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cstdint>
#include <cstring>
#include <vector>

#include "tinstream/tile/codec.hpp"

namespace tinstream::tile {

namespace {

constexpr std::size_t kBlockSize = std::size_t{1} << 14;
constexpr std::size_t kLitLenSymbols = 286;  // 0–255 literals, 256 end of block, 257–285 lengths
constexpr unsigned kEndOfBlock = 256;
constexpr std::size_t kCodeLengthSymbols = 19;
constexpr std::array<std::uint8_t, kCodeLengthSymbols> kCodeLengthOrder{
    16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};

// Length symbol (257 + slot), extra bits and their value for every match length 3…258.
struct LengthCode {
  std::uint16_t symbol = 0;
  std::uint8_t extra_bits = 0;
  std::uint16_t extra = 0;
};
constexpr std::array<std::uint16_t, 29> kLengthBase{3,  4,  5,  6,   7,   8,   9,   10,  11, 13,
                                                    15, 17, 19, 23,  27,  31,  35,  43,  51, 59,
                                                    67, 83, 99, 115, 131, 163, 195, 227, 258};
constexpr std::array<std::uint8_t, 29> kLengthExtra{0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                                    2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
constexpr std::array<LengthCode, 259> make_length_codes() {
  std::array<LengthCode, 259> table{};
  for (std::size_t slot = 0; slot < kLengthBase.size(); ++slot) {
    const unsigned base = kLengthBase[slot];
    for (unsigned extra = 0; extra < (1u << kLengthExtra[slot]) && base + extra <= 258; ++extra) {
      table[base + extra] = {static_cast<std::uint16_t>(257 + slot), kLengthExtra[slot],
                             static_cast<std::uint16_t>(extra)};
    }
  }
  table[258] = {285, 0, 0};  // 258 has its own symbol (284 + 31 extra is not valid)
  return table;
}
constexpr std::array<LengthCode, 259> kLengthCodes = make_length_codes();

// LSB-first bit output into a buffer sized in advance (see compress_runs's bound).
class BitWriter {
 public:
  explicit BitWriter(std::uint8_t* out) : out_(out) {}
  // Requires: count ≤ 32.
  void put(std::uint32_t bits, unsigned count) {
    buffer_ |= std::uint64_t{bits} << filled_;
    filled_ += count;
    if (filled_ >= 32) {
      for (int i = 0; i < 4; ++i) *out_++ = static_cast<std::uint8_t>(buffer_ >> (8 * i));
      buffer_ >>= 32;
      filled_ -= 32;
    }
  }
  // The fast path of the symbol loops: add() only appends to the 64-bit buffer (the caller keeps
  // pending_bits() + count ≤ 64), flush() then writes out its whole bytes without a branch,
  // leaving at most 7 bits pending. flush() stores 8 bytes: the output needs 8 bytes of room
  // past the last byte written.
  void add(std::uint32_t bits, unsigned count) {
    buffer_ |= std::uint64_t{bits} << filled_;
    filled_ += count;
  }
  void flush() {
    if constexpr (std::endian::native == std::endian::little) {
      std::memcpy(out_, &buffer_, 8);
    } else {
      for (int i = 0; i < 8; ++i) out_[i] = static_cast<std::uint8_t>(buffer_ >> (8 * i));
    }
    out_ += filled_ >> 3;
    buffer_ >>= filled_ & ~7u;  // < 64: flush() is called with at most 63 bits pending
    filled_ &= 7u;
  }
  // Pads with zero bits to a byte boundary and writes out everything pending.
  void align() {
    while (filled_ > 0) {
      *out_++ = static_cast<std::uint8_t>(buffer_);
      buffer_ >>= 8;
      filled_ = filled_ > 8 ? filled_ - 8 : 0;
    }
    buffer_ = 0;
  }
  void bytes(const std::uint8_t* p, std::size_t n) {
    assert(filled_ == 0);
    if (n == 0) return;  // p may be null (an empty input's data()): memcpy(…, null, 0) is UB
    std::memcpy(out_, p, n);
    out_ += n;
  }
  std::uint8_t* position() const { return out_; }
  unsigned pending_bits() const { return filled_; }

 private:
  std::uint8_t* out_;
  std::uint64_t buffer_ = 0;
  unsigned filled_ = 0;
};

// Huffman code lengths (≤ limit) for `freq`; every symbol with a count gets a code, and at least
// two symbols do (a one-symbol code would be incomplete), so the code is always complete.
template <std::size_t N>
void huffman_lengths(std::array<std::uint32_t, N> freq, unsigned limit,
                     std::array<std::uint8_t, N>& lengths) {
  std::size_t used = 0;
  for (const auto f : freq) used += f > 0 ? 1 : 0;
  for (std::size_t s = 0; used < 2; ++s) {
    if (freq[s] == 0) {
      freq[s] = 1;
      ++used;
    }
  }
  for (;;) {
    // Two-queue Huffman: leaves sorted by count, internal nodes made in non-decreasing order.
    // Sort keys: count in the high bits, symbol in the low 16 (ties by symbol).
    std::array<std::uint64_t, N> keys;
    std::size_t n = 0;
    for (std::size_t s = 0; s < N; ++s) {
      if (freq[s] > 0) keys[n++] = std::uint64_t{freq[s]} << 16 | s;
    }
    std::sort(keys.begin(), keys.begin() + static_cast<std::ptrdiff_t>(n));
    std::array<std::uint16_t, N> leaves;
    for (std::size_t k = 0; k < n; ++k) leaves[k] = static_cast<std::uint16_t>(keys[k] & 0xFFFFu);
    // Nodes 0 … n−1 are the leaves in sorted order, n … 2n−2 the internal nodes.
    std::array<std::uint64_t, 2 * N> weight;
    std::array<std::uint16_t, 2 * N> parent;
    for (std::size_t i = 0; i < n; ++i) weight[i] = freq[leaves[i]];
    std::size_t next_leaf = 0, next_internal = n, made = n;
    const auto take = [&]() -> std::size_t {
      if (next_leaf < n && (next_internal == made || weight[next_leaf] <= weight[next_internal])) {
        return next_leaf++;
      }
      return next_internal++;
    };
    while (made < 2 * n - 1) {
      const std::size_t a = take(), b = take();
      weight[made] = weight[a] + weight[b];
      parent[a] = parent[b] = static_cast<std::uint16_t>(made);
      ++made;
    }
    // Depths from the root (the last node) down: a parent is always made after its children.
    std::array<std::uint16_t, 2 * N> depth;
    depth[made - 1] = 0;
    unsigned deepest = 0;
    for (std::size_t i = made - 1; i-- > 0;) {
      depth[i] = static_cast<std::uint16_t>(depth[parent[i]] + 1);
      deepest = std::max<unsigned>(deepest, depth[i]);
    }
    if (deepest <= limit) {
      lengths.fill(0);
      for (std::size_t i = 0; i < n; ++i) lengths[leaves[i]] = static_cast<std::uint8_t>(depth[i]);
      return;
    }
    // Too deep: flatten the counts (every used symbol keeps a count ≥ 1) and build again.
    for (auto& f : freq) {
      if (f > 0) f = std::max<std::uint32_t>(1, f >> 1);
    }
  }
}

// Canonical codes (RFC 1951 §3.2.2), bit-reversed for LSB-first output.
template <std::size_t N>
std::array<std::uint16_t, N> canonical_codes(const std::array<std::uint8_t, N>& lengths) {
  std::array<std::uint16_t, 16> count{}, next{};
  for (const auto l : lengths) ++count[l];
  count[0] = 0;
  std::uint32_t code = 0;
  for (std::size_t bits = 1; bits < 16; ++bits) {
    code = (code + count[bits - 1]) << 1;
    next[bits] = static_cast<std::uint16_t>(code);
  }
  std::array<std::uint16_t, N> codes{};
  for (std::size_t s = 0; s < N; ++s) {
    const unsigned len = lengths[s];
    if (len == 0) continue;
    std::uint32_t c = next[len]++, reversed = 0;
    for (unsigned i = 0; i < len; ++i) {
      reversed = (reversed << 1) | (c & 1u);
      c >>= 1;
    }
    codes[s] = static_cast<std::uint16_t>(reversed);
  }
  return codes;
}

// One symbol of the code-length alphabet with its extra bits.
struct LengthToken {
  std::uint8_t symbol, extra_bits, extra;
};

// The code lengths of both alphabets as code-length symbols (runs as 16/17/18).
std::vector<LengthToken> length_tokens(const std::uint8_t* lengths, std::size_t n) {
  std::vector<LengthToken> out;
  for (std::size_t i = 0; i < n;) {
    const std::uint8_t value = lengths[i];
    std::size_t run = 1;
    while (i + run < n && lengths[i + run] == value) ++run;
    i += run;
    if (value == 0) {
      while (run >= 11) {
        const std::size_t r = std::min<std::size_t>(run, 138);
        out.push_back({18, 7, static_cast<std::uint8_t>(r - 11)});
        run -= r;
      }
      if (run >= 3) {
        out.push_back({17, 3, static_cast<std::uint8_t>(run - 3)});
        run = 0;
      }
    } else {
      out.push_back({value, 0, 0});
      --run;
      while (run >= 3) {
        const std::size_t r = std::min<std::size_t>(run, 6);
        out.push_back({16, 2, static_cast<std::uint8_t>(r - 3)});
        run -= r;
      }
    }
    for (; run > 0; --run) out.push_back({value, 0, 0});
  }
  return out;
}

// The length of the run of `byte` at p, knowing that p[0 … known) are `byte`, up to `limit`.
// Eight bytes at a time: runs fill whole planes of version-2 blobs.
std::size_t run_length(const std::uint8_t* p, std::size_t known, std::size_t limit,
                       std::uint8_t byte) {
  std::size_t run = known;
  if constexpr (std::endian::native == std::endian::little) {
    const std::uint64_t pattern = 0x0101010101010101u * byte;
    while (run + 8 <= limit) {
      std::uint64_t word;
      std::memcpy(&word, p + run, 8);
      if (const std::uint64_t diff = word ^ pattern; diff != 0) {
        return run + static_cast<std::size_t>(std::countr_zero(diff)) / 8;  // first other byte
      }
      run += 8;
    }
  }
  while (run < limit && p[run] == byte) ++run;
  return run;
}

// A match of the block: `length` (3…258) repeats of the byte before `position`.
struct Run {
  std::size_t position;
  std::size_t length;
};

// Writes in[begin, end) as one block (dynamic or stored, whichever is smaller).
void write_block(BitWriter& w, std::span<const std::uint8_t> in, std::size_t begin, std::size_t end,
                 bool final, std::vector<Run>& runs) {
  // Every byte is a literal except those covered by `runs` (in order).
  runs.clear();
  std::array<std::uint32_t, kLitLenSymbols> freq{};
  std::size_t i = begin;
  if (i == 0 && i < end) {  // the stream's first byte has no previous byte
    ++freq[in[0]];
    ++i;
  }
  const std::uint8_t* const data = in.data();
  // Literals are counted into two tables by position parity (summed below), so that a byte
  // repeated every other position does not wait on its own counter's previous increment.
  std::array<std::uint32_t, 256> odd{};
  while (i < end) {
    if constexpr (std::endian::native == std::endian::little) {
      // Eight bytes none of which repeats the byte before it start no run: all literals.
      if (i + 8 <= end) {
        std::uint64_t word, before;
        std::memcpy(&word, data + i, 8);
        std::memcpy(&before, data + i - 1, 8);
        const std::uint64_t x = word ^ before;
        if (((x - 0x0101010101010101u) & ~x & 0x8080808080808080u) == 0) {  // no zero byte
          for (int k = 0; k < 8; k += 2) {
            ++freq[static_cast<std::uint8_t>(word >> (8 * k))];
            ++odd[static_cast<std::uint8_t>(word >> (8 * k + 8))];
          }
          i += 8;
          continue;
        }
      }
    }
    const std::uint8_t byte = data[i];
    if (byte != data[i - 1] || i + 2 >= end || data[i + 1] != byte || data[i + 2] != byte) {
      ++freq[byte];
      ++i;
      continue;
    }
    // At least three repeats of the previous byte: one match of up to 258.
    const std::size_t limit = std::min<std::size_t>(258, end - i);
    const std::size_t run = run_length(data + i, 3, limit, byte);
    runs.push_back({i, run});
    ++freq[kLengthCodes[run].symbol];
    i += run;
  }
  for (std::size_t b = 0; b < 256; ++b) freq[b] += odd[b];
  freq[kEndOfBlock] = 1;

  std::array<std::uint8_t, kLitLenSymbols> lit_lengths{};
  huffman_lengths(freq, 15, lit_lengths);
  std::size_t hlit = kLitLenSymbols;
  while (hlit > 257 && lit_lengths[hlit - 1] == 0) --hlit;
  constexpr std::size_t hdist = 2;
  std::array<std::uint8_t, kLitLenSymbols + hdist> all_lengths{};
  std::copy_n(lit_lengths.begin(), hlit, all_lengths.begin());
  all_lengths[hlit] = all_lengths[hlit + 1] = 1;  // distance codes 0 and 1, one bit each
  const std::vector<LengthToken> header = length_tokens(all_lengths.data(), hlit + hdist);
  std::array<std::uint32_t, kCodeLengthSymbols> cl_freq{};
  for (const auto& t : header) ++cl_freq[t.symbol];
  std::array<std::uint8_t, kCodeLengthSymbols> cl_lengths{};
  huffman_lengths(cl_freq, 7, cl_lengths);
  std::size_t hclen = kCodeLengthSymbols;
  while (hclen > 4 && cl_lengths[kCodeLengthOrder[hclen - 1]] == 0) --hclen;

  // Exact sizes of both choices, in bits.
  std::uint64_t dynamic_bits = 3 + 5 + 5 + 4 + 3 * hclen;
  for (const auto& t : header) dynamic_bits += cl_lengths[t.symbol] + t.extra_bits;
  for (std::size_t s = 0; s < kLitLenSymbols; ++s) {
    dynamic_bits += std::uint64_t{freq[s]} * lit_lengths[s];
    if (s >= 257) dynamic_bits += std::uint64_t{freq[s]} * (kLengthExtra[s - 257] + 1);
  }
  const std::uint64_t pad = (8 - (w.pending_bits() + 3) % 8) % 8;
  const std::uint64_t stored_bits = 3 + pad + 32 + 8 * std::uint64_t{end - begin};

  if (stored_bits <= dynamic_bits) {
    w.put(final ? 1u : 0u, 3);  // BFINAL, BTYPE 00
    w.align();
    const auto len = static_cast<std::uint32_t>(end - begin);
    w.put(len | ((~len & 0xFFFFu) << 16), 32);
    w.bytes(in.data() + begin, end - begin);
    return;
  }
  const auto lit_codes = canonical_codes(lit_lengths);
  const auto cl_codes = canonical_codes(cl_lengths);
  // Code and length of each literal/length symbol in one word: code | length << 16.
  std::array<std::uint32_t, kLitLenSymbols> lit_words{};
  for (std::size_t k = 0; k < kLitLenSymbols; ++k) {
    lit_words[k] = lit_codes[k] | std::uint32_t{lit_lengths[k]} << 16;
  }
  w.put((final ? 1u : 0u) | (2u << 1), 3);  // BFINAL, BTYPE 10
  w.put(static_cast<std::uint32_t>(hlit - 257), 5);
  w.put(static_cast<std::uint32_t>(hdist - 1), 5);
  w.put(static_cast<std::uint32_t>(hclen - 4), 4);
  for (std::size_t k = 0; k < hclen; ++k) w.put(cl_lengths[kCodeLengthOrder[k]], 3);
  for (const auto& t : header) {
    w.put(cl_codes[t.symbol], cl_lengths[t.symbol]);
    if (t.extra_bits > 0) w.put(t.extra, t.extra_bits);
  }
  // A local copy of the writer: its state stays in registers (stores through the output pointer
  // could alias `w`).
  BitWriter out = w;
  // Three literals (≤ 45 bits) after each flush (≤ 7 bits left pending).
  const auto literals = [&](std::size_t from, std::size_t to) {
    std::size_t k = from;
    for (; k + 3 <= to; k += 3) {
      out.flush();
      for (std::size_t m = 0; m < 3; ++m) {
        const std::uint32_t word = lit_words[data[k + m]];
        out.add(word & 0xFFFFu, word >> 16);
      }
    }
    for (; k < to; ++k) {
      out.flush();
      const std::uint32_t word = lit_words[data[k]];
      out.add(word & 0xFFFFu, word >> 16);
    }
  };
  std::size_t next = begin;
  for (const Run& r : runs) {
    literals(next, r.position);
    // Length symbol, its extra bits, then distance code 0 (distance 1) of the 1-bit code:
    // 15 + 5 + 1 bits at most, one put.
    const LengthCode& lc = kLengthCodes[r.length];
    const std::uint32_t word = lit_words[lc.symbol];
    const unsigned len = word >> 16;
    out.flush();
    out.add((word & 0xFFFFu) | std::uint32_t{lc.extra} << len, len + lc.extra_bits + 1u);
    next = r.position + r.length;
  }
  literals(next, end);
  out.flush();
  w = out;
  w.put(lit_codes[kEndOfBlock], lit_lengths[kEndOfBlock]);
}

}  // namespace

std::vector<std::uint8_t> compress_runs(std::span<const std::uint8_t> bytes) {
  const std::size_t blocks = std::max<std::size_t>(1, (bytes.size() + kBlockSize - 1) / kBlockSize);
  // No block is larger than it would be stored (≤ 3 + 7 bits of header and padding, 4 bytes of
  // LEN/NLEN, the data): ≤ 6 bytes per block over the input, plus 2 of zlib header, 4 of Adler-32
  // and one for the last partial byte.
  // (+ 8: BitWriter::flush stores 8 bytes at a time)
  std::vector<std::uint8_t> out(2 + bytes.size() + 6 * blocks + 4 + 1 + 8);
  out[0] = 0x78;  // CMF: deflate, 32 KiB window
  out[1] = 0x01;  // FLG: fastest compression, no dictionary; (0x78 · 256 + 0x01) % 31 == 0
  BitWriter w(out.data() + 2);
  std::vector<Run> runs;
  runs.reserve(kBlockSize / 3 + 1);
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t begin = b * kBlockSize;
    const std::size_t end = std::min(bytes.size(), begin + kBlockSize);
    write_block(w, bytes, begin, end, b + 1 == blocks, runs);
  }
  w.align();
  std::uint8_t* p = w.position();
  const std::uint32_t adler = libdeflate_adler32(1, bytes.data(), bytes.size());
  for (int i = 3; i >= 0; --i) *p++ = static_cast<std::uint8_t>(adler >> (8 * i));
  out.resize(static_cast<std::size_t>(p - out.data()));
  return out;
}

}  // namespace tinstream::tile
