// Pointwise item decoders (LASzip item versions 1 and 2) and the pieces the layered ones share.
#include <algorithm>

#include "items.hpp"

namespace tinstream::laz::detail {

// ---------------------------------------------------------------------------------------------
// Shared pieces

void StreamingMedian5::push(std::int32_t v) {
  auto& s = s_;
  if (evict_high_) {
    if (v < s[2]) {
      s[4] = s[3];
      s[3] = s[2];
      if (v < s[0]) {
        s[2] = s[1];
        s[1] = s[0];
        s[0] = v;
      } else if (v < s[1]) {
        s[2] = s[1];
        s[1] = v;
      } else {
        s[2] = v;
      }
    } else {
      if (v < s[3]) {
        s[4] = s[3];
        s[3] = v;
      } else {
        s[4] = v;
      }
      evict_high_ = false;
    }
  } else {
    if (s[2] < v) {
      s[0] = s[1];
      s[1] = s[2];
      if (s[4] < v) {
        s[2] = s[3];
        s[3] = s[4];
        s[4] = v;
      } else if (s[3] < v) {
        s[2] = s[3];
        s[3] = v;
      } else {
        s[2] = v;
      }
    } else {
      if (s[1] < v) {
        s[0] = s[1];
        s[1] = v;
      } else {
        s[0] = v;
      }
      evict_high_ = true;
    }
  }
}

namespace {

// Valid (n, r) pairs get 0..14 in order (1/1, 1/2, 2/2, 1/3, ...); the rest are spread over the
// remaining values so that odd files (returns counted from 0, swapped fields) still get
// distinct contexts. Symmetric in n and r. A format constant.
constexpr std::uint8_t kReturnMap3Bit[8][8] = {
    {15, 14, 13, 12, 11, 10, 9, 8},  {14, 0, 1, 3, 6, 10, 10, 9},
    {13, 1, 2, 4, 7, 11, 11, 10},    {12, 3, 4, 5, 8, 12, 12, 11},
    {11, 6, 7, 8, 9, 13, 13, 12},    {10, 10, 11, 12, 13, 14, 14, 13},
    {9, 10, 11, 12, 13, 14, 15, 14}, {8, 9, 10, 11, 12, 13, 14, 15}};

// The 4-bit (LAS 1.4) return map reduced to six contexts. A format constant.
constexpr std::uint8_t kReturnMap6Ctx[16][16] = {{0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5},
                                                 {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
                                                 {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3},
                                                 {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                                 {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                                 {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                                 {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                                 {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
                                                 {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4},
                                                 {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
                                                 {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4},
                                                 {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
                                                 {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4},
                                                 {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
                                                 {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5},
                                                 {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5}};

// GPSTIME11 multipliers: symbols below 500 scale the step up, 501..510 scale it by -1..-10.
constexpr std::uint32_t kGpsMultiMax = 500;
constexpr std::int32_t kGpsMultiMin = -10;

std::uint8_t fold_byte(std::int32_t v) { return static_cast<std::uint8_t>(v & 0xFF); }
std::int32_t clamp_byte(std::int32_t v) { return v <= 0 ? 0 : (v >= 255 ? 255 : v); }

}  // namespace

std::uint8_t return_map_3bit(std::uint32_t n, std::uint32_t r) { return kReturnMap3Bit[n][r]; }
std::uint8_t return_map_6ctx(std::uint32_t n, std::uint32_t r) { return kReturnMap6Ctx[n][r]; }

// ---------------------------------------------------------------------------------------------
// GPS time sequences (GPSTIME11 v2, POINT14 v3/v4)

GpsTimeSequences::GpsTimeSequences(bool layered)
    : layered_(layered),
      code_full_(layered ? 511 : 512),
      multi_(layered ? 515 : 516),
      zero_step_(layered ? 5 : 6),
      ic_(32, 9) {}

void GpsTimeSequences::reset(std::uint64_t first_time_bits) {
  last_ = next_ = 0;
  time_ = {first_time_bits, 0, 0, 0};
  step_ = {};
  extreme_ = {};
  multi_.reset();
  zero_step_.reset();
  ic_.reset();
}

void GpsTimeSequences::start_new_sequence(ArithmeticDecoder& dec) {
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
std::int32_t GpsTimeSequences::decode_scaled_step(ArithmeticDecoder& dec, std::uint32_t multi) {
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

std::uint64_t GpsTimeSequences::decode(ArithmeticDecoder& dec) {
  // A valid stream switches sequence at most once per point; the bound stops damaged ones.
  for (int hops = 0; hops < 8; ++hops) {
    if (step_[last_] == 0) {
      std::uint32_t sym = dec.decode_symbol(zero_step_);
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
    const std::uint32_t multi = dec.decode_symbol(multi_);
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

// ---------------------------------------------------------------------------------------------
// RGB (RGB12 v2, RGB14 v3/v4)

RgbModels::RgbModels()
    : byte_diff{SymbolModel(256), SymbolModel(256), SymbolModel(256),
                SymbolModel(256), SymbolModel(256), SymbolModel(256)} {}

void RgbModels::reset() {
  changed.reset();
  for (auto& m : byte_diff) m.reset();
}

void decode_rgb(ArithmeticDecoder& dec, RgbModels& m, const std::uint16_t last[3],
                std::uint16_t out[3]) {
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
  std::int32_t diff = r_low - low(last[0]);
  std::int32_t g_low = low(last[1]), b_low = low(last[2]);
  if (sym & 4) {
    g_low = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[2])) +
                      clamp_byte(diff + low(last[1])));
  }
  if (sym & 16) {
    diff = (diff + g_low - low(last[1])) / 2;
    b_low = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[4])) +
                      clamp_byte(diff + low(last[2])));
  }
  diff = r_high - high(last[0]);
  std::int32_t g_high = high(last[1]), b_high = high(last[2]);
  if (sym & 8) {
    g_high = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[3])) +
                       clamp_byte(diff + high(last[1])));
  }
  if (sym & 32) {
    diff = (diff + g_high - high(last[1])) / 2;
    b_high = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(m.byte_diff[5])) +
                       clamp_byte(diff + high(last[2])));
  }
  out[1] = static_cast<std::uint16_t>(g_low | (g_high << 8));
  out[2] = static_cast<std::uint16_t>(b_low | (b_high << 8));
}

// ---------------------------------------------------------------------------------------------
// POINT10

void Point10Fields::load(const std::uint8_t* p) {
  x = static_cast<std::int32_t>(get32(p));
  y = static_cast<std::int32_t>(get32(p + 4));
  z = static_cast<std::int32_t>(get32(p + 8));
  intensity = get16(p + 12);
  returns = p[14];
  classification = p[15];
  scan_angle = p[16];
  user_data = p[17];
  source_id = get16(p + 18);
}

void Point10Fields::store(std::uint8_t* p) const {
  put32(p, static_cast<std::uint32_t>(x));
  put32(p + 4, static_cast<std::uint32_t>(y));
  put32(p + 8, static_cast<std::uint32_t>(z));
  put16(p + 12, intensity);
  p[14] = returns;
  p[15] = classification;
  p[16] = scan_angle;
  p[17] = user_data;
  put16(p + 18, source_id);
}

Point10V1::Point10V1()
    : ic_dx_(32, 1),
      ic_dy_(32, 20),
      ic_z_(32, 20),
      ic_intensity_(16, 1),
      ic_scan_angle_(8, 2),
      ic_source_id_(16, 1),
      changed_(64),
      returns_(256, 256),
      classification_(256, 256),
      user_data_(256, 256) {}

void Point10V1::start(const std::uint8_t* raw) {
  last_.load(raw);
  last_dx_ = {};
  last_dy_ = {};
  next_slot_ = 0;
  for (IntegerDecoder* ic :
       {&ic_dx_, &ic_dy_, &ic_z_, &ic_intensity_, &ic_scan_angle_, &ic_source_id_}) {
    ic->reset();
  }
  changed_.reset();
  returns_.next_chunk();
  classification_.next_chunk();
  user_data_.next_chunk();
}

namespace {
std::int32_t median3(const std::array<std::int32_t, 3>& v) {
  return std::max(std::min(v[0], v[1]), std::min(std::max(v[0], v[1]), v[2]));
}
}  // namespace

void Point10V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  const std::int32_t dx = ic_dx_.decode(dec, median3(last_dx_), 0);
  last_.x = wrap_add(last_.x, dx);
  std::uint32_t k = ic_dx_.last_k();
  const std::int32_t dy = ic_dy_.decode(dec, median3(last_dy_), std::min<std::uint32_t>(k, 19));
  last_.y = wrap_add(last_.y, dy);
  k = (k + ic_dy_.last_k()) / 2;
  last_.z = ic_z_.decode(dec, last_.z, std::min<std::uint32_t>(k, 19));

  const std::uint32_t changed = dec.decode_symbol(changed_);
  if (changed != 0) {
    if (changed & 32) {
      last_.intensity = static_cast<std::uint16_t>(ic_intensity_.decode(dec, last_.intensity, 0));
    }
    if (changed & 16) {
      last_.returns = static_cast<std::uint8_t>(dec.decode_symbol(returns_.at(last_.returns)));
    }
    if (changed & 8) {
      last_.classification =
          static_cast<std::uint8_t>(dec.decode_symbol(classification_.at(last_.classification)));
    }
    if (changed & 4) {
      last_.scan_angle =
          static_cast<std::uint8_t>(ic_scan_angle_.decode(dec, last_.scan_angle, k < 3 ? 1 : 0));
    }
    if (changed & 2) {
      last_.user_data =
          static_cast<std::uint8_t>(dec.decode_symbol(user_data_.at(last_.user_data)));
    }
    if (changed & 1) {
      last_.source_id = static_cast<std::uint16_t>(ic_source_id_.decode(dec, last_.source_id, 0));
    }
  }
  last_dx_[next_slot_] = dx;
  last_dy_[next_slot_] = dy;
  next_slot_ = next_slot_ == 2 ? 0 : next_slot_ + 1;
  last_.store(out);
}

Point10V2::Point10V2()
    : changed_(64),
      ic_intensity_(16, 4),
      scan_angle_{SymbolModel(256), SymbolModel(256)},
      ic_source_id_(16, 1),
      returns_(256, 256),
      classification_(256, 256),
      user_data_(256, 256),
      ic_dx_(32, 2),
      ic_dy_(32, 22),
      ic_z_(32, 20) {}

void Point10V2::start(const std::uint8_t* raw) {
  last_.load(raw);
  last_.intensity = 0;  // v2 starts intensity prediction from 0, not from the raw point
  last_intensity_ = {};
  last_height_ = {};
  for (auto& m : dx_median_) m.reset();
  for (auto& m : dy_median_) m.reset();
  changed_.reset();
  ic_intensity_.reset();
  scan_angle_[0].reset();
  scan_angle_[1].reset();
  ic_source_id_.reset();
  returns_.next_chunk();
  classification_.next_chunk();
  user_data_.next_chunk();
  ic_dx_.reset();
  ic_dy_.reset();
  ic_z_.reset();
}

void Point10V2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  const std::uint32_t changed = dec.decode_symbol(changed_);
  if (changed & 32) {
    last_.returns = static_cast<std::uint8_t>(dec.decode_symbol(returns_.at(last_.returns)));
  }
  const std::uint32_t r = last_.returns & 7u;
  const std::uint32_t n = (last_.returns >> 3) & 7u;
  const std::uint32_t m = return_map_3bit(n, r);
  const std::uint32_t l = return_level(n, r, 7);
  if (changed != 0) {
    if (changed & 16) {
      last_.intensity = static_cast<std::uint16_t>(
          ic_intensity_.decode(dec, last_intensity_[m], std::min<std::uint32_t>(m, 3)));
      last_intensity_[m] = last_.intensity;
    } else {
      last_.intensity = last_intensity_[m];
    }
    if (changed & 8) {
      last_.classification =
          static_cast<std::uint8_t>(dec.decode_symbol(classification_.at(last_.classification)));
    }
    if (changed & 4) {
      const std::uint32_t scan_direction = (last_.returns >> 6) & 1u;
      const auto d = static_cast<std::int32_t>(dec.decode_symbol(scan_angle_[scan_direction]));
      last_.scan_angle = fold_byte(d + last_.scan_angle);
    }
    if (changed & 2) {
      last_.user_data =
          static_cast<std::uint8_t>(dec.decode_symbol(user_data_.at(last_.user_data)));
    }
    if (changed & 1) {
      last_.source_id = static_cast<std::uint16_t>(ic_source_id_.decode(dec, last_.source_id, 0));
    }
  }
  const std::uint32_t single = n == 1 ? 1 : 0;
  std::int32_t diff = ic_dx_.decode(dec, dx_median_[m].get(), single);
  last_.x = wrap_add(last_.x, diff);
  dx_median_[m].push(diff);
  std::uint32_t k = ic_dx_.last_k();
  diff = ic_dy_.decode(dec, dy_median_[m].get(), single + (k < 20 ? k & ~1u : 20));
  last_.y = wrap_add(last_.y, diff);
  dy_median_[m].push(diff);
  k = (ic_dx_.last_k() + ic_dy_.last_k()) / 2;
  last_.z = ic_z_.decode(dec, last_height_[l], single + (k < 18 ? k & ~1u : 18));
  last_height_[l] = last_.z;
  last_.store(out);
}

// ---------------------------------------------------------------------------------------------
// GPSTIME11 v1

GpsTime11V1::GpsTime11V1() : multi_(512), zero_step_(3), ic_(32, 6) {}

void GpsTime11V1::start(const std::uint8_t* raw) {
  last_ = get64(raw);
  last_step_ = 0;
  extreme_ = 0;
  multi_.reset();
  zero_step_.reset();
  ic_.reset();
}

void GpsTime11V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  auto add = [this](std::int32_t d) {
    last_ += static_cast<std::uint64_t>(static_cast<std::int64_t>(d));
  };
  if (last_step_ == 0) {
    const std::uint32_t sym = dec.decode_symbol(zero_step_);
    if (sym == 1) {
      last_step_ = ic_.decode(dec, 0, 0);
      add(last_step_);
    } else if (sym == 2) {
      last_ = dec.read_int64();
    }
  } else {
    const std::uint32_t multi = dec.decode_symbol(multi_);
    if (multi < 510) {
      std::int32_t diff;
      if (multi == 1) {
        diff = ic_.decode(dec, last_step_, 1);
        last_step_ = diff;
        extreme_ = 0;
      } else if (multi == 0) {
        diff = ic_.decode(dec, last_step_ / 4, 2);
        if (++extreme_ > 3) {
          last_step_ = diff;
          extreme_ = 0;
        }
      } else {
        const std::int32_t predicted = wrap_mul(static_cast<std::int32_t>(multi), last_step_);
        diff = ic_.decode(dec, predicted, multi < 10 ? 3 : (multi < 50 ? 4 : 5));
        if (multi == 509 && ++extreme_ > 3) {
          last_step_ = diff;
          extreme_ = 0;
        }
      }
      add(diff);
    } else if (multi == 510) {
      last_ = dec.read_int64();
    }
  }
  put64(out, last_);
}

// ---------------------------------------------------------------------------------------------
// RGB12

Rgb12V1::Rgb12V1() : changed_(64), ic_(8, 6) {}

void Rgb12V1::start(const std::uint8_t* raw) {
  std::memcpy(last_.data(), raw, 6);
  changed_.reset();
  ic_.reset();
}

void Rgb12V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  const std::uint32_t sym = dec.decode_symbol(changed_);
  for (std::uint32_t i = 0; i < 6; ++i) {
    if (sym & (1u << i)) last_[i] = static_cast<std::uint8_t>(ic_.decode(dec, last_[i], i));
  }
  std::memcpy(out, last_.data(), 6);
}

void Rgb12V2::start(const std::uint8_t* raw) {
  for (int i = 0; i < 3; ++i) last_[i] = get16(raw + 2 * i);
  models_.reset();
}

void Rgb12V2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  std::uint16_t now[3];
  decode_rgb(dec, models_, last_, now);
  for (int i = 0; i < 3; ++i) {
    last_[i] = now[i];
    put16(out + 2 * i, now[i]);
  }
}

// ---------------------------------------------------------------------------------------------
// BYTE

ByteV1::ByteV1(std::size_t count) : last_(count), ic_(8, static_cast<std::uint32_t>(count)) {}

void ByteV1::start(const std::uint8_t* raw) {
  std::memcpy(last_.data(), raw, last_.size());
  ic_.reset();
}

void ByteV1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  for (std::size_t i = 0; i < last_.size(); ++i) {
    last_[i] = static_cast<std::uint8_t>(ic_.decode(dec, last_[i], static_cast<std::uint32_t>(i)));
  }
  std::memcpy(out, last_.data(), last_.size());
}

ByteV2::ByteV2(std::size_t count) : last_(count) {
  diff_.reserve(count);
  for (std::size_t i = 0; i < count; ++i) diff_.emplace_back(256);
}

void ByteV2::start(const std::uint8_t* raw) {
  std::memcpy(last_.data(), raw, last_.size());
  for (auto& m : diff_) m.reset();
}

void ByteV2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  for (std::size_t i = 0; i < last_.size(); ++i) {
    last_[i] = fold_byte(static_cast<std::int32_t>(dec.decode_symbol(diff_[i])) + last_[i]);
  }
  std::memcpy(out, last_.data(), last_.size());
}

// ---------------------------------------------------------------------------------------------
// Wave packets

void WavePacketFields::load(const std::uint8_t* p) {
  offset = get64(p);
  size = get32(p + 8);
  return_point = get32(p + 12);
  for (int i = 0; i < 3; ++i) xyz[static_cast<std::size_t>(i)] = get32(p + 16 + 4 * i);
}

void WavePacketFields::store(std::uint8_t* p) const {
  put64(p, offset);
  put32(p + 8, size);
  put32(p + 12, return_point);
  for (int i = 0; i < 3; ++i) put32(p + 16 + 4 * i, xyz[static_cast<std::size_t>(i)]);
}

WavePacketCoder::WavePacketCoder()
    : packet_index_(256),
      offset_case_{SymbolModel(4), SymbolModel(4), SymbolModel(4), SymbolModel(4)},
      ic_offset_diff_(32, 1),
      ic_packet_size_(32, 1),
      ic_return_point_(32, 1),
      ic_xyz_(32, 3) {}

void WavePacketCoder::reset(const std::uint8_t* raw29) {
  std::memcpy(last_.data(), raw29, 29);
  last_diff_32_ = 0;
  last_offset_case_ = 0;
  packet_index_.reset();
  for (auto& m : offset_case_) m.reset();
  ic_offset_diff_.reset();
  ic_packet_size_.reset();
  ic_return_point_.reset();
  ic_xyz_.reset();
}

void WavePacketCoder::decode(ArithmeticDecoder& dec, std::uint8_t* out29) {
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
