// Layered item decoders (LASzip item versions 3 and 4: POINT14, RGB14, RGBNIR14, BYTE14,
// WAVEPACKET14). Each scanner channel (0-3) has its own context: models and "last" values.
#include <algorithm>

#include "item_coders.hpp"
#include "items.hpp"

namespace tinstream::laz::detail {

// ---------------------------------------------------------------------------------------------
// POINT14

void Point14Fields::load(const std::uint8_t* p) {
  x = static_cast<std::int32_t>(get32(p));
  y = static_cast<std::int32_t>(get32(p + 4));
  z = static_cast<std::int32_t>(get32(p + 8));
  intensity = get16(p + 12);
  return_number = p[14] & 0x0F;
  number_of_returns = p[14] >> 4;
  class_flags = p[15] & 0x0F;
  scanner_channel = (p[15] >> 4) & 3;
  scan_direction = (p[15] >> 6) & 1;
  edge_of_line = p[15] >> 7;
  classification = p[16];
  user_data = p[17];
  scan_angle = static_cast<std::int16_t>(get16(p + 18));
  source_id = get16(p + 20);
  gps_time = get64(p + 22);
  gps_time_changed = false;
}

void Point14Fields::store(std::uint8_t* p) const {
  put32(p, static_cast<std::uint32_t>(x));
  put32(p + 4, static_cast<std::uint32_t>(y));
  put32(p + 8, static_cast<std::uint32_t>(z));
  put16(p + 12, intensity);
  p[14] = static_cast<std::uint8_t>(return_number | (number_of_returns << 4));
  p[15] = static_cast<std::uint8_t>(class_flags | (scanner_channel << 4) | (scan_direction << 6) |
                                    (edge_of_line << 7));
  p[16] = classification;
  p[17] = user_data;
  put16(p + 18, static_cast<std::uint16_t>(scan_angle));
  put16(p + 20, source_id);
  put64(p + 22, gps_time);
}

// One scanner channel's state. Indices: m = return map (0..5), l = return level (0..7),
// cpr = first (2) / last (1) bits of the current return, g = GPS time changed.
struct Point14Layered::Context {
  Point14Fields last;
  std::array<std::uint16_t, 8> last_intensity{};  // by cpr * 2 + g
  std::array<StreamingMedian5, 12> dx_median{};   // by m * 2 + g
  std::array<StreamingMedian5, 12> dy_median{};
  std::array<std::int32_t, 8> last_z{};  // by l
  // XY layer
  std::array<SymbolModel, 8> changed{SymbolModel(128), SymbolModel(128), SymbolModel(128),
                                     SymbolModel(128), SymbolModel(128), SymbolModel(128),
                                     SymbolModel(128), SymbolModel(128)};
  SymbolModel scanner_step{3};
  LazyModels number_of_returns{16, 16};
  LazyModels return_number{16, 16};
  SymbolModel return_step_same_time{13};
  IntegerDecoder ic_dx{32, 2}, ic_dy{32, 22};
  // other layers
  IntegerDecoder ic_z{32, 20};
  LazyModels classification{64, 256};
  LazyModels flags{64, 64};
  LazyModels user_data{64, 256};
  IntegerDecoder ic_intensity{16, 4};
  IntegerDecoder ic_scan_angle{16, 2};
  IntegerDecoder ic_source_id{16, 1};
  GpsTimeSequences gps{true};

  void reset(const Point14Fields& from) {
    last = from;
    last.gps_time_changed = false;
    last_intensity.fill(from.intensity);
    for (auto& m : dx_median) m.reset();
    for (auto& m : dy_median) m.reset();
    last_z.fill(from.z);
    for (auto& m : changed) m.reset();
    scanner_step.reset();
    number_of_returns.next_chunk();
    return_number.next_chunk();
    return_step_same_time.reset();
    ic_dx.reset();
    ic_dy.reset();
    ic_z.reset();
    classification.next_chunk();
    flags.next_chunk();
    user_data.next_chunk();
    ic_intensity.reset();
    ic_scan_angle.reset();
    ic_source_id.reset();
    gps.reset(from.gps_time);
  }
};

Point14Layered::Point14Layered(const LayerSelection& s) {
  wanted_ = {true,         s.z,         s.classification, s.flags,   s.intensity,
             s.scan_angle, s.user_data, s.point_source,   s.gps_time};
}

Point14Layered::~Point14Layered() = default;

Point14Layered::Context& Point14Layered::open_context(std::uint32_t channel,
                                                      const Point14Fields& from) {
  if (!contexts_[channel]) contexts_[channel] = std::make_unique<Context>();
  contexts_[channel]->reset(from);
  in_use_[channel] = true;
  return *contexts_[channel];
}

void Point14Layered::start(const std::uint8_t* raw) {
  Point14Fields first;
  first.load(raw);
  in_use_ = {};
  current_ = first.scanner_channel;
  open_context(current_, first);
}

namespace {

// LAS 1.4 return numbers folded into the 3-bit legacy fields never appear in the output of
// formats 6-10, so they are not kept. The "scan angle rank" likewise.
std::int32_t scan_angle_from(std::int32_t decoded) { return static_cast<std::int16_t>(decoded); }

}  // namespace

TINSTREAM_LAZ_INLINE void Point14Layered::decode(std::uint8_t* out) {
  Context* c = contexts_[current_].get();
  ArithmeticDecoder& xy = layers_[kLayerXY].dec;

  // Which fields changed, in the context of the previous point's return and time change.
  std::uint32_t lpr = (c->last.return_number == 1 ? 1u : 0u) +
                      (c->last.return_number >= c->last.number_of_returns ? 2u : 0u) +
                      (c->last.gps_time_changed ? 4u : 0u);
  const std::uint32_t changed = xy.decode_symbol(c->changed[lpr]);
  if (changed & (1u << 6)) {  // another scanner channel: current + 1..3 (mod 4)
    const std::uint32_t step = xy.decode_symbol(c->scanner_step);
    const std::uint32_t channel = (current_ + step + 1) & 3;
    if (!in_use_[channel]) open_context(channel, c->last);
    current_ = channel;
    c = contexts_[channel].get();
    c->last.scanner_channel = static_cast<std::uint8_t>(channel);
  }
  Point14Fields& p = c->last;
  const bool source_changed = (changed & (1u << 5)) != 0;
  const bool time_changed = (changed & (1u << 4)) != 0;
  const bool angle_changed = (changed & (1u << 3)) != 0;

  const std::uint32_t last_n = p.number_of_returns;
  const std::uint32_t last_r = p.return_number;
  std::uint32_t n = last_n;
  if (changed & (1u << 2)) {
    n = xy.decode_symbol(c->number_of_returns.at(last_n));
    p.number_of_returns = static_cast<std::uint8_t>(n);
  }
  std::uint32_t r = last_r;
  switch (changed & 3) {
    case 0:
      break;
    case 1:
      r = (last_r + 1) & 15;
      break;
    case 2:
      r = (last_r + 15) & 15;
      break;
    default:
      if (time_changed) {
        r = xy.decode_symbol(c->return_number.at(last_r));
      } else {
        r = (last_r + xy.decode_symbol(c->return_step_same_time) + 2) & 15;
      }
      break;
  }
  p.return_number = static_cast<std::uint8_t>(r);

  const std::uint32_t m = return_map_6ctx(n, r);
  const std::uint32_t l = return_level(n, r, 7);
  const std::uint32_t cpr = (r == 1 ? 2u : 0u) + (r >= n ? 1u : 0u);
  const std::uint32_t g = time_changed ? 1 : 0;
  const std::uint32_t single = n == 1 ? 1 : 0;

  StreamingMedian5& mx = c->dx_median[(m << 1) | g];
  std::int32_t diff = c->ic_dx.decode(xy, mx.get(), single);
  p.x = wrap_add(p.x, diff);
  mx.push(diff);
  StreamingMedian5& my = c->dy_median[(m << 1) | g];
  std::uint32_t k = c->ic_dx.last_k();
  diff = c->ic_dy.decode(xy, my.get(), single + (k < 20 ? k & ~1u : 20));
  p.y = wrap_add(p.y, diff);
  my.push(diff);

  if (layers_[kLayerZ].active) {
    k = (c->ic_dx.last_k() + c->ic_dy.last_k()) / 2;
    p.z = c->ic_z.decode(layers_[kLayerZ].dec, c->last_z[l], single + (k < 18 ? k & ~1u : 18));
    c->last_z[l] = p.z;
  }
  if (layers_[kLayerClassification].active) {
    const std::uint32_t ctx = ((p.classification & 0x1Fu) << 1) + (cpr == 3 ? 1u : 0u);
    p.classification = static_cast<std::uint8_t>(
        layers_[kLayerClassification].dec.decode_symbol(c->classification.at(ctx)));
  }
  if (layers_[kLayerFlags].active) {
    const std::uint32_t ctx = (static_cast<std::uint32_t>(p.edge_of_line) << 5) |
                              (static_cast<std::uint32_t>(p.scan_direction) << 4) | p.class_flags;
    const std::uint32_t flags = layers_[kLayerFlags].dec.decode_symbol(c->flags.at(ctx));
    p.edge_of_line = static_cast<std::uint8_t>((flags >> 5) & 1);
    p.scan_direction = static_cast<std::uint8_t>((flags >> 4) & 1);
    p.class_flags = static_cast<std::uint8_t>(flags & 0x0F);
  }
  if (layers_[kLayerIntensity].active) {
    std::uint16_t& predicted = c->last_intensity[(cpr << 1) | g];
    p.intensity = static_cast<std::uint16_t>(
        c->ic_intensity.decode(layers_[kLayerIntensity].dec, predicted, cpr));
    predicted = p.intensity;
  }
  if (layers_[kLayerScanAngle].active && angle_changed) {
    p.scan_angle = static_cast<std::int16_t>(
        scan_angle_from(c->ic_scan_angle.decode(layers_[kLayerScanAngle].dec, p.scan_angle, g)));
  }
  if (layers_[kLayerUserData].active) {
    p.user_data = static_cast<std::uint8_t>(
        layers_[kLayerUserData].dec.decode_symbol(c->user_data.at(p.user_data / 4u)));
  }
  if (layers_[kLayerPointSource].active && source_changed) {
    p.source_id = static_cast<std::uint16_t>(
        c->ic_source_id.decode(layers_[kLayerPointSource].dec, p.source_id, 0));
  }
  if (layers_[kLayerGpsTime].active && time_changed) {
    p.gps_time = c->gps.decode(layers_[kLayerGpsTime].dec);
  }
  p.store(out);
  p.gps_time_changed = time_changed;
}

// ---------------------------------------------------------------------------------------------
// RGB14 and RGBNIR14

Rgb14Layered::Rgb14Layered(bool nir, bool version4, const LayerSelection& s)
    : nir_(nir), version4_(version4), want_rgb_(s.rgb), want_nir_(nir && s.nir) {}

Rgb14Layered::Context& Rgb14Layered::open(std::uint32_t channel, const std::uint16_t* from) {
  if (!contexts_[channel]) contexts_[channel] = std::make_unique<Context>();
  Context& c = *contexts_[channel];
  std::copy(from, from + 4, c.last);
  c.rgb.reset();
  c.nir_changed.reset();
  c.nir_diff_low.reset();
  c.nir_diff_high.reset();
  return c;
}

void Rgb14Layered::start(const std::uint8_t* raw, std::uint32_t channel) {
  std::uint16_t first[4] = {get16(raw), get16(raw + 2), get16(raw + 4),
                            nir_ ? get16(raw + 6) : std::uint16_t{0}};
  channels_ = {};
  channels_.current = channel;
  channels_.in_use[channel] = true;
  open(channel, first);
}

TINSTREAM_LAZ_INLINE void Rgb14Layered::decode(std::uint8_t* out, std::uint32_t channel) {
  const std::uint32_t source = channels_.follow(
      channel, version4_,
      [this](std::uint32_t ch, std::uint32_t from) { open(ch, contexts_[from]->last); });
  Context& models = *contexts_[channels_.current];
  std::uint16_t* last = contexts_[source]->last;
  if (layers_[0].active) {
    std::uint16_t now[3];
    decode_rgb(layers_[0].dec, models.rgb, last, now);
    std::copy(now, now + 3, last);
  }
  for (std::size_t i = 0; i < 3; ++i) put16(out + 2 * i, last[i]);
  if (!nir_) return;
  if (layers_[1].active) {
    ArithmeticDecoder& dec = layers_[1].dec;
    const std::uint32_t sym = dec.decode_symbol(models.nir_changed);
    std::uint32_t low = last[3] & 0xFFu, high = last[3] >> 8;
    if (sym & 1) low = (dec.decode_symbol(models.nir_diff_low) + low) & 0xFF;
    if (sym & 2) high = (dec.decode_symbol(models.nir_diff_high) + high) & 0xFF;
    last[3] = static_cast<std::uint16_t>(low | (high << 8));
  }
  put16(out + 6, last[3]);
}

// ---------------------------------------------------------------------------------------------
// BYTE14

Byte14Layered::Byte14Layered(std::size_t count, bool version4, const LayerSelection& s)
    : count_(count), version4_(version4), wanted_(s.extra_bytes), layers_(count) {}

Byte14Layered::Context& Byte14Layered::open(std::uint32_t channel, const std::uint8_t* from) {
  if (!contexts_[channel]) {
    contexts_[channel] = std::make_unique<Context>();
    Context& c = *contexts_[channel];
    c.last.resize(count_);
    c.diff.reserve(count_);
    for (std::size_t i = 0; i < count_; ++i) c.diff.emplace_back(256);
  }
  Context& c = *contexts_[channel];
  std::copy(from, from + count_, c.last.begin());
  // Models of layers that are not decoded are never used: leave them as they are.
  for (std::size_t i = 0; i < count_; ++i) {
    if (layers_[i].active) c.diff[i].reset();
  }
  return c;
}

void Byte14Layered::start(const std::uint8_t* raw, std::uint32_t channel) {
  channels_ = {};
  channels_.current = channel;
  channels_.in_use[channel] = true;
  open(channel, raw);
}

TINSTREAM_LAZ_INLINE void Byte14Layered::decode(std::uint8_t* out, std::uint32_t channel) {
  const std::uint32_t source =
      channels_.follow(channel, version4_, [this](std::uint32_t ch, std::uint32_t from) {
        open(ch, contexts_[from]->last.data());  // distinct contexts: no aliasing
      });
  Context& models = *contexts_[channels_.current];
  std::uint8_t* last = contexts_[source]->last.data();
  for (std::size_t i = 0; i < count_; ++i) {
    if (layers_[i].active) {
      last[i] = static_cast<std::uint8_t>((layers_[i].dec.decode_symbol(models.diff[i]) + last[i]) &
                                          0xFF);
    }
    out[i] = last[i];
  }
}

// ---------------------------------------------------------------------------------------------
// WAVEPACKET14

WavePacket14Layered::WavePacket14Layered(bool version4, const LayerSelection& s)
    : version4_(version4), wanted_(s.wavepacket) {}

void WavePacket14Layered::start(const std::uint8_t* raw, std::uint32_t channel) {
  channels_ = {};
  channels_.current = channel;
  channels_.in_use[channel] = true;
  if (!contexts_[channel]) contexts_[channel] = std::make_unique<WavePacketCoder>();
  contexts_[channel]->reset(raw);
}

void WavePacket14Layered::decode(std::uint8_t* out, std::uint32_t channel) {
  const std::uint32_t source =
      channels_.follow(channel, version4_, [this](std::uint32_t ch, std::uint32_t from) {
        if (!contexts_[ch]) contexts_[ch] = std::make_unique<WavePacketCoder>();
        contexts_[ch]->reset(contexts_[from]->last());
      });
  WavePacketCoder& coder = *contexts_[channels_.current];
  if (!layer_.active) {
    std::memcpy(out, contexts_[source]->last(), 29);
    return;
  }
  if (source == channels_.current) {
    coder.decode(layer_.dec, out);
    return;
  }
  // v3 at a switch to a channel already in use: the models are the new channel's, the
  // prediction and the update are the previous channel's last packet.
  std::array<std::uint8_t, 29> own;
  std::memcpy(own.data(), coder.last(), 29);
  coder.overwrite_last(contexts_[source]->last());
  coder.decode(layer_.dec, out);
  contexts_[source]->overwrite_last(out);
  coder.overwrite_last(own.data());
}

// ---------------------------------------------------------------------------------------------
// The record loop

void decode_layered(Point14Layered& point14, std::span<LayeredItem> items,
                    const std::uint16_t* offsets, std::uint16_t record_length, std::uint8_t* out,
                    std::uint64_t n) {
  for (std::uint64_t r = 0; r < n; ++r, out += record_length) {
    point14.decode(out);
    const std::uint32_t channel = point14.channel();
    for (std::size_t i = 0; i < items.size(); ++i) {
      std::uint8_t* dst = out + offsets[i + 1];
      LayeredItem& item = items[i];
      // An explicit switch (not std::visit) so that the items inline into this loop.
      switch (item.index()) {
        case 0:
          std::get_if<Rgb14Layered>(&item)->decode(dst, channel);
          break;
        case 1:
          std::get_if<Byte14Layered>(&item)->decode(dst, channel);
          break;
        default:
          std::get_if<WavePacket14Layered>(&item)->decode(dst, channel);
          break;
      }
    }
  }
}

}  // namespace tinstream::laz::detail
