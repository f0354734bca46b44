// Pointwise item decoders (LASzip item versions 1 and 2) and the pieces the layered ones share.
#include <algorithm>
#include <tuple>
#include <utility>

#include "item_coders.hpp"
#include "items.hpp"

namespace tinstream::laz::detail {

// ---------------------------------------------------------------------------------------------
// Shared pieces

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

// ---------------------------------------------------------------------------------------------
// RGB (RGB12 v2, RGB14 v3/v4)

RgbModels::RgbModels()
    : byte_diff{SymbolModel(256), SymbolModel(256), SymbolModel(256),
                SymbolModel(256), SymbolModel(256), SymbolModel(256)} {}

void RgbModels::reset() {
  changed.reset();
  for (auto& m : byte_diff) m.reset();
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

TINSTREAM_LAZ_INLINE void Point10V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
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

TINSTREAM_LAZ_INLINE void Point10V2::changed_fields(ArithmeticDecoder& dec, Steps& s) {
  s.changed = dec.decode_symbol(changed_);
}

TINSTREAM_LAZ_INLINE void Point10V2::returns(ArithmeticDecoder& dec, Steps& s) {
  if (s.changed & 32) {
    last_.returns = static_cast<std::uint8_t>(dec.decode_symbol(returns_.at(last_.returns)));
  }
  const std::uint32_t r = last_.returns & 7u;
  const std::uint32_t n = (last_.returns >> 3) & 7u;
  s.m = return_map_3bit(n, r);
  s.l = return_level(n, r, 7);
  s.single = n == 1 ? 1 : 0;
}

TINSTREAM_LAZ_INLINE void Point10V2::intensity_class(ArithmeticDecoder& dec, Steps& s) {
  if (s.changed & 16) s.k = ic_intensity_.decode_class(dec, std::min<std::uint32_t>(s.m, 3));
}

TINSTREAM_LAZ_INLINE void Point10V2::intensity(ArithmeticDecoder& dec, const Steps& s) {
  if (s.changed & 16) {
    last_.intensity =
        static_cast<std::uint16_t>(ic_intensity_.decode_in_class(dec, last_intensity_[s.m], s.k));
    last_intensity_[s.m] = last_.intensity;
  } else if (s.changed != 0) {
    last_.intensity = last_intensity_[s.m];
  }
}

TINSTREAM_LAZ_INLINE void Point10V2::other_fields(ArithmeticDecoder& dec, const Steps& s) {
  if ((s.changed & 15) == 0) return;
  if (s.changed & 8) {
    last_.classification =
        static_cast<std::uint8_t>(dec.decode_symbol(classification_.at(last_.classification)));
  }
  if (s.changed & 4) {
    const std::uint32_t scan_direction = (last_.returns >> 6) & 1u;
    const auto d = static_cast<std::int32_t>(dec.decode_symbol(scan_angle_[scan_direction]));
    last_.scan_angle = fold_byte(d + last_.scan_angle);
  }
  if (s.changed & 2) {
    last_.user_data = static_cast<std::uint8_t>(dec.decode_symbol(user_data_.at(last_.user_data)));
  }
  if (s.changed & 1) {
    last_.source_id = static_cast<std::uint16_t>(ic_source_id_.decode(dec, last_.source_id, 0));
  }
}

TINSTREAM_LAZ_INLINE void Point10V2::x_class(ArithmeticDecoder& dec, Steps& s) {
  s.k = ic_dx_.decode_class(dec, s.single);
}

TINSTREAM_LAZ_INLINE void Point10V2::x(ArithmeticDecoder& dec, const Steps& s) {
  const std::int32_t diff = ic_dx_.decode_in_class(dec, dx_median_[s.m].get(), s.k);
  last_.x = wrap_add(last_.x, diff);
  dx_median_[s.m].push(diff);
}

TINSTREAM_LAZ_INLINE void Point10V2::y_class(ArithmeticDecoder& dec, Steps& s) {
  const std::uint32_t k = ic_dx_.last_k();
  s.k = ic_dy_.decode_class(dec, s.single + (k < 20 ? k & ~1u : 20));
}

TINSTREAM_LAZ_INLINE void Point10V2::y(ArithmeticDecoder& dec, const Steps& s) {
  const std::int32_t diff = ic_dy_.decode_in_class(dec, dy_median_[s.m].get(), s.k);
  last_.y = wrap_add(last_.y, diff);
  dy_median_[s.m].push(diff);
}

TINSTREAM_LAZ_INLINE void Point10V2::z_class(ArithmeticDecoder& dec, Steps& s) {
  const std::uint32_t k = (ic_dx_.last_k() + ic_dy_.last_k()) / 2;
  s.k = ic_z_.decode_class(dec, s.single + (k < 18 ? k & ~1u : 18));
}

TINSTREAM_LAZ_INLINE void Point10V2::z(ArithmeticDecoder& dec, const Steps& s) {
  last_.z = ic_z_.decode_in_class(dec, last_height_[s.l], s.k);
  last_height_[s.l] = last_.z;
}

TINSTREAM_LAZ_INLINE void Point10V2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  Steps s;
  changed_fields(dec, s);
  returns(dec, s);
  intensity_class(dec, s);
  intensity(dec, s);
  other_fields(dec, s);
  x_class(dec, s);
  x(dec, s);
  y_class(dec, s);
  y(dec, s);
  z_class(dec, s);
  z(dec, s);
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

TINSTREAM_LAZ_INLINE void GpsTime11V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
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

// GPSTIME11 v2: the sequence coder (item_coders.hpp).
TINSTREAM_LAZ_INLINE void GpsTime11V2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  put64(out, seq_.decode(dec));
}

// ---------------------------------------------------------------------------------------------
// RGB12

Rgb12V1::Rgb12V1() : changed_(64), ic_(8, 6) {}

void Rgb12V1::start(const std::uint8_t* raw) {
  std::memcpy(last_.data(), raw, 6);
  changed_.reset();
  ic_.reset();
}

TINSTREAM_LAZ_INLINE void Rgb12V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  const std::uint32_t sym = dec.decode_symbol(changed_);
  for (std::uint32_t i = 0; i < 6; ++i) {
    if (sym & (1u << i)) last_[i] = static_cast<std::uint8_t>(ic_.decode(dec, last_[i], i));
  }
  std::memcpy(out, last_.data(), 6);
}

void Rgb12V2::start(const std::uint8_t* raw) {
  for (std::size_t i = 0; i < 3; ++i) last_[i] = get16(raw + 2 * i);
  models_.reset();
}

TINSTREAM_LAZ_INLINE void Rgb12V2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  std::uint16_t now[3];
  decode_rgb(dec, models_, last_, now);
  for (std::size_t i = 0; i < 3; ++i) {
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

TINSTREAM_LAZ_INLINE void ByteV1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
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

TINSTREAM_LAZ_INLINE void ByteV2::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
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
  for (std::size_t i = 0; i < 3; ++i) xyz[i] = get32(p + 16 + 4 * i);
}

void WavePacketFields::store(std::uint8_t* p) const {
  put64(p, offset);
  put32(p + 8, size);
  put32(p + 12, return_point);
  for (std::size_t i = 0; i < 3; ++i) put32(p + 16 + 4 * i, xyz[i]);
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

TINSTREAM_LAZ_INLINE void WavePacket13V1::decode(ArithmeticDecoder& dec, std::uint8_t* out) {
  coder_.decode(dec, out);
}

// ---------------------------------------------------------------------------------------------
// The record loop

namespace {

// One loop per item list: every decode inlines, and the decoder's interval and cursor live in
// registers for the whole loop (it is a local copy; nothing takes its address).
template <typename... Items, std::size_t... I>
void decode_fixed(std::span<PointwiseItem> items, const std::uint16_t* offsets,
                  std::uint16_t record_length, ArithmeticDecoder& dec, std::uint8_t* out,
                  std::uint64_t n, std::index_sequence<I...>) {
  const std::tuple<Items*...> typed{std::get_if<Items>(&items[I])...};
  const std::uint16_t at[] = {offsets[I]...};
  ArithmeticDecoder local = dec;
  for (std::uint64_t i = 0; i < n; ++i, out += record_length) {
    (std::get<I>(typed)->decode(local, out + at[I]), ...);
  }
  dec = local;
}

template <typename... Items>
void decode_fixed(std::span<PointwiseItem> items, const std::uint16_t* offsets,
                  std::uint16_t record_length, ArithmeticDecoder& dec, std::uint8_t* out,
                  std::uint64_t n) {
  decode_fixed<Items...>(items, offsets, record_length, dec, out, n,
                         std::index_sequence_for<Items...>{});
}

template <typename... Items>
bool holds(std::span<PointwiseItem> items) {
  if (items.size() != sizeof...(Items)) return false;
  std::size_t i = 0;
  return (std::holds_alternative<Items>(items[i++]) && ...);
}

void decode_any(std::span<PointwiseItem> items, const std::uint16_t* offsets,
                std::uint16_t record_length, ArithmeticDecoder& dec, std::uint8_t* out,
                std::uint64_t n) {
  ArithmeticDecoder local = dec;
  for (std::uint64_t r = 0; r < n; ++r, out += record_length) {
    for (std::size_t i = 0; i < items.size(); ++i) {
      std::visit([&](auto& item) { item.decode(local, out + offsets[i]); }, items[i]);
    }
  }
  dec = local;
}

}  // namespace

bool pairs_pointwise(std::span<const PointwiseItem> items) {
  return items.size() == 2 && std::holds_alternative<Point10V2>(items[0]) &&
         std::holds_alternative<GpsTime11V2>(items[1]);
}

// The steps alternate between the chunks field by field (attributes, x, y, z, GPS time): each
// is a few symbols long, short enough that the two chains overlap in the out-of-order window
// (whole records alternated overlapped only at their seams: 3 %, bench/laz/RESULTS.md).
void decode_pointwise_pair(std::span<PointwiseItem> items_a, ArithmeticDecoder& dec_a,
                           std::uint8_t* out_a, std::span<PointwiseItem> items_b,
                           ArithmeticDecoder& dec_b, std::uint8_t* out_b,
                           const std::uint16_t* offsets, std::uint16_t record_length,
                           std::uint64_t n) {
  assert(pairs_pointwise(items_a) && pairs_pointwise(items_b));
  Point10V2& point_a = *std::get_if<Point10V2>(&items_a[0]);
  Point10V2& point_b = *std::get_if<Point10V2>(&items_b[0]);
  GpsTime11V2& time_a = *std::get_if<GpsTime11V2>(&items_a[1]);
  GpsTime11V2& time_b = *std::get_if<GpsTime11V2>(&items_b[1]);
  const std::uint16_t time_at = offsets[1];
  ArithmeticDecoder a = dec_a;
  ArithmeticDecoder b = dec_b;
  for (std::uint64_t i = 0; i < n; ++i, out_a += record_length, out_b += record_length) {
    Point10V2::Steps sa;
    Point10V2::Steps sb;
    point_a.changed_fields(a, sa);
    point_b.changed_fields(b, sb);
    point_a.returns(a, sa);
    point_b.returns(b, sb);
    point_a.intensity_class(a, sa);
    point_b.intensity_class(b, sb);
    point_a.intensity(a, sa);
    point_b.intensity(b, sb);
    point_a.other_fields(a, sa);
    point_b.other_fields(b, sb);
    point_a.x_class(a, sa);
    point_b.x_class(b, sb);
    point_a.x(a, sa);
    point_b.x(b, sb);
    point_a.y_class(a, sa);
    point_b.y_class(b, sb);
    point_a.y(a, sa);
    point_b.y(b, sb);
    point_a.z_class(a, sa);
    point_b.z_class(b, sb);
    point_a.z(a, sa);
    point_b.z(b, sb);
    point_a.store(out_a);
    point_b.store(out_b);
    GpsTimeSequences& seq_a = time_a.sequences();
    GpsTimeSequences& seq_b = time_b.sequences();
    const std::uint32_t sym_a = seq_a.first_symbol(a);
    const std::uint32_t sym_b = seq_b.first_symbol(b);
    const std::uint32_t k_a = seq_a.step_class(a, sym_a);
    const std::uint32_t k_b = seq_b.step_class(b, sym_b);
    put64(out_a + time_at, seq_a.finish(a, sym_a, k_a));
    put64(out_b + time_at, seq_b.finish(b, sym_b, k_b));
  }
  dec_a = a;
  dec_b = b;
}

void decode_pointwise(std::span<PointwiseItem> items, const std::uint16_t* offsets,
                      std::uint16_t record_length, ArithmeticDecoder& dec, std::uint8_t* out,
                      std::uint64_t n) {
  if (holds<Point10V2, GpsTime11V2>(items)) {
    decode_fixed<Point10V2, GpsTime11V2>(items, offsets, record_length, dec, out, n);
  } else if (holds<Point10V2>(items)) {
    decode_fixed<Point10V2>(items, offsets, record_length, dec, out, n);
  } else if (holds<Point10V2, Rgb12V2>(items)) {
    decode_fixed<Point10V2, Rgb12V2>(items, offsets, record_length, dec, out, n);
  } else if (holds<Point10V2, GpsTime11V2, Rgb12V2>(items)) {
    decode_fixed<Point10V2, GpsTime11V2, Rgb12V2>(items, offsets, record_length, dec, out, n);
  } else {
    decode_any(items, offsets, record_length, dec, out, n);
  }
}

}  // namespace tinstream::laz::detail
