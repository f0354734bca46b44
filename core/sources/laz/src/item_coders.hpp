// The coders that pointwise and layered items share (GPS time sequences, RGB, wave packets),
// defined inline
// so that every item loop compiles them in (see TINSTREAM_LAZ_INLINE). Included only by the
// item sources.
#pragma once

#include "items.hpp"

namespace tinstream::laz::detail {

// GPSTIME11 multipliers: symbols below 500 scale the step up, 501..510 scale it by -1..-10.
inline constexpr std::uint32_t kGpsMultiMax = 500;
inline constexpr std::int32_t kGpsMultiMin = -10;

inline std::uint8_t fold_byte(std::int32_t v) { return static_cast<std::uint8_t>(v & 0xFF); }
inline std::int32_t clamp_byte(std::int32_t v) { return v <= 0 ? 0 : (v >= 255 ? 255 : v); }

// ---------------------------------------------------------------------------------------------
// GPS time sequences (GPSTIME11 v2, POINT14 v3/v4)

TINSTREAM_LAZ_INLINE void GpsTimeSequences::start_new_sequence(ArithmeticDecoder& dec) {
  // The high 32 bits are coded against the current sequence's, the low 32 bits raw.
  next_ = (next_ + 1) & 3;
  const auto high =
      static_cast<std::uint32_t>(ic_.decode(dec, static_cast<std::int32_t>(time_[last_] >> 32), 8));
  time_[next_] = (static_cast<std::uint64_t>(high) << 32) | dec.read_int();
  last_ = next_;
  step_[last_] = 0;
  extreme_[last_] = 0;
}

// Symbols 0 and 2..510 of the multi model: a step relative to the current one. Steps far off
// the prediction (multiplier 0, 500 or -10) replace the current step after four in a row.
TINSTREAM_LAZ_INLINE std::int32_t GpsTimeSequences::decode_scaled_step(ArithmeticDecoder& dec,
                                                                       std::uint32_t multi) {
  std::int32_t& step = step_[last_];
  std::int32_t diff;
  bool extreme = false;
  if (multi == 0) {
    diff = ic_.decode(dec, 0, 7);
    extreme = true;
  } else if (multi < kGpsMultiMax) {
    diff = ic_.decode(dec, wrap_mul(static_cast<std::int32_t>(multi), step), multi < 10 ? 2 : 3);
  } else if (multi == kGpsMultiMax) {
    diff = ic_.decode(dec, wrap_mul(static_cast<std::int32_t>(kGpsMultiMax), step), 4);
    extreme = true;
  } else {
    const std::int32_t factor = static_cast<std::int32_t>(kGpsMultiMax) - static_cast<int>(multi);
    if (factor > kGpsMultiMin) {
      diff = ic_.decode(dec, wrap_mul(factor, step), 5);
    } else {
      diff = ic_.decode(dec, wrap_mul(kGpsMultiMin, step), 6);
      extreme = true;
    }
  }
  if (extreme && ++extreme_[last_] > 3) {
    step = diff;
    extreme_[last_] = 0;
  }
  return diff;
}

TINSTREAM_LAZ_INLINE std::uint32_t GpsTimeSequences::first_symbol(ArithmeticDecoder& dec) {
  return dec.decode_symbol(step_[last_] == 0 ? zero_step_ : multi_);
}

TINSTREAM_LAZ_INLINE std::uint32_t GpsTimeSequences::step_class(ArithmeticDecoder& dec,
                                                                std::uint32_t sym) {
  if (step_[last_] == 0 || sym != 1) return kNoClass;
  return ic_.decode_class(dec, 1);
}

TINSTREAM_LAZ_INLINE std::uint64_t GpsTimeSequences::finish(ArithmeticDecoder& dec,
                                                            std::uint32_t sym, std::uint32_t k) {
  if (k != kNoClass) {  // multiplier 1: the step again, corrected
    const std::int32_t diff = ic_.decode_in_class(dec, step_[last_], k);
    time_[last_] += static_cast<std::uint64_t>(static_cast<std::int64_t>(diff));
    extreme_[last_] = 0;
    return time_[last_];
  }
  // A valid stream switches sequence at most once per point; the bound stops damaged ones.
  for (int hops = 0; hops < 8; ++hops) {
    if (hops > 0) sym = first_symbol(dec);
    if (step_[last_] == 0) {
      if (!layered_) {
        if (sym == 0) return time_[last_];  // unchanged
        --sym;
      }
      if (sym == 0) {  // a step that fits 32 bits
        step_[last_] = ic_.decode(dec, 0, 0);
        time_[last_] += static_cast<std::uint64_t>(static_cast<std::int64_t>(step_[last_]));
        extreme_[last_] = 0;
      } else if (sym == 1) {
        start_new_sequence(dec);
      } else {
        last_ = (last_ + sym - 1) & 3;
        continue;
      }
      return time_[last_];
    }
    const std::uint32_t multi = sym;
    if (multi == 1) {
      const std::int32_t diff = ic_.decode(dec, step_[last_], 1);
      time_[last_] += static_cast<std::uint64_t>(static_cast<std::int64_t>(diff));
      extreme_[last_] = 0;
    } else if (multi < 511) {
      const std::int32_t diff = decode_scaled_step(dec, multi);
      time_[last_] += static_cast<std::uint64_t>(static_cast<std::int64_t>(diff));
    } else if (multi == code_full_) {
      start_new_sequence(dec);
    } else if (multi > code_full_) {
      last_ = (last_ + multi - code_full_) & 3;
      continue;
    }
    // (v2's 511 = unchanged)
    return time_[last_];
  }
  dec.mark_corrupt();
  return time_[last_];
}

TINSTREAM_LAZ_INLINE std::uint64_t GpsTimeSequences::decode(ArithmeticDecoder& dec) {
  const std::uint32_t sym = first_symbol(dec);
  return finish(dec, sym, step_class(dec, sym));
}

// ---------------------------------------------------------------------------------------------
// RGB (RGB12 v2, RGB14 v3/v4)

TINSTREAM_LAZ_INLINE void decode_rgb(ArithmeticDecoder& dec, RgbModels& m,
                                     const std::uint16_t last[3], std::uint16_t out[3]) {
  const std::uint32_t sym = dec.decode_symbol(m.changed);
  auto low = [](std::uint16_t v) { return static_cast<std::int32_t>(v & 0xFF); };
  auto high = [](std::uint16_t v) { return static_cast<std::int32_t>(v >> 8); };
  // Bit i of sym: byte i changed (R low, R high, G low, G high, B low, B high); bit 6: the
  // channels differ (else green and blue copy red).
  std::int32_t r_low = low(last[0]), r_high = high(last[0]);
  if (sym & 1)
    r_low = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[0])) + r_low);
  if (sym & 2)
    r_high = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[1])) + r_high);
  out[0] = static_cast<std::uint16_t>(r_low | (r_high << 8));
  if (!(sym & 64)) {
    out[1] = out[2] = out[0];
    return;
  }
  // Green and blue of one byte half (h 0: low bytes, 1: high), each changed byte predicted from
  // red's change in that half (blue from the mean of red's and green's).
  auto green_blue = [&](std::uint32_t h, std::int32_t r_now, std::int32_t & g, std::int32_t & b)
      __attribute__((always_inline)) {
    auto part = [h](std::uint16_t v) { return static_cast<std::int32_t>((v >> (8 * h)) & 0xFF); };
    std::int32_t diff = r_now - part(last[0]);
    g = part(last[1]);
    b = part(last[2]);
    if (sym & (4u << h)) {
      g = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[2 + h])) +
                    clamp_byte(diff + part(last[1])));
    }
    if (sym & (16u << h)) {
      diff = (diff + g - part(last[1])) / 2;
      b = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[4 + h])) +
                    clamp_byte(diff + part(last[2])));
    }
  };
  std::int32_t g_low, b_low, g_high, b_high;
  green_blue(0, r_low, g_low, b_low);
  green_blue(1, r_high, g_high, b_high);
  out[1] = static_cast<std::uint16_t>(g_low | (g_high << 8));
  out[2] = static_cast<std::uint16_t>(b_low | (b_high << 8));
}

// ---------------------------------------------------------------------------------------------
// Wave packets (WAVEPACKET13 v1, WAVEPACKET14 v3/v4)

TINSTREAM_LAZ_INLINE void WavePacketCoder::decode(ArithmeticDecoder& dec, std::uint8_t* out29) {
  out29[0] = static_cast<std::uint8_t>(dec.decode_symbol(packet_index_));
  WavePacketFields prev, now;
  prev.load(last_.data() + 1);
  // The offset is: the same, right after the previous packet, a 32-bit step, or raw 64 bits.
  last_offset_case_ = dec.decode_symbol(offset_case_[last_offset_case_]);
  switch (last_offset_case_) {
    case 0:
      now.offset = prev.offset;
      break;
    case 1:
      now.offset = prev.offset + prev.size;
      break;
    case 2:
      last_diff_32_ = ic_offset_diff_.decode(dec, last_diff_32_, 0);
      now.offset =
          prev.offset + static_cast<std::uint64_t>(static_cast<std::int64_t>(last_diff_32_));
      break;
    default:
      now.offset = dec.read_int64();
      break;
  }
  now.size = static_cast<std::uint32_t>(
      ic_packet_size_.decode(dec, static_cast<std::int32_t>(prev.size), 0));
  now.return_point = static_cast<std::uint32_t>(
      ic_return_point_.decode(dec, static_cast<std::int32_t>(prev.return_point), 0));
  for (std::uint32_t i = 0; i < 3; ++i) {
    now.xyz[i] =
        static_cast<std::uint32_t>(ic_xyz_.decode(dec, static_cast<std::int32_t>(prev.xyz[i]), i));
  }
  now.store(out29 + 1);
  std::memcpy(last_.data(), out29, 29);
}

}  // namespace tinstream::laz::detail
