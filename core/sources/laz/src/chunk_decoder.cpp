#include "chunk_decoder.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "chunk_table.hpp"

namespace tinstream::laz::detail {

bool read_at(int fd, std::uint64_t offset, void* dst, std::size_t n) {
  auto* p = static_cast<std::uint8_t*>(dst);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    p += got;
    n -= static_cast<std::size_t>(got);
    offset += static_cast<std::uint64_t>(got);
  }
  return true;
}

bool FileWindow::next_window(const std::uint8_t** begin, const std::uint8_t** end) {
  if (failed_ || pos_ >= end_) return false;
  const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(end_ - pos_, kWindowBytes));
  if (buffer_.size() < n) buffer_.resize(n);
  if (!read_at(fd_, pos_, buffer_.data(), n)) {
    failed_ = true;
    return false;
  }
  pos_ += n;
  *begin = buffer_.data();
  *end = buffer_.data() + n;
  return true;
}

ChunkDecoder::ChunkDecoder(const LaszipVlr& vlr, std::uint16_t record_length,
                           const LayerSelection& layers, int fd)
    : layered_(vlr.compressor == Compressor::layered_chunked),
      record_length_(record_length),
      fd_(fd),
      first_(record_length) {
  std::uint16_t offset = 0;
  for (const LaszipItem& item : vlr.items) {
    offsets_.push_back(offset);
    sizes_.push_back(item.size);
    offset = static_cast<std::uint16_t>(offset + item.size);
    const bool v4 = item.version == 4;
    // parse_laszip_vlr() has checked types, sizes, versions and their order.
    switch (item.type) {
      case ItemType::point10:
        if (item.version == 1) {
          pointwise_.emplace_back(std::in_place_type<Point10V1>);
        } else {
          pointwise_.emplace_back(std::in_place_type<Point10V2>);
        }
        break;
      case ItemType::gpstime11:
        if (item.version == 1) {
          pointwise_.emplace_back(std::in_place_type<GpsTime11V1>);
        } else {
          pointwise_.emplace_back(std::in_place_type<GpsTime11V2>);
        }
        break;
      case ItemType::rgb12:
        if (item.version == 1) {
          pointwise_.emplace_back(std::in_place_type<Rgb12V1>);
        } else {
          pointwise_.emplace_back(std::in_place_type<Rgb12V2>);
        }
        break;
      case ItemType::byte:
        if (item.version == 1) {
          pointwise_.emplace_back(std::in_place_type<ByteV1>, item.size);
        } else {
          pointwise_.emplace_back(std::in_place_type<ByteV2>, item.size);
        }
        break;
      case ItemType::wavepacket13:
        pointwise_.emplace_back(std::in_place_type<WavePacket13V1>);
        break;
      case ItemType::point14:
        point14_ = std::make_unique<Point14Layered>(v4, layers);
        break;
      case ItemType::rgb14:
        layered_items_.emplace_back(std::in_place_type<Rgb14Layered>, false, v4, layers);
        break;
      case ItemType::rgbnir14:
        layered_items_.emplace_back(std::in_place_type<Rgb14Layered>, true, v4, layers);
        break;
      case ItemType::byte14:
        layered_items_.emplace_back(std::in_place_type<Byte14Layered>, item.size, v4, layers);
        break;
      case ItemType::wavepacket14:
        layered_items_.emplace_back(std::in_place_type<WavePacket14Layered>, v4, layers);
        break;
    }
  }
  if (layered_) {
    const std::size_t total = detail::layer_count(vlr);
    layer_sizes_.assign(total, 0);
    layer_windows_.resize(total);
  }
}

ChunkDecoder::~ChunkDecoder() = default;

std::vector<Layer*> ChunkDecoder::all_layers() {
  std::vector<Layer*> out;
  for (std::size_t i = 0; i < point14_->layer_count(); ++i) out.push_back(&point14_->layer(i));
  for (auto& item : layered_items_) {
    std::visit(
        [&](auto& it) {
          for (std::size_t i = 0; i < it.layer_count(); ++i) out.push_back(&it.layer(i));
        },
        item);
  }
  return out;
}

Result<std::pair<std::uint64_t, std::uint64_t>> ChunkDecoder::layered_extent(
    int fd, std::uint64_t offset, std::uint16_t record_length, std::size_t layers) {
  std::vector<std::uint8_t> head(record_length + 4 + 4 * layers);
  if (!read_at(fd, offset, head.data(), head.size())) {
    return corrupt_data("the file ends inside the chunk's header (" + std::to_string(head.size()) +
                        " bytes at byte " + std::to_string(offset) + ")");
  }
  const std::uint8_t* p = head.data() + record_length;
  const std::uint64_t points = get32(p);
  std::uint64_t bytes = head.size();
  for (std::size_t i = 0; i < layers; ++i) bytes += get32(p + 4 + 4 * i);
  return std::make_pair(points, bytes);
}

Status ChunkDecoder::begin(const ChunkExtent& chunk) {
  chunk_ = chunk;
  left_ = chunk.points;
  first_pending_ = chunk.points > 0;
  if (chunk.points == 0) return {};
  if (chunk.bytes < record_length_ || !read_at(fd_, chunk.offset, first_.data(), record_length_)) {
    return corrupt_data("the chunk is shorter than its first (raw) point record");
  }
  const std::uint8_t* raw = first_.data();
  if (!layered_) {
    for (std::size_t i = 0; i < pointwise_.size(); ++i) {
      std::visit([&](auto& item) { item.start(raw + offsets_[i]); }, pointwise_[i]);
    }
    header_bytes_ = record_length_;
    window_.open(fd_, chunk.offset + record_length_, chunk.offset + chunk.bytes);
    dec_.start(&window_);
    return stream_health();
  }

  // Layered: the point count and the layer table follow the raw record.
  const std::size_t layers = layer_sizes_.size();
  std::vector<std::uint8_t> table(4 + 4 * layers);
  header_bytes_ = record_length_ + table.size();
  if (chunk.bytes < header_bytes_ ||
      !read_at(fd_, chunk.offset + record_length_, table.data(), table.size())) {
    return corrupt_data("the chunk ends inside its layer table");
  }
  const std::uint32_t stated = get32(table.data());
  // LASzip and laz-perf write the chunk's point count; the LAZ specification's wording
  // ("remaining points") allows one less.
  if (stated != chunk.points && stated + std::uint64_t{1} != chunk.points) {
    return corrupt_data("the chunk's header says it holds " + std::to_string(stated) +
                        " points, the chunk table " + std::to_string(chunk.points));
  }
  std::uint64_t total = header_bytes_;
  for (std::size_t i = 0; i < layers; ++i) {
    layer_sizes_[i] = get32(table.data() + 4 + 4 * i);
    total += layer_sizes_[i];
  }
  if (chunk.exact_length ? total != chunk.bytes : total > chunk.bytes) {
    return corrupt_data("its layers add up to " + std::to_string(total) +
                        " bytes, the chunk table gives it " + std::to_string(chunk.bytes));
  }
  // Every point after the raw first one starts with a symbol of the XY/returns layer (whose
  // contexts every other layer takes): that layer cannot be empty. (Decoding an empty stream
  // would divide by its zero interval.)
  if (chunk.points > 1 && layer_sizes_[kLayerXY] == 0) {
    return corrupt_data("its XY/returns layer is empty, yet it holds " +
                        std::to_string(chunk.points) + " points");
  }
  chunk_.bytes = total;
  chunk_.exact_length = true;

  std::vector<Layer*> all = all_layers();
  std::uint64_t pos = chunk.offset + header_bytes_;
  std::size_t index = 0;
  auto open_layers = [&](auto& item) {
    for (std::size_t i = 0; i < item.layer_count(); ++i, ++index) {
      Layer& layer = item.layer(i);
      layer.size = layer_sizes_[index];
      layer.active = item.wanted(i) && layer.size > 0;
      if (layer.active) {
        layer_windows_[index].open(fd_, pos, pos + layer.size);
        layer.dec.start(&layer_windows_[index]);
      }
      pos += layer.size;
    }
  };
  open_layers(*point14_);
  for (auto& item : layered_items_) std::visit(open_layers, item);

  point14_->start(raw);
  const std::uint32_t channel = point14_->channel();
  for (std::size_t i = 0; i < layered_items_.size(); ++i) {
    std::visit([&](auto& item) { item.start(raw + offsets_[i + 1], channel); }, layered_items_[i]);
  }
  return stream_health();
}

Status ChunkDecoder::decode(std::uint8_t* out, std::uint64_t n) {
  if (n > left_) return Error(ErrorCode::internal, "asked for more records than the chunk holds");
  if (n == 0) return {};
  if (first_pending_) {
    std::memcpy(out, first_.data(), record_length_);
    out += record_length_;
    --n;
    --left_;
    first_pending_ = false;
  }
  if (layered_) {
    decode_layered(*point14_, layered_items_, offsets_.data(), record_length_, out, n);
  } else {
    decode_pointwise(pointwise_, offsets_.data(), record_length_, dec_, out, n);
  }
  left_ -= n;
  return stream_health();
}

bool ChunkDecoder::pairable() const { return !layered_ && pairs_pointwise(pointwise_); }

bool ChunkDecoder::pairs_with(const ChunkDecoder& other) const {
  return pairable() && other.pairable() && record_length_ == other.record_length_ &&
         offsets_ == other.offsets_;
}

std::pair<Status, Status> ChunkDecoder::decode_pair(ChunkDecoder& other, std::uint8_t* out,
                                                    std::uint8_t* other_out, std::uint64_t n) {
  if (n > left_ || n > other.left_ || first_pending_ != other.first_pending_) {
    const Status wrong(Error(ErrorCode::internal, "chunks decoded in lock step out of step"));
    return {wrong, wrong};
  }
  if (n == 0) return {Status{}, Status{}};
  if (first_pending_) {
    std::memcpy(out, first_.data(), record_length_);
    std::memcpy(other_out, other.first_.data(), record_length_);
    out += record_length_;
    other_out += record_length_;
    --n;
    --left_;
    --other.left_;
    first_pending_ = other.first_pending_ = false;
  }
  decode_pointwise_pair(pointwise_, dec_, out, other.pointwise_, other.dec_, other_out,
                        offsets_.data(), record_length_, n);
  left_ -= n;
  other.left_ -= n;
  return {stream_health(), other.stream_health()};
}

Status ChunkDecoder::stream_health() const {
  auto check = [](const ArithmeticDecoder& d, const char* what) -> Status {
    if (d.io_failed()) {
      return io_error(std::string("reading the ") + what +
                      " failed (file truncated or unreadable)");
    }
    if (d.overrun() > 0) {
      return corrupt_data(std::string("the ") + what +
                          " ends before its points are decoded (truncated or damaged data)");
    }
    if (d.corrupt()) {
      return corrupt_data(std::string("the ") + what + " holds values no encoder writes");
    }
    return {};
  };
  if (!layered_) return check(dec_, "compressed point stream");
  static const char* const kNames[kPoint14Layers] = {
      "XY/returns layer", "Z layer",          "classification layer", "flags layer",
      "intensity layer",  "scan angle layer", "user data layer",      "point source ID layer",
      "GPS time layer"};
  for (std::size_t i = 0; i < kPoint14Layers; ++i) {
    const Layer& layer = point14_->layer(i);
    if (layer.active) {
      if (Status st = check(layer.dec, kNames[i]); !st.ok()) return st;
    }
  }
  for (const auto& item : layered_items_) {
    Status st;
    std::visit(
        [&](const auto& it) {
          for (std::size_t i = 0; i < it.layer_count() && st.ok(); ++i) {
            if (it.layer(i).active) st = check(it.layer(i).dec, "RGB/NIR/extra-byte/wave layer");
          }
        },
        item);
    if (!st.ok()) return st;
  }
  return {};
}

Status ChunkDecoder::finish() {
  if (Status st = stream_health(); !st.ok()) return st;
  if (chunk_.points == 0) return {};
  if (!layered_) {
    if (!chunk_.exact_length) return {};
    const std::uint64_t used = header_bytes_ + dec_.consumed();
    if (used != chunk_.bytes) {
      return corrupt_data("decoding used " + std::to_string(used) + " of the chunk's " +
                          std::to_string(chunk_.bytes) + " bytes (damaged data)");
    }
    return {};
  }
  for (Layer* layer : all_layers()) {
    if (layer->active && layer->dec.consumed() != layer->size) {
      return corrupt_data("a layer's decoding used " + std::to_string(layer->dec.consumed()) +
                          " of its " + std::to_string(layer->size) + " bytes (damaged data)");
    }
  }
  return {};
}

std::uint64_t ChunkDecoder::consumed() const {
  if (!layered_) return header_bytes_ + dec_.consumed();
  return chunk_.bytes;
}

}  // namespace tinstream::laz::detail
