// tinstream/sources/point_source.hpp — streaming point readers for ingest pass 1
// (docs/DESIGN.md §3.1).
//
// Contract:
// - A PointSource reads one input file (LAS 1.0–1.4, XYZ/CSV text, or any GDAL raster) and
//   hands out its points in batches, in file order, in the file's own CRS and units with
//   scale/offset applied. Memory is bounded by the batch size the caller asks for, never by
//   the size of the file.
// - Bad input never throws and never crashes: open_source() and read() return an Error whose
//   message names the file and the record (LAS point number, text line, raster row/column).
// - A PointSource is not thread-safe; use one per thread. It owns its file handle.
// - Several inputs of mixed formats: open each with open_source() and loop; SourceInfo and
//   SourceCounters are plain values, so per-input summaries are easy to keep.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::sources {

// One accepted point. Coordinates are in the source CRS units with scale/offset applied.
struct SourcePoint {
  double x = 0;
  double y = 0;
  double z = 0;
  // 1-based record number in the file: LAS point index, text line number, or raster cell
  // index (row * width + column + 1). Lets later stages name the record in their errors.
  std::uint64_t record = 0;
  std::uint8_t classification = 0;  // ASPRS class (LAS); 0 where the format has none
};

// A linear unit: its name and how many metres one unit is.
struct LinearUnit {
  std::string name;     // "metre", "foot", "US survey foot", …
  double to_metre = 1;  // 1, 0.3048, 1200/3937, …
};

// Axis-aligned bounds in source units (cell centres for rasters). min_z/max_z are NaN when the
// file does not say (rasters without statistics).
struct SourceBounds {
  double min_x = 0, min_y = 0, min_z = 0;
  double max_x = 0, max_y = 0, max_z = 0;
};

// What a source knows about itself before any point is read.
struct SourceInfo {
  std::string path;
  std::string format;  // "LAS 1.2 PDF 3", "XYZ", "GDAL GTiff", …
  // Horizontal (or full) CRS as the file states it: "EPSG:n", WKT, or a PROJ string; empty
  // when the file has none (ESRI ASCII grids, XYZ text) — then the caller must give one.
  std::string crs;
  std::string crs_origin;            // where `crs` came from: "LAS WKT VLR", "LAS GeoKeys", "GDAL"
  std::string vertical_crs;          // informational ("EPSG:5103" from a LAS VerticalCSTypeGeoKey)
  std::optional<LinearUnit> z_unit;  // explicit vertical unit stated by the file, if any
  // Records the reader will visit (LAS points, raster cells); unknown for text. Use it as the
  // progress total. Accepted points may be fewer (class filter, NODATA).
  std::optional<std::uint64_t> record_count;
  std::optional<SourceBounds> bounds;  // from the header / geotransform, if the file says
  std::vector<std::string> notes;      // human-readable remarks (rules applied, quirks found)
};

// Per-source counters; records_read = accepted + rejected_class + rejected_nodata +
// rejected_invalid (+ rejected_withheld).
struct SourceCounters {
  std::uint64_t records_read = 0;
  std::uint64_t accepted = 0;
  std::uint64_t rejected_class = 0;     // dropped by the classification filter
  std::uint64_t rejected_withheld = 0;  // LAS points flagged "withheld" (deleted)
  std::uint64_t rejected_nodata = 0;    // raster NODATA / NaN cells
  std::uint64_t rejected_invalid = 0;   // bad records skipped under InvalidPolicy::skip
};

enum class SourceFormat { automatic, las, xyz, raster };

// What to do with a record that cannot be used (NaN/inf coordinate, malformed text line).
enum class InvalidPolicy {
  fail,  // default: read() returns an Error naming the file and the record
  skip,  // count it in SourceCounters::rejected_invalid and go on
};

// Classification filter (LAS, and XYZ with a class column). The rule, verbatim as the CLI's
// --help prints it (kClassFilterRule):
//   * If `classes` is given, keep exactly those ASPRS classes.
//   * Otherwise, for LAS: if the file holds at least one ground point (class 2, not withheld),
//     keep only class 2 (bare earth); otherwise keep every class except noise (7 low noise,
//     18 high noise). Whether ground exists is decided by a scan of the class byte of the
//     records before the first batch is read; the scan stops at the first ground point, so it
//     is cheap for classified files and one extra sequential read for unclassified ones.
//     (LAS header return counts say nothing about classes, hence the scan.)
//   * XYZ with a class column: every class except 7 and 18 (no pre-scan of text files).
//   * Points flagged "withheld" in LAS are always dropped (the spec calls them deleted).
inline constexpr std::string_view kClassFilterRule =
    "Classes kept: with --classes, exactly those ASPRS classes. Otherwise, for LAS: if the file "
    "has any ground point (class 2), only class 2 (bare earth); if it has none, every class "
    "except noise (7 and 18). For text with a class column: every class except 7 and 18. "
    "LAS points flagged withheld are always dropped.";
struct ClassFilter {
  std::optional<std::vector<std::uint8_t>> classes;
};

// XYZ/CSV text layout.
struct TextLayout {
  // Field delimiter; nullopt = any run of spaces/tabs. With a delimiter char (',' ';' '\t' …)
  // every occurrence separates fields and surrounding spaces are trimmed.
  std::optional<char> delimiter;
  std::size_t x_column = 0, y_column = 1, z_column = 2;  // 0-based
  std::optional<std::size_t> class_column;
  // Lines to skip at the top. nullopt = automatic: the first non-comment line is skipped as a
  // header when none of its x/y/z fields parses as a number.
  std::optional<std::size_t> header_lines;
  char comment = '#';  // lines whose first non-blank char is this are ignored; so are blank lines
};

// What GDAL may open for a raster input, and how big it may be (ingest confinement). The caller
// states it: the CLI keeps the default (the user's own files, anywhere on the local disk); the
// server's admin ingest uses RasterPolicy::confined(data_root). Whatever the policy:
// - only the listed GDAL drivers open an input; names beginning with /vsi (archives, network)
//   are refused, and GDAL's HTTP access is off (CPL_VSIL_CURL_ALLOWED_EXTENSIONS);
// - a VRT (when "VRT" is listed) is read as XML first and accepted only when every element is
//   one a plain mosaic or subset needs (bands, simple/complex/averaged sources, NODATA, scale,
//   metadata): raw bands (a file read at any offset), derived bands (pixel functions), warped
//   and pansharpened VRTs, overviews, masks, GCPs and open options are refused; every
//   SourceFilename must be a local regular file (no /vsi, no connection string) that one of the
//   listed drivers other than VRT opens, and under `root` when it is set;
// - the raster, its blocks and every VRT source are checked against the size limits below
//   before any buffer is allocated for them (a VRT declaring a 2^31-wide raster fails cleanly).
struct RasterPolicy {
  // GDAL drivers (short names) an input may be opened with. Elevation formats only.
  std::vector<std::string> drivers = {"GTiff", "AAIGrid", "SRTMHGT", "EHdr", "USGSDEM",
                                      "GSAG",  "GSBG",    "GS7BG",   "BT",   "VRT"};
  // Non-empty: the input and every file a VRT names must resolve (symlinks followed) to a
  // regular file under this directory. Empty: anywhere on the local file system.
  std::filesystem::path root;
  int max_width = 1 << 22;   // cells per row: the reader's strip buffer holds one row at least
  int max_height = 1 << 22;  // rows
  std::uint64_t max_cells = std::uint64_t{1} << 36;         // width × height (6.9e10)
  std::uint64_t max_block_bytes = std::uint64_t{64} << 20;  // one GDAL block of one band
  std::uint64_t max_vrt_bytes = std::uint64_t{16} << 20;    // a VRT's XML text

  // The admin API's policy: files under `root` only; VRTs only when `allow_vrt`.
  static RasterPolicy confined(std::filesystem::path root, bool allow_vrt = true) {
    RasterPolicy p;
    p.root = std::move(root);
    if (!allow_vrt) std::erase(p.drivers, std::string("VRT"));
    return p;
  }
};

struct SourceOptions {
  SourceFormat format = SourceFormat::automatic;
  ClassFilter class_filter;
  InvalidPolicy invalid = InvalidPolicy::fail;
  TextLayout text;
  int raster_band = 1;  // 1-based GDAL band
  // LAZ: threads decoding chunks ahead of read() (0: one per core, at most 8; 1: none).
  unsigned decode_threads = 0;
  RasterPolicy raster;  // what GDAL may open (rasters only)
};

class PointSource {
 public:
  virtual ~PointSource();
  PointSource(const PointSource&) = delete;
  PointSource& operator=(const PointSource&) = delete;

  virtual const SourceInfo& info() const = 0;
  // Appends up to max_points accepted points to `batch` (it is not cleared). Returns the number
  // appended; 0 means the end of the source. After an Error the source stays at the error.
  // Requires: max_points > 0.
  virtual Result<std::size_t> read(std::vector<SourcePoint>& batch, std::size_t max_points) = 0;
  virtual const SourceCounters& counters() const = 0;

 protected:
  PointSource() = default;
};

// Opens a source. Format: SourceOptions::format, else by extension (.las, .laz and .copc.laz;
// .xyz .csv .txt .pts → text), else by magic ("LASF"), else any raster GDAL opens. LAZ files
// (LASzip-compressed LAS, any point format, COPC included) read exactly like LAS. Errors name
// the file.
Result<std::unique_ptr<PointSource>> open_source(const std::filesystem::path& path,
                                                 const SourceOptions& options = {});

Result<std::unique_ptr<PointSource>> open_las(const std::filesystem::path& path,
                                              const SourceOptions& options = {});
Result<std::unique_ptr<PointSource>> open_xyz(const std::filesystem::path& path,
                                              const SourceOptions& options = {});
Result<std::unique_ptr<PointSource>> open_raster(const std::filesystem::path& path,
                                                 const SourceOptions& options = {});

// Parses "metre"/"m", "foot"/"ft", "us-foot"/"ftUS" (and a few spellings) into a LinearUnit.
Result<LinearUnit> parse_linear_unit(const std::string& text);

// Parses a comma-separated class list ("2,9") for ClassFilter::classes.
Result<std::vector<std::uint8_t>> parse_class_list(const std::string& text);

}  // namespace tinstream::sources
