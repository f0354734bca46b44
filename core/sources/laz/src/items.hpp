// Item decoders: one per LASzip item type and version. An item is a fixed slice of the point
// record (POINT10 = bytes 0..19 of formats 0-5, GPSTIME11 = the 8-byte GPS time, ...); the
// record is the items' bytes one after the other, in the LASzip VLR's order.
//
// Every decoder has the same shape, with no virtual calls:
//   start(raw)        the chunk's first record is stored raw: take the item's bytes as the state
//   decode(..., out)  decode the next item into `out` (its bytes in LAS layout)
// Pointwise items (versions 1 and 2, compressors 1 and 2) share one ArithmeticDecoder per chunk.
// Layered items (versions 3 and 4, compressor 3) own one decoder per layer and decode a batch of
// points at a time, layer by layer (decode_batch; see Point14Context); a layer not asked for
// (LayerSelection) or empty in this chunk is never decoded, and its fields keep the value of the
// chunk's first point, as LASzip's selective decompression does.
//
// The prediction rules, contexts and model sizes follow the LAZ specification and LASzip's
// lasreaditemcompressed_v1/v2/v3/v4.cpp; the code is organised our own way.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <variant>
#include <vector>

#include "entropy.hpp"
#include "tinstream/laz/laszip_vlr.hpp"
#include "tinstream/laz/laz_reader.hpp"

namespace tinstream::laz::detail {

// ---------------------------------------------------------------------------------------------
// Small shared pieces

inline std::uint16_t get16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
inline std::uint32_t get32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}
inline std::uint64_t get64(const std::uint8_t* p) {
  return get32(p) | (static_cast<std::uint64_t>(get32(p + 4)) << 32);
}
inline void put16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
inline void put32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline void put64(std::uint8_t* p, std::uint64_t v) {
  put32(p, static_cast<std::uint32_t>(v));
  put32(p + 4, static_cast<std::uint32_t>(v >> 32));
}
// Two's-complement addition without signed overflow.
inline std::int32_t wrap_add(std::int32_t a, std::int32_t b) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) + static_cast<std::uint32_t>(b));
}
inline std::int32_t wrap_mul(std::int32_t a, std::int32_t b) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
}

// The running "median of five" LASzip predicts coordinate steps with. It is not the median of
// the last five values: the five slots stay sorted, and each new value evicts from the top or
// from the bottom, alternating after each value that lands on the far side of the middle.
//
// Either way the kept slots are the sorted union of the four that stay and the new value, so
// push() is a branch-free insertion: evicting the top keeps s[0..3], the bottom s[1..4].
class StreamingMedian5 {
 public:
  void reset() { *this = StreamingMedian5{}; }
  std::int32_t get() const { return s_[2]; }
  TINSTREAM_LAZ_INLINE void push(std::int32_t v) {
    const std::size_t from = evict_high_ ? 0 : 1;
    const std::int32_t a0 = s_[from], a1 = s_[from + 1], a2 = s_[from + 2], a3 = s_[from + 3];
    // The top is evicted again while values land below the middle, the bottom while they land
    // at or above it; a value on the other side switches.
    evict_high_ = evict_high_ ? v < s_[2] : !(s_[2] < v);
    s_[0] = std::min(a0, v);
    s_[1] = std::max(a0, std::min(a1, v));
    s_[2] = std::max(a1, std::min(a2, v));
    s_[3] = std::max(a2, std::min(a3, v));
    s_[4] = std::max(a3, v);
  }

 private:
  std::array<std::int32_t, 5> s_{};
  bool evict_high_ = true;
};

// Context maps from (number of returns n, return number r).
std::uint8_t return_map_3bit(std::uint32_t n, std::uint32_t r);  // 0..15, n, r < 8 (v1/v2)
std::uint8_t return_map_6ctx(std::uint32_t n, std::uint32_t r);  // 0..5, n, r < 16 (v3/v4)
inline std::uint32_t return_level(std::uint32_t n, std::uint32_t r, std::uint32_t cap) {
  const std::uint32_t d = n > r ? n - r : r - n;
  return d < cap ? d : cap;
}

// The GPS time coder of GPSTIME11 v2 and of POINT14's GPS layer (v3): up to four sequences of
// times, each with its current step; a symbol says "step times m", "new sequence", "switch to
// sequence j", or (v2 only) "unchanged".
class GpsTimeSequences {
 public:
  explicit GpsTimeSequences(bool layered);
  void reset(std::uint64_t first_time_bits);
  // Decodes the next time (as the bits of the double); `dec` is marked corrupt when a damaged
  // stream keeps switching sequences.
  TINSTREAM_LAZ_INLINE std::uint64_t decode(ArithmeticDecoder& dec);
  std::uint64_t current() const { return time_[last_]; }

  // decode() in steps of one symbol for the usual time (the step repeated: a multiplier of 1),
  // for loops that alternate two streams symbol by symbol:
  // decode(dec) == finish(dec, sym, step_class(dec, sym)) with sym = first_symbol(dec).
  static constexpr std::uint32_t kNoClass = ~0u;  // step_class(): not the usual time
  TINSTREAM_LAZ_INLINE std::uint32_t first_symbol(ArithmeticDecoder& dec);
  TINSTREAM_LAZ_INLINE std::uint32_t step_class(ArithmeticDecoder& dec, std::uint32_t sym);
  TINSTREAM_LAZ_INLINE std::uint64_t finish(ArithmeticDecoder& dec, std::uint32_t sym,
                                            std::uint32_t k);

 private:
  TINSTREAM_LAZ_INLINE void start_new_sequence(ArithmeticDecoder& dec);
  TINSTREAM_LAZ_INLINE std::int32_t decode_scaled_step(ArithmeticDecoder& dec, std::uint32_t multi);

  bool layered_;
  std::uint32_t code_full_;  // "new sequence" in the multi model
  std::uint32_t last_ = 0;   // the sequence the last time belongs to
  std::uint32_t next_ = 0;   // the sequence slot a new sequence takes
  std::array<std::uint64_t, 4> time_{};
  std::array<std::int32_t, 4> step_{};
  std::array<std::int32_t, 4> extreme_{};
  SymbolModel multi_;
  SymbolModel zero_step_;
  IntegerDecoder ic_;
};

// The RGB coder shared by RGB12 v2 and RGB14 v3/v4: which of the six bytes changed (and whether
// the three channels changed alike), then each changed byte as a difference from the previous
// byte, the red change predicting green and blue.
struct RgbModels {
  RgbModels();
  void reset();
  SymbolModel changed{128};
  std::array<SymbolModel, 6> byte_diff;
};
TINSTREAM_LAZ_INLINE void decode_rgb(ArithmeticDecoder& dec, RgbModels& m,
                                     const std::uint16_t last[3], std::uint16_t out[3]);

// ---------------------------------------------------------------------------------------------
// Pointwise items (compressors 1 and 2)

// POINT10 bytes 0..19 of formats 0-5, as fields.
struct Point10Fields {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint8_t returns = 0;  // return number (bits 0-2), number of returns (3-5), flags (6-7)
  std::uint8_t classification = 0;  // class (0-4), synthetic/key-point/withheld (5-7)
  std::uint8_t scan_angle = 0;
  std::uint8_t user_data = 0;
  std::uint16_t source_id = 0;
  void load(const std::uint8_t* p);
  void store(std::uint8_t* p) const;
};

class Point10V1 {
 public:
  Point10V1();
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  Point10Fields last_;
  std::array<std::int32_t, 3> last_dx_{}, last_dy_{};
  std::uint32_t next_slot_ = 0;
  IntegerDecoder ic_dx_, ic_dy_, ic_z_, ic_intensity_, ic_scan_angle_, ic_source_id_;
  SymbolModel changed_;
  LazyModels returns_, classification_, user_data_;
};

class Point10V2 {
 public:
  Point10V2();
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

  // decode() as steps of at most one symbol each (other_fields(): the rarely changed fields),
  // so that a loop decoding two chunks can alternate between them symbol by symbol
  // (decode_pointwise_pair). In decode()'s order: changed_fields, returns, intensity_class,
  // intensity, other_fields, x_class, x, y_class, y, z_class, z, store; `Steps` carries the
  // point's state from one step to the next.
  struct Steps {
    std::uint32_t changed = 0;  // which attributes changed (a 6-bit mask)
    std::uint32_t m = 0;        // 3-bit return map
    std::uint32_t l = 0;        // return level
    std::uint32_t single = 0;   // 1 when the point is a single return
    std::uint32_t k = 0;        // the magnitude class of the field being decoded
  };
  TINSTREAM_LAZ_INLINE void changed_fields(ArithmeticDecoder& dec, Steps& s);
  TINSTREAM_LAZ_INLINE void returns(ArithmeticDecoder& dec, Steps& s);
  TINSTREAM_LAZ_INLINE void intensity_class(ArithmeticDecoder& dec, Steps& s);
  TINSTREAM_LAZ_INLINE void intensity(ArithmeticDecoder& dec, const Steps& s);
  TINSTREAM_LAZ_INLINE void other_fields(ArithmeticDecoder& dec, const Steps& s);
  TINSTREAM_LAZ_INLINE void x_class(ArithmeticDecoder& dec, Steps& s);
  TINSTREAM_LAZ_INLINE void x(ArithmeticDecoder& dec, const Steps& s);
  TINSTREAM_LAZ_INLINE void y_class(ArithmeticDecoder& dec, Steps& s);
  TINSTREAM_LAZ_INLINE void y(ArithmeticDecoder& dec, const Steps& s);
  TINSTREAM_LAZ_INLINE void z_class(ArithmeticDecoder& dec, Steps& s);
  TINSTREAM_LAZ_INLINE void z(ArithmeticDecoder& dec, const Steps& s);
  void store(std::uint8_t* out) const { last_.store(out); }

 private:
  Point10Fields last_;
  std::array<std::uint16_t, 16> last_intensity_{};
  std::array<std::int32_t, 8> last_height_{};
  std::array<StreamingMedian5, 16> dx_median_, dy_median_;
  SymbolModel changed_;
  IntegerDecoder ic_intensity_;
  std::array<SymbolModel, 2> scan_angle_;
  IntegerDecoder ic_source_id_;
  LazyModels returns_, classification_, user_data_;
  IntegerDecoder ic_dx_, ic_dy_, ic_z_;
};

class GpsTime11V1 {
 public:
  GpsTime11V1();
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  std::uint64_t last_ = 0;
  std::int32_t last_step_ = 0;
  std::int32_t extreme_ = 0;
  SymbolModel multi_, zero_step_;
  IntegerDecoder ic_;
};

class GpsTime11V2 {
 public:
  GpsTime11V2() : seq_(false) {}
  void start(const std::uint8_t* raw) { seq_.reset(get64(raw)); }
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);
  GpsTimeSequences& sequences() { return seq_; }  // for decode_pointwise_pair's steps

 private:
  GpsTimeSequences seq_;
};

class Rgb12V1 {
 public:
  Rgb12V1();
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  std::array<std::uint8_t, 6> last_{};  // R low, R high, G low, G high, B low, B high
  SymbolModel changed_;
  IntegerDecoder ic_;
};

class Rgb12V2 {
 public:
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  std::uint16_t last_[3] = {0, 0, 0};
  RgbModels models_;
};

// Extra bytes (BYTE v1: integer-coded per byte; v2: a difference symbol per byte).
class ByteV1 {
 public:
  explicit ByteV1(std::size_t count);
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  std::vector<std::uint8_t> last_;
  IntegerDecoder ic_;
};

class ByteV2 {
 public:
  explicit ByteV2(std::size_t count);
  void start(const std::uint8_t* raw);
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  std::vector<std::uint8_t> last_;
  std::vector<SymbolModel> diff_;
};

// The 28 bytes after the descriptor index of a wave packet (formats 4, 5, 9, 10).
struct WavePacketFields {
  std::uint64_t offset = 0;
  std::uint32_t size = 0;
  std::uint32_t return_point = 0;
  std::array<std::uint32_t, 3> xyz{};
  void load(const std::uint8_t* p);
  void store(std::uint8_t* p) const;
};

// The wave packet coder of WAVEPACKET13 v1 and WAVEPACKET14 v3/v4 (one context's worth).
class WavePacketCoder {
 public:
  WavePacketCoder();
  void reset(const std::uint8_t* raw29);
  // Decodes into out29 (index byte + 28 bytes) and makes it the new state.
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out29);
  const std::uint8_t* last() const { return last_.data(); }
  void overwrite_last(const std::uint8_t* raw29) { std::memcpy(last_.data(), raw29, 29); }

 private:
  std::array<std::uint8_t, 29> last_{};
  std::int32_t last_diff_32_ = 0;
  std::uint32_t last_offset_case_ = 0;
  SymbolModel packet_index_;
  std::array<SymbolModel, 4> offset_case_;
  IntegerDecoder ic_offset_diff_, ic_packet_size_, ic_return_point_, ic_xyz_;
};

class WavePacket13V1 {
 public:
  void start(const std::uint8_t* raw) { coder_.reset(raw); }
  TINSTREAM_LAZ_INLINE void decode(ArithmeticDecoder& dec, std::uint8_t* out);

 private:
  WavePacketCoder coder_;
};

using PointwiseItem = std::variant<Point10V1, Point10V2, GpsTime11V1, GpsTime11V2, Rgb12V1, Rgb12V2,
                                   ByteV1, ByteV2, WavePacket13V1>;

// Decodes the next n records of a pointwise chunk: items[i] at byte offsets[i] of each record.
// The common item lists (POINT10 v2 with GPSTIME11 v2, RGB12 v2 and BYTE v2, in LAS order) run a
// loop compiled for that list; others dispatch per item.
void decode_pointwise(std::span<PointwiseItem> items, const std::uint16_t* offsets,
                      std::uint16_t record_length, ArithmeticDecoder& dec, std::uint8_t* out,
                      std::uint64_t n);

// Two chunks' streams decoded on one thread, n records of each. A symbol decode is a chain of
// dependent steps (division, table load, multiply, renormalise) that one stream cannot overlap
// with its next symbol; two streams' steps interleaved at the field level give the processor two
// independent chains in its out-of-order window. Only for the item lists that
// pairs_pointwise() accepts; each chunk's records come out as decode_pointwise() gives them.
bool pairs_pointwise(std::span<const PointwiseItem> items);
void decode_pointwise_pair(std::span<PointwiseItem> items_a, ArithmeticDecoder& dec_a,
                           std::uint8_t* out_a, std::span<PointwiseItem> items_b,
                           ArithmeticDecoder& dec_b, std::uint8_t* out_b,
                           const std::uint16_t* offsets, std::uint16_t record_length,
                           std::uint64_t n);

// ---------------------------------------------------------------------------------------------
// Layered items (compressor 3, versions 3 and 4)

// One layer of a layered chunk: its byte range in the chunk, and its decoder when it is read.
struct Layer {
  std::uint32_t size = 0;  // bytes, from the chunk's layer table
  bool active = false;     // asked for and non-empty: decoded point by point
  ArithmeticDecoder dec;
};

// POINT14 (formats 6-10, bytes 0..29) as fields.
struct Point14Fields {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint8_t return_number = 0, number_of_returns = 0;
  std::uint8_t class_flags = 0, scanner_channel = 0, scan_direction = 0, edge_of_line = 0;
  std::uint8_t classification = 0, user_data = 0;
  std::int16_t scan_angle = 0;
  std::uint16_t source_id = 0;
  std::uint64_t gps_time = 0;     // the double's bits
  bool gps_time_changed = false;  // coder state: did the time change at this point
  void load(const std::uint8_t* p);
  void store(std::uint8_t* p) const;
};

// Layers of POINT14, in their order in the chunk.
enum Point14Layer : std::size_t {
  kLayerXY,
  kLayerZ,
  kLayerClassification,
  kLayerFlags,
  kLayerIntensity,
  kLayerScanAngle,
  kLayerUserData,
  kLayerPointSource,
  kLayerGpsTime,
  kPoint14Layers
};

// What the XY/returns layer decodes for one point that the other layers' contexts need. A
// layered chunk is decoded a batch of points at a time, layer by layer: the XY/returns layer for
// the whole batch first (it records these), then each other layer in its own loop over the
// batch, taking point i's context from here and its own history from its channel's state.
struct Point14Context {
  static constexpr std::uint8_t kOpens = 4;  // in `channel`: the channel is new to the chunk here
  std::uint8_t channel;                      // scanner channel (bits 0-1), kOpens
  std::uint8_t from;       // the previous point's channel (a channel opening here starts from it)
  std::uint8_t returns;    // GPS time changed (bit 0), cpr (bits 1-2), scan angle changed (3),
                           // point source changed (4), return level (bits 5-7)
  std::uint8_t z_context;  // the Z integer decoder's context
  // The context LASzip hands the other items (RGB14, RGBNIR14, BYTE14, WAVEPACKET14): its point
  // reader starts each point's context at 0 (laswritepoint.cpp, lasreadpoint.cpp: `U32 context
  // = 0;` per point). The POINT14 item v3 sets it to the scanner channel only where the channel
  // switches (and at the chunk's first point, start()), so a point that stays on channel 2 is
  // coded by those items in their context 0; v4 sets it to the channel at every point. Found
  // with the LASzip-written four-channel test files (tests/data).
  std::uint8_t item_context;
};

// Points per batch: the contexts take 5 bytes a point (5 KiB), and a batch of records of up to
// ~60 bytes stays in the L2 cache while each layer's loop passes over it.
inline constexpr std::size_t kLayeredBatch = 1024;

class Point14Layered {
 public:
  Point14Layered(bool version4, const LayerSelection& selection);
  ~Point14Layered();
  std::size_t layer_count() const { return kPoint14Layers; }
  Layer& layer(std::size_t i) { return layers_[i]; }
  const Layer& layer(std::size_t i) const { return layers_[i]; }
  bool wanted(std::size_t i) const { return wanted_[i]; }
  void start(const std::uint8_t* raw);
  // Decodes the next n (<= kLayeredBatch) records' POINT14 bytes (0..29 of each record),
  // layer by layer, and keeps the points' contexts for the other items (contexts()).
  void decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n);
  const Point14Context* contexts() const { return batch_.data(); }
  // Whether the other items stay in one context over the last batch (every point's
  // item_context is the one before it).
  bool one_item_context() const { return one_item_context_; }
  // The last decoded point's channel (after start(): the chunk's first point's, which is the
  // other items' context for their start()).
  std::uint32_t channel() const { return current_; }

 private:
  struct Context;
  Context& open_context(std::uint32_t channel, const Point14Fields& from);
  template <typename... Passes>
  void decode_xy(std::uint8_t* records, std::uint16_t record_length, std::size_t n,
                 Passes&... passes);
  template <typename... Passes>
  void layer_loop(std::size_t n, Passes&... passes);

  std::array<Point14Context, kLayeredBatch> batch_{};
  bool version4_;
  bool one_item_context_ = true;
  std::uint32_t item_context_ = 0;  // the other items' context after the last point decoded
  std::array<Layer, kPoint14Layers> layers_;
  std::array<bool, kPoint14Layers> wanted_{};
  std::array<std::unique_ptr<Context>, 4> contexts_;
  std::array<bool, 4> in_use_{};
  std::uint32_t current_ = 0;
};

// The per-channel bookkeeping of the items after POINT14. Version 3 has a quirk that version 4
// fixed: at the point where the channel switches to one already used in this chunk, v3 predicts
// from (and updates) the previous channel's last item; v4 uses the new channel's own.
struct ChannelSwitch {
  std::uint32_t current = 0;
  std::array<bool, 4> in_use{};
  // Moves to `channel` and returns the channel whose last item predicts (and takes) this
  // point. A channel new in this chunk is first opened from the previous channel's last item:
  // open(new_channel, previous_channel).
  template <typename Open>
  std::uint32_t follow(std::uint32_t channel, bool version4, Open&& open) {
    std::uint32_t source = current;
    if (channel != current) {
      current = channel;
      if (!in_use[channel]) {
        open(channel, source);
        in_use[channel] = true;
        source = channel;
      } else if (version4) {
        source = channel;
      }
    }
    return source;
  }
};

class Rgb14Layered {
 public:
  Rgb14Layered(bool nir, bool version4, const LayerSelection& selection);
  std::size_t layer_count() const { return nir_ ? 2 : 1; }
  Layer& layer(std::size_t i) { return layers_[i]; }
  const Layer& layer(std::size_t i) const { return layers_[i]; }
  bool wanted(std::size_t i) const { return i == 0 ? want_rgb_ : want_nir_; }
  void start(const std::uint8_t* raw, std::uint32_t channel);
  // The next n records' item bytes at `out` (record_length apart), point i in context[i].
  void decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                    const Point14Context* context, bool one_context);

 private:
  struct Context {
    std::uint16_t last[4] = {0, 0, 0, 0};  // R, G, B, NIR
    RgbModels rgb;
    SymbolModel nir_changed{4};
    SymbolModel nir_diff_low{256}, nir_diff_high{256};
  };
  // Opens `channel` from channel `from`'s last item for layer `layer` (0 RGB, 1 NIR).
  void open(std::uint32_t channel, std::uint32_t from, std::size_t layer);

  bool nir_, version4_, want_rgb_, want_nir_;
  std::array<Layer, 2> layers_;
  std::array<std::unique_ptr<Context>, 4> contexts_;
  ChannelSwitch channels_;
};

class Byte14Layered {
 public:
  Byte14Layered(std::size_t count, bool version4, const LayerSelection& selection);
  std::size_t layer_count() const { return layers_.size(); }
  Layer& layer(std::size_t i) { return layers_[i]; }
  const Layer& layer(std::size_t i) const { return layers_[i]; }
  bool wanted(std::size_t) const { return wanted_; }
  void start(const std::uint8_t* raw, std::uint32_t channel);
  void decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                    const Point14Context* context, bool one_context);

 private:
  struct Context {
    std::vector<std::uint8_t> last;
    std::vector<SymbolModel> diff;
  };
  Context& create(std::uint32_t channel);
  // Opens `channel` from channel `from`'s last byte `byte` (its layer).
  void open(std::uint32_t channel, std::uint32_t from, std::size_t byte);
  template <bool kOneContext, std::size_t kWidth>
  void decode_group(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                    const Point14Context* context, std::size_t b);

  std::size_t count_;
  bool version4_, wanted_;
  std::vector<Layer> layers_;
  std::array<std::unique_ptr<Context>, 4> contexts_;
  ChannelSwitch channels_;
};

class WavePacket14Layered {
 public:
  WavePacket14Layered(bool version4, const LayerSelection& selection);
  std::size_t layer_count() const { return 1; }
  Layer& layer(std::size_t) { return layer_; }
  const Layer& layer(std::size_t) const { return layer_; }
  bool wanted(std::size_t) const { return wanted_; }
  void start(const std::uint8_t* raw, std::uint32_t channel);
  void decode_batch(std::uint8_t* out, std::uint16_t record_length, std::size_t n,
                    const Point14Context* context, bool one_context);

 private:
  void decode(std::uint8_t* out, std::uint32_t channel);

  bool version4_, wanted_;
  Layer layer_;
  std::array<std::unique_ptr<WavePacketCoder>, 4> contexts_;
  ChannelSwitch channels_;
};

using LayeredItem = std::variant<Rgb14Layered, Byte14Layered, WavePacket14Layered>;

// Decodes the next n records of a layered chunk: POINT14 at byte 0 of each record, items[i] at
// byte offsets[i + 1]. Batch by batch (kLayeredBatch points), and in a batch layer by layer:
// each layer's loop keeps its one decoder in registers and its models in cache.
void decode_layered(Point14Layered& point14, std::span<LayeredItem> items,
                    const std::uint16_t* offsets, std::uint16_t record_length, std::uint8_t* out,
                    std::uint64_t n);

}  // namespace tinstream::laz::detail
