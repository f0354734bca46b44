// Layered item decoders (LASzip item versions 3 and 4: POINT14, RGB14, RGBNIR14, BYTE14,
// WAVEPACKET14). Each of four contexts (0-3) has its own models and "last" values: POINT14's
// context is the point's scanner channel; the other items' is the one LASzip hands them, which
// in v3 is 0 except where the channel switches (Point14Context::item_context).
#include <algorithm>
#include <utility>

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

  // A channel opens (at the chunk's first point, or where the chunk first switches to it) from
  // a point's fields: each layer's part separately, as the layer's loop reaches that point.
  void reset(const Point14Fields& from) {
    reset_xy(from);
    reset_z(from);
    reopen<&Point14Fields::classification, &Context::classification>(from);
    reset_flags(from);
    reset_intensity(from);
    reopen<&Point14Fields::scan_angle, &Context::ic_scan_angle>(from);
    reopen<&Point14Fields::user_data, &Context::user_data>(from);
    reopen<&Point14Fields::source_id, &Context::ic_source_id>(from);
    reset_gps_time(from);
  }
  void reset_xy(const Point14Fields& from) {
    last.x = from.x;
    last.y = from.y;
    last.return_number = from.return_number;
    last.number_of_returns = from.number_of_returns;
    last.scanner_channel = from.scanner_channel;
    last.gps_time_changed = false;
    for (auto& m : dx_median) m.reset();
    for (auto& m : dy_median) m.reset();
    for (auto& m : changed) m.reset();
    scanner_step.reset();
    number_of_returns.next_chunk();
    return_number.next_chunk();
    return_step_same_time.reset();
    ic_dx.reset();
    ic_dy.reset();
  }
  // One layer's part: its field of `last` taken from `from`, its models as at a chunk's start
  // (lazily created models start a new generation, the others reset).
  template <auto kField, auto kModels>
  void reopen(const Point14Fields& from) {
    last.*kField = from.*kField;
    auto& models = this->*kModels;
    if constexpr (requires { models.next_chunk(); }) {
      models.next_chunk();
    } else {
      models.reset();
    }
  }
  void reset_z(const Point14Fields& from) {
    reopen<&Point14Fields::z, &Context::ic_z>(from);
    last_z.fill(from.z);
  }
  void reset_flags(const Point14Fields& from) {
    last.class_flags = from.class_flags;
    last.scan_direction = from.scan_direction;
    reopen<&Point14Fields::edge_of_line, &Context::flags>(from);
  }
  void reset_intensity(const Point14Fields& from) {
    reopen<&Point14Fields::intensity, &Context::ic_intensity>(from);
    last_intensity.fill(from.intensity);
  }
  void reset_gps_time(const Point14Fields& from) {
    last.gps_time = from.gps_time;
    gps.reset(from.gps_time);
  }
};

Point14Layered::Point14Layered(bool version4, const LayerSelection& s) : version4_(version4) {
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
  item_context_ = current_;
  open_context(current_, first);
}

namespace {

// LAS 1.4 return numbers folded into the 3-bit legacy fields never appear in the output of
// formats 6-10, so they are not kept. The "scan angle rank" likewise.
std::int32_t scan_angle_from(std::int32_t decoded) { return static_cast<std::int16_t>(decoded); }

}  // namespace

namespace {

// One layer's part of a loop over the batch: open(new channel's context, previous channel's
// context) where a channel opens, then step(context of the point's channel, point context, i).
template <typename Open, typename Step>
struct LayerPass {
  Open open;
  Step step;
};
template <typename Open, typename Step>
LayerPass(Open, Step) -> LayerPass<Open, Step>;

}  // namespace

// The XY/returns layer of n points: x, y and the return byte of each record, and each point's
// context for the other layers (batch_). The channel switches happen here; a channel new to the
// chunk gets its XY part opened here and the other layers' parts in their own loops.
template <typename... Passes>
TINSTREAM_LAZ_INLINE void Point14Layered::decode_xy(std::uint8_t* records,
                                                    std::uint16_t record_length, std::size_t n,
                                                    Passes&... passes) {
  ArithmeticDecoder xy = layers_[kLayerXY].dec;  // in registers for the loop
  std::uint32_t current = current_;
  Context* c = contexts_[current].get();
  std::uint8_t* out = records;
  std::uint32_t item_context = item_context_;
  bool one_item_context = true;
  for (std::size_t i = 0; i < n; ++i, out += record_length) {
    Point14Context& pc = batch_[i];
    pc.from = static_cast<std::uint8_t>(current);
    std::uint32_t opens = 0;
    bool switches = false;
    // Which fields changed, in the context of the previous point's return and time change.
    const std::uint32_t lpr = (c->last.return_number == 1 ? 1u : 0u) +
                              (c->last.return_number >= c->last.number_of_returns ? 2u : 0u) +
                              (c->last.gps_time_changed ? 4u : 0u);
    const std::uint32_t changed = xy.decode_symbol(c->changed[lpr]);
    if (changed & (1u << 6)) [[unlikely]] {  // another scanner channel: current + 1..3 (mod 4)
      const std::uint32_t step = xy.decode_symbol(c->scanner_step);
      const std::uint32_t channel = (current + step + 1) & 3;
      switches = true;
      if (!in_use_[channel]) {
        if (!contexts_[channel]) contexts_[channel] = std::make_unique<Context>();
        contexts_[channel]->reset_xy(c->last);
        (passes.open(*contexts_[channel], static_cast<const Context&>(*c)), ...);
        in_use_[channel] = true;
        opens = Point14Context::kOpens;
      }
      current = channel;
      c = contexts_[channel].get();
      c->last.scanner_channel = static_cast<std::uint8_t>(channel);
    }
    Point14Fields& p = c->last;
    const bool time_changed = (changed & (1u << 4)) != 0;

    const std::uint32_t last_n = p.number_of_returns;
    const std::uint32_t last_r = p.return_number;
    std::uint32_t nr = last_n;
    if (changed & (1u << 2)) {
      nr = xy.decode_symbol(c->number_of_returns.at(last_n));
      p.number_of_returns = static_cast<std::uint8_t>(nr);
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

    const std::uint32_t m = return_map_6ctx(nr, r);
    const std::uint32_t l = return_level(nr, r, 7);
    const std::uint32_t cpr = (r == 1 ? 2u : 0u) + (r >= nr ? 1u : 0u);
    const std::uint32_t g = time_changed ? 1 : 0;
    const std::uint32_t single = nr == 1 ? 1 : 0;

    StreamingMedian5& mx = c->dx_median[(m << 1) | g];
    std::int32_t diff = c->ic_dx.decode(xy, mx.get(), single);
    p.x = wrap_add(p.x, diff);
    mx.push(diff);
    StreamingMedian5& my = c->dy_median[(m << 1) | g];
    std::uint32_t k = c->ic_dx.last_k();
    diff = c->ic_dy.decode(xy, my.get(), single + (k < 20 ? k & ~1u : 20));
    p.y = wrap_add(p.y, diff);
    my.push(diff);
    k = (c->ic_dx.last_k() + c->ic_dy.last_k()) / 2;

    put32(out, static_cast<std::uint32_t>(p.x));
    put32(out + 4, static_cast<std::uint32_t>(p.y));
    out[14] = static_cast<std::uint8_t>(r | (nr << 4));
    pc.channel = static_cast<std::uint8_t>(current | opens);
    // v3: the channel where it switches, else 0; v4: the channel (Point14Context::item_context).
    const std::uint32_t point_item_context = version4_ || switches ? current : 0;
    pc.item_context = static_cast<std::uint8_t>(point_item_context);
    one_item_context &= point_item_context == item_context;
    item_context = point_item_context;
    pc.returns = static_cast<std::uint8_t>(g | (cpr << 1) | (changed & (1u << 3)) |
                                           (changed & (1u << 5)) >> 1 | (l << 5));
    pc.z_context = static_cast<std::uint8_t>(single + (k < 18 ? k & ~1u : 18));
    p.gps_time_changed = time_changed;
    (passes.step(*c, static_cast<const Point14Context&>(pc), i), ...);
  }
  layers_[kLayerXY].dec = xy;
  current_ = current;
  item_context_ = item_context;
  one_item_context_ = one_item_context;
}

// One loop over the batch for the given layers (each its own stream: their symbol chains
// overlap in the processor).
template <typename... Passes>
TINSTREAM_LAZ_INLINE void Point14Layered::layer_loop(std::size_t n, Passes&... passes) {
  for (std::size_t i = 0; i < n; ++i) {
    const Point14Context pc = batch_[i];
    Context& c = *contexts_[pc.channel & 3];
    if (pc.channel & Point14Context::kOpens) [[unlikely]] {
      const Context& from = *contexts_[pc.from];
      (passes.open(c, from), ...);
    }
    (passes.step(c, pc, i), ...);
  }
}

void Point14Layered::decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n) {
  const std::size_t rl = record_length;
  // Each layer's decoder in a local (registers while its loop runs), written back at the end.
  ArithmeticDecoder z_dec = layers_[kLayerZ].dec;
  const bool z_active = layers_[kLayerZ].active;
  LayerPass z{[](Context& c, const Context& from) { c.reset_z(from.last); },
              [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
                if (z_active) {
                  std::int32_t& predicted = c.last_z[pc.returns >> 5];
                  predicted = c.ic_z.decode(z_dec, predicted, pc.z_context);
                  c.last.z = predicted;
                }
                put32(out + i * rl + 8, static_cast<std::uint32_t>(c.last.z));
              }};
  ArithmeticDecoder class_dec = layers_[kLayerClassification].dec;
  const bool class_active = layers_[kLayerClassification].active;
  LayerPass classification{
      [](Context& c, const Context& from) {
        c.reopen<&Point14Fields::classification, &Context::classification>(from.last);
      },
      [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
        if (class_active) {
          const std::uint32_t ctx =
              ((c.last.classification & 0x1Fu) << 1) + ((pc.returns & 6) == 6 ? 1u : 0u);
          c.last.classification =
              static_cast<std::uint8_t>(class_dec.decode_symbol(c.classification.at(ctx)));
        }
        out[i * rl + 16] = c.last.classification;
      }};
  ArithmeticDecoder flags_dec = layers_[kLayerFlags].dec;
  const bool flags_active = layers_[kLayerFlags].active;
  LayerPass flags{[](Context& c, const Context& from) { c.reset_flags(from.last); },
                  [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
                    Point14Fields& p = c.last;
                    if (flags_active) {
                      const std::uint32_t ctx =
                          (static_cast<std::uint32_t>(p.edge_of_line) << 5) |
                          (static_cast<std::uint32_t>(p.scan_direction) << 4) | p.class_flags;
                      const std::uint32_t f = flags_dec.decode_symbol(c.flags.at(ctx));
                      p.edge_of_line = static_cast<std::uint8_t>((f >> 5) & 1);
                      p.scan_direction = static_cast<std::uint8_t>((f >> 4) & 1);
                      p.class_flags = static_cast<std::uint8_t>(f & 0x0F);
                    }
                    out[i * rl + 15] =
                        static_cast<std::uint8_t>(p.class_flags | ((pc.channel & 3) << 4) |
                                                  (p.scan_direction << 6) | (p.edge_of_line << 7));
                  }};
  ArithmeticDecoder intensity_dec = layers_[kLayerIntensity].dec;
  const bool intensity_active = layers_[kLayerIntensity].active;
  LayerPass intensity{
      [](Context& c, const Context& from) { c.reset_intensity(from.last); },
      [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
        if (intensity_active) {
          const std::uint32_t cpr = (pc.returns >> 1) & 3;
          std::uint16_t& predicted = c.last_intensity[pc.returns & 7];  // cpr * 2 + g
          c.last.intensity =
              static_cast<std::uint16_t>(c.ic_intensity.decode(intensity_dec, predicted, cpr));
          predicted = c.last.intensity;
        }
        put16(out + i * rl + 12, c.last.intensity);
      }};
  ArithmeticDecoder angle_dec = layers_[kLayerScanAngle].dec;
  const bool angle_active = layers_[kLayerScanAngle].active;
  LayerPass angle{[](Context& c, const Context& from) {
                    c.reopen<&Point14Fields::scan_angle, &Context::ic_scan_angle>(from.last);
                  },
                  [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
                    if (angle_active && (pc.returns & (1u << 3))) {
                      c.last.scan_angle = static_cast<std::int16_t>(scan_angle_from(
                          c.ic_scan_angle.decode(angle_dec, c.last.scan_angle, pc.returns & 1)));
                    }
                    put16(out + i * rl + 18, static_cast<std::uint16_t>(c.last.scan_angle));
                  }};
  ArithmeticDecoder user_dec = layers_[kLayerUserData].dec;
  const bool user_active = layers_[kLayerUserData].active;
  LayerPass user_data{[](Context& c, const Context& from) {
                        c.reopen<&Point14Fields::user_data, &Context::user_data>(from.last);
                      },
                      [&](Context& c, Point14Context, std::size_t i) TINSTREAM_LAZ_LAMBDA {
                        if (user_active) {
                          c.last.user_data = static_cast<std::uint8_t>(
                              user_dec.decode_symbol(c.user_data.at(c.last.user_data / 4u)));
                        }
                        out[i * rl + 17] = c.last.user_data;
                      }};
  ArithmeticDecoder source_dec = layers_[kLayerPointSource].dec;
  const bool source_active = layers_[kLayerPointSource].active;
  LayerPass source{[](Context& c, const Context& from) {
                     c.reopen<&Point14Fields::source_id, &Context::ic_source_id>(from.last);
                   },
                   [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
                     if (source_active && (pc.returns & (1u << 4))) {
                       c.last.source_id = static_cast<std::uint16_t>(
                           c.ic_source_id.decode(source_dec, c.last.source_id, 0));
                     }
                     put16(out + i * rl + 20, c.last.source_id);
                   }};
  ArithmeticDecoder gps_dec = layers_[kLayerGpsTime].dec;
  const bool gps_active = layers_[kLayerGpsTime].active;
  LayerPass gps{[](Context& c, const Context& from) { c.reset_gps_time(from.last); },
                [&](Context& c, Point14Context pc, std::size_t i) TINSTREAM_LAZ_LAMBDA {
                  if (gps_active && (pc.returns & 1)) c.last.gps_time = c.gps.decode(gps_dec);
                  put64(out + i * rl + 22, c.last.gps_time);
                }};
  // Two or three layers per loop: enough independent chains to fill the processor, few enough
  // decoders to stay in registers.
  decode_xy(out, record_length, n, z);
  layer_loop(n, intensity, classification);
  layer_loop(n, flags, user_data);
  layer_loop(n, angle, source, gps);
  layers_[kLayerZ].dec = z_dec;
  layers_[kLayerClassification].dec = class_dec;
  layers_[kLayerFlags].dec = flags_dec;
  layers_[kLayerIntensity].dec = intensity_dec;
  layers_[kLayerScanAngle].dec = angle_dec;
  layers_[kLayerUserData].dec = user_dec;
  layers_[kLayerPointSource].dec = source_dec;
  layers_[kLayerGpsTime].dec = gps_dec;
}

// ---------------------------------------------------------------------------------------------
// RGB14 and RGBNIR14

Rgb14Layered::Rgb14Layered(bool nir, bool version4, const LayerSelection& s)
    : nir_(nir), version4_(version4), want_rgb_(s.rgb), want_nir_(nir && s.nir) {}

void Rgb14Layered::open(std::uint32_t channel, std::uint32_t from, std::size_t layer) {
  if (!contexts_[channel]) contexts_[channel] = std::make_unique<Context>();
  Context& c = *contexts_[channel];
  const std::uint16_t* source = contexts_[from]->last;  // distinct contexts: no aliasing
  if (layer == 0) {
    std::copy(source, source + 3, c.last);
    c.rgb.reset();
  } else {
    c.last[3] = source[3];
    c.nir_changed.reset();
    c.nir_diff_low.reset();
    c.nir_diff_high.reset();
  }
}

void Rgb14Layered::start(const std::uint8_t* raw, std::uint32_t channel) {
  std::uint16_t first[4] = {get16(raw), get16(raw + 2), get16(raw + 4),
                            nir_ ? get16(raw + 6) : std::uint16_t{0}};
  channels_ = {};
  channels_.current = channel;
  channels_.in_use[channel] = true;
  if (!contexts_[channel]) contexts_[channel] = std::make_unique<Context>();
  Context& c = *contexts_[channel];
  std::copy(first, first + 4, c.last);
  c.rgb.reset();
  c.nir_changed.reset();
  c.nir_diff_low.reset();
  c.nir_diff_high.reset();
}

void Rgb14Layered::decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                                const Point14Context* context, bool /*one_context*/) {
  // RGB and NIR in one loop: two streams, each decoder in a local (registers).
  ArithmeticDecoder rgb_dec = layers_[0].dec, nir_dec = layers_[1].dec;
  const bool rgb_active = layers_[0].active, nir_active = nir_ && layers_[1].active;
  ChannelSwitch sw = channels_;
  for (std::size_t i = 0; i < n; ++i, out += record_length) {
    const std::uint32_t source =
        sw.follow(context[i].item_context, version4_, [this](std::uint32_t ch, std::uint32_t from) {
          open(ch, from, 0);
          open(ch, from, 1);
        });
    Context& models = *contexts_[sw.current];
    std::uint16_t* last = contexts_[source]->last;
    if (rgb_active) {
      std::uint16_t now[3];
      decode_rgb(rgb_dec, models.rgb, last, now);
      std::copy(now, now + 3, last);
    }
    for (std::size_t k = 0; k < 3; ++k) put16(out + 2 * k, last[k]);
    if (!nir_) continue;
    if (nir_active) {
      const std::uint32_t sym = nir_dec.decode_symbol(models.nir_changed);
      std::uint32_t low = last[3] & 0xFFu, high = last[3] >> 8;
      if (sym & 1) low = (nir_dec.decode_symbol(models.nir_diff_low) + low) & 0xFF;
      if (sym & 2) high = (nir_dec.decode_symbol(models.nir_diff_high) + high) & 0xFF;
      last[3] = static_cast<std::uint16_t>(low | (high << 8));
    }
    put16(out + 6, last[3]);
  }
  channels_ = sw;
  layers_[0].dec = rgb_dec;
  layers_[1].dec = nir_dec;
}

// ---------------------------------------------------------------------------------------------
// BYTE14

Byte14Layered::Byte14Layered(std::size_t count, bool version4, const LayerSelection& s)
    : count_(count), version4_(version4), wanted_(s.extra_bytes), layers_(count) {}

Byte14Layered::Context& Byte14Layered::create(std::uint32_t channel) {
  if (!contexts_[channel]) {
    contexts_[channel] = std::make_unique<Context>();
    Context& c = *contexts_[channel];
    c.last.resize(count_);
    c.diff.reserve(count_);
    for (std::size_t i = 0; i < count_; ++i) c.diff.emplace_back(256);
  }
  return *contexts_[channel];
}

void Byte14Layered::open(std::uint32_t channel, std::uint32_t from, std::size_t byte) {
  Context& c = create(channel);
  c.last[byte] = contexts_[from]->last[byte];  // distinct contexts: no aliasing
  // Models of layers that are not decoded are never used: leave them as they are.
  if (layers_[byte].active) c.diff[byte].reset();
}

void Byte14Layered::start(const std::uint8_t* raw, std::uint32_t channel) {
  channels_ = {};
  channels_.current = channel;
  channels_.in_use[channel] = true;
  Context& c = create(channel);
  std::copy(raw, raw + count_, c.last.begin());
  for (std::size_t i = 0; i < count_; ++i) {
    if (layers_[i].active) c.diff[i].reset();
  }
}

void Byte14Layered::decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                                 const Point14Context* context, bool one_context) {
  // Two bytes' layers per loop, three in the last when the count is odd (one alone only when
  // it is the only one): two or three streams, each decoder in a local. A loop of one stream is
  // one chain of dependent symbol decodes with nothing to overlap it. Each loop follows the
  // channel switches on its own copy of the switch state; all copies end in the same state.
  const ChannelSwitch at_start = channels_;
  auto group = [&]<std::size_t kWidth>(std::size_t b) {
    channels_ = at_start;
    if (one_context) {
      decode_group<true, kWidth>(out, record_length, n, context, b);
    } else {
      decode_group<false, kWidth>(out, record_length, n, context, b);
    }
  };
  std::size_t b = 0;
  for (; b + 3 < count_ || b + 2 == count_; b += 2) group.template operator()<2>(b);
  if (b + 3 == count_) {
    group.template operator()<3>(b);
  } else if (b + 1 == count_) {
    group.template operator()<1>(b);
  }
}

namespace {

// f(std::integral_constant<std::size_t, k>) for k = 0 .. kCount - 1, each call inlined: a
// group's decoders are indexed by constants, so that they stay in registers.
template <std::size_t kCount, typename F>
TINSTREAM_LAZ_INLINE void for_each_index(F&& f) {
  [&]<std::size_t... k>(std::index_sequence<k...>) TINSTREAM_LAZ_LAMBDA {
    (f(std::integral_constant<std::size_t, k>{}), ...);
  }
  (std::make_index_sequence<kCount>{});
}

}  // namespace

// Byte layers b .. b + kWidth - 1. kOneContext: no point of the batch switches context, so the
// models and the last bytes stay those of the current context, the bytes kept in locals for
// the loop.
template <bool kOneContext, std::size_t kWidth>
void Byte14Layered::decode_group(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                                 const Point14Context* context, std::size_t b) {
  ChannelSwitch& sw = channels_;
  Context& first = *contexts_[sw.current];
  std::array<ArithmeticDecoder, kWidth> dec;
  std::array<bool, kWidth> active;
  std::array<SymbolModel*, kWidth> model;
  std::array<std::uint8_t, kWidth> own;
  for_each_index<kWidth>([&](auto k) TINSTREAM_LAZ_LAMBDA {
    dec[k] = layers_[b + k].dec;
    active[k] = layers_[b + k].active;
    model[k] = &first.diff[b + k];
    own[k] = first.last[b + k];
  });
  std::uint8_t* o = out + b;
  for (std::size_t i = 0; i < n; ++i, o += record_length) {
    std::uint8_t* last = own.data();
    if constexpr (!kOneContext) {
      const std::uint32_t source = sw.follow(context[i].item_context, version4_,
                                             [this, b](std::uint32_t ch, std::uint32_t from) {
                                               for (std::size_t k = 0; k < kWidth; ++k) {
                                                 open(ch, from, b + k);
                                               }
                                             });
      Context& models = *contexts_[sw.current];
      for_each_index<kWidth>([&](auto k) TINSTREAM_LAZ_LAMBDA { model[k] = &models.diff[b + k]; });
      last = contexts_[source]->last.data() + b;
    }
    for_each_index<kWidth>([&](auto k) TINSTREAM_LAZ_LAMBDA {
      if (active[k]) {
        last[k] = static_cast<std::uint8_t>((dec[k].decode_symbol(*model[k]) + last[k]) & 0xFF);
      }
      o[k] = last[k];
    });
  }
  for_each_index<kWidth>([&](auto k) TINSTREAM_LAZ_LAMBDA {
    if constexpr (kOneContext) first.last[b + k] = own[k];
    layers_[b + k].dec = dec[k];
  });
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

void WavePacket14Layered::decode_batch(std::uint8_t* out, std::uint16_t record_length,
                                       std::size_t n, const Point14Context* context,
                                       bool /*one_context*/) {
  for (std::size_t i = 0; i < n; ++i, out += record_length) decode(out, context[i].item_context);
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
  while (n > 0) {
    const auto batch = static_cast<std::size_t>(std::min<std::uint64_t>(n, kLayeredBatch));
    point14.decode_batch(out, record_length, batch);
    const Point14Context* context = point14.contexts();
    for (std::size_t i = 0; i < items.size(); ++i) {
      std::visit(
          [&](auto& item) {
            item.decode_batch(out + offsets[i + 1], record_length, batch, context,
                              point14.one_item_context());
          },
          items[i]);
    }
    out += batch * record_length;
    n -= batch;
  }
}

}  // namespace tinstream::laz::detail
