// Writes the generated LAZ test files of this folder and their uncompressed twins with LASzip
// (rapidlasso's reference implementation, Apache-2.0), not with our code: the decoder's tests
// compare our decode of each .laz with the records of its .las twin. Not part of the build
// (LASzip is not packaged in Debian 12); README.md here says how it was built and run.
//   make_laz_cases OUT_DIR
// The points are synthetic but shaped like an airborne multi-channel scan: pulses of 1..15
// returns sharing a GPS time, each scanner channel with its own scan line, channel switches
// mid-chunk and at chunk starts, classes above 31, all four classification flags, extra bytes
// whose columns vary differently (constant, counter, random, a float).
#include <laszip_api.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct Rng {  // splitmix64: the same files on every machine
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  int below(int n) { return static_cast<int>(next() % static_cast<std::uint64_t>(n)); }
  double unit() { return static_cast<double>(next() >> 11) / 9007199254740992.0; }
};

struct Case {
  const char* name;
  int version_minor;
  int format;
  int extra_bytes;
  int chunk_size;
  int points;
  int channels;     // scanner channels used (1 = legacy formats)
  int max_returns;  // 7 for formats 0-5, up to 15 for 6-10
  // The item versions LASzip is asked for (0: its default, v2 for formats 0-5, v3 for 6-10).
  // v4 for LAS 1.4 needs the one-line change of README.md (LASzip's API picks v4 only for LAS
  // 1.5 headers); the points are those of the v3 file with the same format and extra bytes.
  // v1 (formats 0-5: POINT10, GPSTIME11, RGB12, BYTE) needs the same change.
  int item_version = 0;
  // Chunk size 0: LASzip's compressor 1 (pointwise, no chunks), which its API does not offer
  // (the second change of README.md); otherwise compressor 2 or 3.
};

const Case kCases[] = {
    {"laz_gen_f1_eb7", 2, 1, 7, 1000, 2500, 1, 7},
    {"laz_gen_f6_eb7_4ch", 4, 6, 7, 1000, 2500, 4, 15},
    {"laz_gen_f7_eb1_4ch", 4, 7, 1, 800, 2500, 4, 15},
    {"laz_gen_f10_eb2_4ch", 4, 10, 2, 900, 2500, 4, 15},
    {"laz_gen_f7_eb1_4ch_v4", 4, 7, 1, 800, 2500, 4, 15, 4},
    {"laz_gen_f10_eb2_4ch_v4", 4, 10, 2, 900, 2500, 4, 15, 4},
    {"laz_gen_f0_eb1", 2, 0, 1, 500, 1500, 1, 7},
    {"laz_gen_f2_eb0", 2, 2, 0, 500, 1500, 1, 7},
    {"laz_gen_f4_eb3", 3, 4, 3, 700, 1500, 1, 7},
    {"laz_gen_f5_eb0", 3, 5, 0, 700, 1500, 1, 7},
    {"laz_gen_f8_eb7_4ch", 4, 8, 7, 600, 1500, 4, 15},
    {"laz_gen_f9_eb0_4ch", 4, 9, 0, 600, 1500, 4, 15},
    {"laz_gen_f9_eb0_4ch_v4", 4, 9, 0, 600, 1500, 4, 15, 4},
    {"laz_gen_f3_eb2_v1_nochunks", 2, 3, 2, 0, 1500, 1, 7, 1},
    {"laz_gen_f5_eb1_v1", 3, 5, 1, 500, 1500, 1, 7, 1},
    // Small seeds for laz_fuzzer (core/sources/laz/fuzz/corpus): three chunks of 20 points.
    {"seed_f10_eb2_4ch", 4, 10, 2, 20, 60, 4, 15},
    {"seed_f10_eb2_4ch_v4", 4, 10, 2, 20, 60, 4, 15, 4},
    {"seed_f5_eb3", 3, 5, 3, 20, 60, 1, 7},
};

int base_length(int format) {
  switch (format) {
    case 0:
      return 20;
    case 1:
      return 28;
    case 2:
      return 26;
    case 3:
      return 34;
    case 4:
      return 57;
    case 5:
      return 63;
    case 6:
      return 30;
    case 7:
      return 36;
    case 8:
      return 38;
    case 9:
      return 59;
    case 10:
      return 67;
    default:
      return -1;
  }
}

bool check(laszip_POINTER z, int rc, const char* what) {
  if (rc == 0) return true;
  laszip_CHAR* error = nullptr;
  laszip_get_error(z, &error);
  std::fprintf(stderr, "%s: %s\n", what, error ? error : "?");
  return false;
}

struct Point {
  laszip_point p;
  std::vector<laszip_U8> extra;
};

std::vector<Point> make_points(const Case& c, Rng& rng) {
  struct Head {  // one scanner channel: its own line position, angle sweep and clock
    double x, y, heading, angle, t;
  };
  Head heads[4];
  for (int h = 0; h < 4; ++h) {
    heads[h] = {500.0 + 40.0 * h, 800.0 - 25.0 * h, 0.3 + 0.4 * h, -20.0 + 10.0 * h,
                250000.0 + 0.37 * h};
  }
  std::vector<Point> out;
  int channel = 0;
  std::uint32_t counter = 0;
  std::uint64_t wave_offset = 0;
  while (static_cast<int>(out.size()) < c.points) {
    // A channel switch every ~12 pulses, and at the start of some chunks.
    const bool chunk_start =
        c.chunk_size > 0 && out.size() % static_cast<std::size_t>(c.chunk_size) == 0;
    if (c.channels > 1 && (rng.below(12) == 0 || (chunk_start && out.size() > 0))) {
      channel = (channel + 1 + rng.below(c.channels - 1)) % c.channels;
    }
    Head& head = heads[channel];
    head.t += 1.0e-5 * (1 + rng.below(3));
    head.angle += 0.7;
    if (head.angle > 25.0) {  // next scan line
      head.angle = -25.0;
      head.x += 0.8 * std::cos(head.heading);
      head.y += 0.8 * std::sin(head.heading);
    }
    const double along = head.angle * 0.6;
    const double gx = head.x - along * std::sin(head.heading);
    const double gy = head.y + along * std::cos(head.heading);
    const double ground = 120.0 + 6.0 * std::sin(gx * 0.02) + 3.0 * std::cos(gy * 0.03);
    int n = 1;
    if (rng.below(4) == 0) n = 2 + rng.below(c.max_returns - 1);  // vegetation: several returns
    const bool oddity = rng.below(100) == 0;  // returns 0 of 0, as some real files have
    for (int r = 1; r <= n && static_cast<int>(out.size()) < c.points; ++r) {
      Point pt;
      std::memset(&pt.p, 0, sizeof(pt.p));
      const double z = r == n ? ground + 0.05 * (rng.unit() - 0.5) : ground + 18.0 * rng.unit();
      pt.p.X = static_cast<laszip_I32>(std::lround((gx + 0.02 * rng.unit()) * 1000.0));
      pt.p.Y = static_cast<laszip_I32>(std::lround((gy + 0.02 * rng.unit()) * 1000.0));
      pt.p.Z = static_cast<laszip_I32>(std::lround(z * 1000.0));
      pt.p.intensity =
          static_cast<laszip_U16>(r == n ? 900 + rng.below(300) : 100 + rng.below(600));
      pt.p.scan_direction_flag = (counter / 37) & 1;
      pt.p.edge_of_flight_line = head.angle > 24.0;
      pt.p.user_data = static_cast<laszip_U8>(channel * 16 + (r == 1));
      pt.p.point_source_ID = static_cast<laszip_U16>(7 + channel + (counter > 1700));
      pt.p.gps_time = head.t;
      const int cls_table[] = {2, 2, 2, 3, 4, 5, 6, 1, 9, 40, 64, 255};
      int cls = r == n ? 2 : cls_table[3 + rng.below(9)];
      if (c.format < 6 && cls > 31) cls = 1;
      const int flags = rng.below(10) == 0 ? rng.below(16) : 0;
      if (c.format >= 6) {
        pt.p.extended_point_type = 1;  // as LASzip's writer sets it for formats 6-10
        pt.p.extended_return_number = static_cast<laszip_U8>(oddity ? 0 : r);
        pt.p.extended_number_of_returns = static_cast<laszip_U8>(oddity ? 0 : n);
        pt.p.extended_scanner_channel = static_cast<laszip_U8>(channel);
        pt.p.extended_classification = static_cast<laszip_U8>(cls);
        pt.p.extended_classification_flags = static_cast<laszip_U8>(flags);
        pt.p.extended_scan_angle = static_cast<laszip_I16>(std::lround(head.angle / 0.006));
        pt.p.classification = static_cast<laszip_U8>(cls < 32 ? cls : 0);
        pt.p.synthetic_flag = flags & 1;
        pt.p.keypoint_flag = (flags >> 1) & 1;
        pt.p.withheld_flag = (flags >> 2) & 1;
        pt.p.return_number = static_cast<laszip_U8>(oddity ? 0 : std::min(r, 7));
        pt.p.number_of_returns = static_cast<laszip_U8>(oddity ? 0 : std::min(n, 7));
      } else {
        pt.p.return_number = static_cast<laszip_U8>(oddity ? 0 : r);
        pt.p.number_of_returns = static_cast<laszip_U8>(oddity ? 0 : n);
        pt.p.classification = static_cast<laszip_U8>(cls);
        pt.p.synthetic_flag = flags & 1;
        pt.p.keypoint_flag = (flags >> 1) & 1;
        pt.p.withheld_flag = (flags >> 2) & 1;
        pt.p.scan_angle_rank = static_cast<laszip_I8>(std::lround(head.angle));
      }
      const int f = c.format;
      if (f == 8 || f == 10) {  // NIR
        pt.p.rgb[3] = static_cast<laszip_U16>(r == n ? 30000 + rng.below(2000) : rng.below(65536));
      }
      if (f == 4 || f == 5 || f == 9 || f == 10) {
        // A waveform packet: descriptor, offset, size, return location, dx/dy/dz.
        const std::uint8_t descriptor = static_cast<std::uint8_t>(1 + channel % 3);
        const std::uint32_t size = rng.below(20) == 0 ? 512u : 256u;
        const float location = static_cast<float>(1000.0 + 3.0 * r + rng.unit());
        const float d[3] = {static_cast<float>(1e-5 * (channel + 1)),
                            static_cast<float>(-2e-5 * channel), -1.5e-4f};
        pt.p.wave_packet[0] = descriptor;
        std::memcpy(&pt.p.wave_packet[1], &wave_offset, 8);
        std::memcpy(&pt.p.wave_packet[9], &size, 4);
        std::memcpy(&pt.p.wave_packet[13], &location, 4);
        std::memcpy(&pt.p.wave_packet[17], d, 12);
        wave_offset += size;
      }
      if (f == 2 || f == 3 || f == 5 || f == 7 || f == 8 || f == 10) {  // RGB
        const int shade = static_cast<int>((z - 110.0) * 2000.0);
        pt.p.rgb[0] = static_cast<laszip_U16>(std::clamp(shade, 0, 65535));
        pt.p.rgb[1] = static_cast<laszip_U16>(std::clamp(shade + rng.below(4000), 0, 65535));
        pt.p.rgb[2] = static_cast<laszip_U16>(rng.below(8) == 0 ? rng.below(65536) : 20000);
      }
      pt.extra.resize(static_cast<std::size_t>(c.extra_bytes));
      if (c.extra_bytes == 1) {
        pt.extra[0] = static_cast<laszip_U8>(r == n ? 200 + rng.below(20) : rng.below(256));
      } else if (c.extra_bytes == 2) {
        pt.extra[0] = static_cast<laszip_U8>(channel * 60 + rng.below(4));
        pt.extra[1] = static_cast<laszip_U8>(counter >> 4);
      } else if (c.extra_bytes >= 3) {
        pt.extra[0] = 0x2A;                                    // constant
        pt.extra[1] = static_cast<laszip_U8>(counter);         // counter
        pt.extra[2] = static_cast<laszip_U8>(rng.below(256));  // noise
        if (c.extra_bytes >= 7) {
          const float deviation = static_cast<float>(z - ground);  // a float32 column
          std::memcpy(&pt.extra[3], &deviation, 4);
        }
      }
      out.push_back(std::move(pt));
      ++counter;
    }
  }
  return out;
}

bool write(const Case& c, const std::vector<Point>& points, const std::string& path,
           bool compress) {
  laszip_POINTER z = nullptr;
  if (laszip_create(&z)) return false;
  laszip_header* h = nullptr;
  laszip_get_header_pointer(z, &h);
  h->version_major = 1;
  h->version_minor = static_cast<laszip_U8>(c.version_minor);
  h->header_size = c.version_minor == 4 ? 375 : (c.version_minor == 3 ? 235 : 227);
  h->offset_to_point_data = h->header_size;
  h->point_data_format = static_cast<laszip_U8>(c.format);
  h->point_data_record_length = static_cast<laszip_U16>(base_length(c.format) + c.extra_bytes);
  std::snprintf(h->generating_software, 32, "tinstream make_laz_cases");
  std::snprintf(h->system_identifier, 32, "synthetic");
  h->file_creation_day = 333;
  h->file_creation_year = 2026;
  h->x_scale_factor = h->y_scale_factor = h->z_scale_factor = 0.001;
  h->min_x = h->min_y = h->min_z = 1e300;
  h->max_x = h->max_y = h->max_z = -1e300;
  std::uint64_t by_return[15] = {};
  for (const Point& pt : points) {
    const double x = pt.p.X * 0.001, y = pt.p.Y * 0.001, zz = pt.p.Z * 0.001;
    h->min_x = std::min(h->min_x, x), h->max_x = std::max(h->max_x, x);
    h->min_y = std::min(h->min_y, y), h->max_y = std::max(h->max_y, y);
    h->min_z = std::min(h->min_z, zz), h->max_z = std::max(h->max_z, zz);
    const int r = c.format >= 6 ? pt.p.extended_return_number : pt.p.return_number;
    if (r >= 1 && r <= 15) ++by_return[r - 1];
  }
  if (c.format >= 6) {
    h->number_of_point_records = 0;
    h->extended_number_of_point_records = points.size();
    for (int i = 0; i < 15; ++i) h->extended_number_of_points_by_return[i] = by_return[i];
  } else {
    h->number_of_point_records = static_cast<laszip_U32>(points.size());
    for (int i = 0; i < 5; ++i)
      h->number_of_points_by_return[i] = static_cast<laszip_U32>(by_return[i]);
  }
  if (compress && c.item_version) {
    setenv("LASZIP_REQUEST_VERSION", std::to_string(c.item_version).c_str(), 1);
  } else {
    unsetenv("LASZIP_REQUEST_VERSION");
  }
  if (compress && c.chunk_size == 0) {
    setenv("LASZIP_REQUEST_COMPRESSOR", "1", 1);
  } else {
    unsetenv("LASZIP_REQUEST_COMPRESSOR");
  }
  bool ok =
      check(z, laszip_request_native_extension(z, 1), "native extension") &&
      (c.chunk_size == 0 ||
       check(z, laszip_set_chunk_size(z, static_cast<laszip_U32>(c.chunk_size)), "chunk size")) &&
      check(z, laszip_open_writer(z, path.c_str(), compress ? 1 : 0), "open writer");
  laszip_point* p = nullptr;
  laszip_get_point_pointer(z, &p);
  for (std::size_t i = 0; ok && i < points.size(); ++i) {
    laszip_U8* extra = p->extra_bytes;
    const laszip_I32 n_extra = p->num_extra_bytes;
    *p = points[i].p;
    p->extra_bytes = extra;
    p->num_extra_bytes = n_extra;
    if (n_extra != c.extra_bytes) {
      std::fprintf(stderr, "%s: LASzip set up %d extra bytes, not %d\n", path.c_str(), n_extra,
                   c.extra_bytes);
      ok = false;
      break;
    }
    std::memcpy(extra, points[i].extra.data(), points[i].extra.size());
    ok = check(z, laszip_write_point(z), "write point");
  }
  ok = ok && check(z, laszip_close_writer(z), "close writer");
  laszip_destroy(z);
  return ok;
}

// LASzip reads the .laz back and writes it uncompressed: must equal the direct .las twin.
bool round_trip(const Case& c, const std::string& laz, const std::string& las) {
  laszip_POINTER r = nullptr;
  laszip_create(&r);
  laszip_BOOL compressed = 0;
  if (!check(r, laszip_open_reader(r, laz.c_str(), &compressed), "open reader")) return false;
  laszip_header* h = nullptr;
  laszip_get_header_pointer(r, &h);
  const laszip_I64 count =
      static_cast<laszip_I64>(h->number_of_point_records ? h->number_of_point_records
                                                         : h->extended_number_of_point_records);
  laszip_point* p = nullptr;
  laszip_get_point_pointer(r, &p);
  std::vector<Point> back;
  for (laszip_I64 i = 0; i < count; ++i) {
    if (!check(r, laszip_read_point(r), "read point")) return false;
    Point pt;
    pt.p = *p;
    pt.extra.assign(p->extra_bytes, p->extra_bytes + p->num_extra_bytes);
    pt.p.extra_bytes = nullptr;
    back.push_back(std::move(pt));
  }
  laszip_close_reader(r);
  laszip_destroy(r);
  if (count != c.points) {
    std::fprintf(stderr, "%s: LASzip reads %lld points back, not %d\n", laz.c_str(),
                 static_cast<long long>(count), c.points);
    return false;
  }
  return compressed && write(c, back, las, false);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_laz_cases OUT_DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  for (const Case& c : kCases) {
    Rng rng{0x7157ull * static_cast<std::uint64_t>(c.format + 1) +
            static_cast<std::uint64_t>(c.extra_bytes)};
    const std::vector<Point> points = make_points(c, rng);
    const std::string base = dir + "/" + c.name;
    if (!write(c, points, base + ".laz", true) || !write(c, points, base + ".las", false) ||
        !round_trip(c, base + ".laz", "/tmp/" + std::string(c.name) + ".roundtrip.las")) {
      return 1;
    }
    std::printf("%s: %zu points\n", c.name, points.size());
  }
  return 0;
}
