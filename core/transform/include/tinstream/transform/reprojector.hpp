// tinstream/transform/reprojector.hpp — source CRS → WGS84 lon/lat + ellipsoidal height (m).
//
// Contract:
// - Built once per input from the CRS the user gave (ReprojectOptions::crs) or else the file's
//   (SourceInfo::crs): an "EPSG:n" code, WKT (1 or 2, ESRI flavour too) or a PROJ string.
//   A missing or unknown CRS is an Error naming the file, never a guess.
// - Horizontal: PROJ (proj_create_crs_to_crs to EPSG:4326, normalised to lon/lat order) on the
//   horizontal part of the CRS (the first member of a compound CRS). Output longitudes are
//   wrapped to [-180, 180].
// - Vertical, the rule (also the CLI's --help):
//     z unit: the `z_unit` option if given; else the vertical unit the file states (LAS
//     VerticalUnitsGeoKey, raster unit type); else the unit of the CRS's vertical axis (compound
//     or 3D CRS); else the linear unit of the horizontal CRS when it is projected (a LAS file in
//     a feet-based projection has z in feet); else metre.
//     datum: `vertical_datum` = "ellipsoidal" (default) takes heights as already ellipsoidal;
//     "egm96", "egm2008" or a PROJ grid file name (…tif/.gtx) takes them as orthometric heights
//     above that geoid and adds the geoid undulation N from the PROJ grid: h = H + N;
//     "crs" lets PROJ convert from the source's own vertical CRS (a compound CRS such as
//     "EPSG:26910+5703", or the LAS VerticalCSTypeGeoKey) to EPSG:4979, in that CRS's vertical
//     unit (the z unit rule does not apply, and a z_unit option is refused). PROJ's own choice of
//     operation is kept only if it is not a "ballpark" (no-op) vertical transformation; when the
//     grids it needs are missing, the Error names them.
//   Why "crs" is not the default: for vertical CRSs such as NAVD88 PROJ needs grids that are
//   rarely installed; an explicit choice that fails loudly is safer than a silent no-op.
// - A geoid grid PROJ cannot find is an Error naming the grid file and how to install it.
// - Not thread-safe (it owns a PROJ context); use one Reprojector per thread. Movable.
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/sources/point_source.hpp"

namespace tinstream::transform {

// The vertical rules above in the words the CLI's --help prints.
inline constexpr std::string_view kHeightRule =
    "Heights: z is converted to metres with --z-units if given, else the unit the file states "
    "(LAS VerticalUnitsGeoKey, raster unit), else the CRS's vertical axis unit, else the linear "
    "unit of a projected CRS (a LAS file in a feet projection has z in feet), else metres. "
    "--vertical-datum ellipsoidal (default) takes heights as ellipsoidal; egm96, egm2008 or a "
    "PROJ grid file adds that geoid's undulation (orthometric to ellipsoidal); crs lets PROJ "
    "convert from the source's vertical CRS (e.g. --crs EPSG:26910+5703). A missing grid is an "
    "error that names it.";

// WGS84 geodetic position: degrees, metres above the ellipsoid.
struct GeoPoint {
  double lon = 0;
  double lat = 0;
  double h = 0;
};

struct ReprojectOptions {
  std::string crs;                            // overrides the file's CRS when not empty
  std::optional<sources::LinearUnit> z_unit;  // overrides the z unit rule
  // "ellipsoidal", "egm96", "egm2008", a geoid grid file name, or "crs" (see above). A grid file
  // name is a bare name (is_grid_file_name): PROJ finds it in its data directories; it never goes
  // into a PROJ string unchecked.
  std::string vertical_datum = "ellipsoidal";
  // The options come from an untrusted caller (the server's admin API): `crs` must be an
  // authority code (is_authority_code), and PROJ may not download grids whatever PROJ_NETWORK says.
  bool confined = false;
};

// What a Reprojector decided, for logs and run summaries.
struct ReprojectionPlan {
  std::string crs;              // the CRS text used
  std::string crs_name;         // PROJ's name for it
  std::string horizontal_unit;  // "foot", "metre", "degree", …
  sources::LinearUnit z_unit;   // how z was converted to metres
  std::string z_unit_rule;      // which rule chose z_unit
  std::string geoid_grid;       // grid(s) used for heights; empty for ellipsoidal heights
  std::vector<std::string> notes;
};

class Reprojector {
 public:
  // `info` names the file in errors and supplies the file's CRS and z unit.
  static Result<Reprojector> create(const sources::SourceInfo& info,
                                    const ReprojectOptions& options);
  Reprojector(Reprojector&&) noexcept;
  Reprojector& operator=(Reprojector&&) noexcept;
  ~Reprojector();

  const ReprojectionPlan& plan() const;

  // Replaces `out` with the transformed points, in order. Errors (a point PROJ cannot
  // transform, a point outside the geoid grid) name the file and the record.
  Status transform(std::span<const sources::SourcePoint> in, std::vector<GeoPoint>& out);

 private:
  struct Impl;
  explicit Reprojector(std::unique_ptr<Impl> impl);
  Status transform_3d(std::span<const sources::SourcePoint> in, std::vector<GeoPoint>& out);
  std::unique_ptr<Impl> impl_;
};

// The PROJ grid file names tried for a vertical datum option ("egm96" → us_nga_egm96_15.tif,
// egm96_15.gtx); a grid file name (is_grid_file_name) is itself. Empty for "ellipsoidal" and
// "crs". Anything else is invalid_argument.
Result<std::vector<std::string>> geoid_grid_candidates(const std::string& vertical_datum);

// A bare grid file name: 1-128 characters from [A-Za-z0-9._-], starting with a letter or digit,
// ending in .tif, .gtx or .gtg. No directory, no space, no '+': it cannot add a PROJ step or
// reach a file outside PROJ's data directories.
bool is_grid_file_name(std::string_view name);
// "AUTH:code" or "AUTH:code+code" (upper-case authority, decimal codes): a CRS text that cannot
// name a file.
bool is_authority_code(std::string_view crs);

}  // namespace tinstream::transform
