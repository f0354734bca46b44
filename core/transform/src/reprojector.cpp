#include "tinstream/transform/reprojector.hpp"

#include <proj.h>
#include <proj_experimental.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>

namespace tinstream::transform {
namespace {

struct ContextDeleter {
  void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
};
struct PjDeleter {
  void operator()(PJ* p) const { proj_destroy(p); }
};
using ContextPtr = std::unique_ptr<PJ_CONTEXT, ContextDeleter>;
using PjPtr = std::unique_ptr<PJ, PjDeleter>;

std::string shorten(const std::string& s, std::size_t n = 120) {
  return s.size() <= n ? s : s.substr(0, n) + "…";
}

std::string proj_message(PJ_CONTEXT* ctx) {
  const int err = proj_context_errno(ctx);
  const char* m = err != 0 ? proj_context_errno_string(ctx, err) : nullptr;
  return m != nullptr ? std::string(m) : std::string("PROJ gave no detail");
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Whether a CRS text can make PROJ open a file: a PROJ string ("+init=", "+nadgrids=", …) or a
// WKT with an EXTENSION (PROJ4, PROJ4_GRIDS). Case-insensitive.
bool may_name_files(std::string_view crs) {
  std::string lower(crs);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const auto first = lower.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && lower[first] == '+') return true;
  for (const char* word : {"extension[", "+init", "init=", "grids=", "+proj"}) {
    if (lower.find(word) != std::string::npos) return true;
  }
  return false;
}

struct AxisUnit {
  std::string name;
  double factor = 1;  // to metres (linear) or radians (angular)
  bool linear = true;
};

std::optional<AxisUnit> axis_unit(PJ_CONTEXT* ctx, const PJ* crs, int axis) {
  PjPtr cs(proj_crs_get_coordinate_system(ctx, crs));
  if (!cs || axis >= proj_cs_get_axis_count(ctx, cs.get())) return std::nullopt;
  const char* unit_name = nullptr;
  const char* unit_type = nullptr;
  double factor = 0;
  if (proj_cs_get_axis_info(ctx, cs.get(), axis, nullptr, nullptr, nullptr, &factor, &unit_name,
                            nullptr, nullptr) == 0) {
    return std::nullopt;
  }
  (void)unit_type;
  const PJ_COORDINATE_SYSTEM_TYPE type = proj_cs_get_type(ctx, cs.get());
  AxisUnit u;
  u.name = unit_name != nullptr ? unit_name : "";
  u.factor = factor;
  u.linear = !(type == PJ_CS_TYPE_ELLIPSOIDAL && axis < 2);
  return u;
}

struct ListDeleter {
  void operator()(PJ_OBJ_LIST* l) const { proj_list_destroy(l); }
};
struct FactoryDeleter {
  void operator()(PJ_OPERATION_FACTORY_CONTEXT* f) const {
    proj_operation_factory_context_destroy(f);
  }
};

// Operations from `source` (with a vertical part) to EPSG:4979, best first, with the given grid
// availability rule.
std::vector<PjPtr> candidate_operations(PJ_CONTEXT* ctx, const PJ* source, const PJ* target,
                                        PROJ_GRID_AVAILABILITY_USE grids,
                                        const std::optional<std::array<double, 4>>& area) {
  std::vector<PjPtr> out;
  std::unique_ptr<PJ_OPERATION_FACTORY_CONTEXT, FactoryDeleter> factory(
      proj_create_operation_factory_context(ctx, nullptr));
  if (!factory) return out;
  proj_operation_factory_context_set_spatial_criterion(ctx, factory.get(),
                                                       PROJ_SPATIAL_CRITERION_PARTIAL_INTERSECTION);
  proj_operation_factory_context_set_grid_availability_use(ctx, factory.get(), grids);
  if (area) {
    proj_operation_factory_context_set_area_of_interest(ctx, factory.get(), (*area)[0], (*area)[1],
                                                        (*area)[2], (*area)[3]);
  }
  std::unique_ptr<PJ_OBJ_LIST, ListDeleter> list(
      proj_create_operations(ctx, source, target, factory.get()));
  if (!list) return out;
  const int n = proj_list_get_count(list.get());
  for (int i = 0; i < n; ++i) out.emplace_back(proj_list_get(ctx, list.get(), i));
  return out;
}

std::string grids_of(PJ_CONTEXT* ctx, const PJ* op, bool missing_only) {
  std::string names;
  const int n = proj_coordoperation_get_grid_used_count(ctx, op);
  for (int i = 0; i < n; ++i) {
    const char* short_name = nullptr;
    int available = 0;
    if (proj_coordoperation_get_grid_used(ctx, op, i, &short_name, nullptr, nullptr, nullptr,
                                          nullptr, nullptr, &available) == 0) {
      continue;
    }
    if (missing_only && available != 0) continue;
    if (short_name != nullptr) names += (names.empty() ? "" : ", ") + std::string(short_name);
  }
  return names;
}

// The source CRS split into its parts. A BoundCRS (WKT1 with TOWGS84) transforms as itself; its
// units are those of its base (unit_crs).
struct SourceCrs {
  PjPtr whole;       // the CRS as given when it is compound, else null (moved into horizontal)
  PjPtr horizontal;  // its horizontal part (or the whole CRS)
  PjPtr vertical;    // its vertical part, or null
  PjPtr base;        // a BoundCRS's base, or null
  const PJ* unit_crs = nullptr;
  PJ_TYPE htype = PJ_TYPE_UNKNOWN;
  bool geographic = false;
  std::optional<AxisUnit> hunit;
};

// Untrusted options and files (options.confined): only CRS texts that cannot name files (a PROJ
// string's +init=, +nadgrids= or +geoidgrids=, WKT1's PROJ4 and PROJ4_GRIDS extensions).
Status check_confined_crs(const sources::SourceInfo& info, const ReprojectOptions& options) {
  const std::string& file = info.path;
  if (!options.crs.empty() && !is_authority_code(options.crs)) {
    return invalid_argument(file + ": CRS '" + shorten(options.crs, 60) +
                            "' refused: here a CRS is an authority code such as EPSG:32632 "
                            "or EPSG:2903+6360");
  }
  if (options.crs.empty() && may_name_files(info.crs)) {
    return unsupported(file +
                       ": the file's CRS is a PROJ string or carries a PROJ extension "
                       "(which can name grid and init files); give the CRS as an authority "
                       "code instead");
  }
  return {};
}

}  // namespace

struct Reprojector::Impl {
  ContextPtr ctx;
  PjPtr horizontal;  // source horizontal CRS → EPSG:4326, lon/lat order
  PjPtr geoid;       // lon/lat degrees + H → h, or null
  PjPtr full3d;      // vertical_datum=crs: source (x, y, z native) → lon, lat, h; else null

  Result<SourceCrs> open_crs(const sources::SourceInfo& info, const ReprojectOptions& options);
  Status plan_z_unit(const SourceCrs& crs, const sources::SourceInfo& info,
                     const ReprojectOptions& options);
  Status plan_horizontal(const SourceCrs& crs);
  Status plan_vertical_crs(const PjPtr& compound, const PjPtr& horizontal_crs, PjPtr& vertical,
                           PJ_TYPE htype, const sources::SourceInfo& info,
                           const ReprojectOptions& options);
  Status plan_geoid(const ReprojectOptions& options);
  ReprojectionPlan plan;
  std::string path;
};

// vertical_datum=crs: let PROJ go from the source's compound (or 3D) CRS to EPSG:4979.
Status Reprojector::Impl::plan_vertical_crs(const PjPtr& compound, const PjPtr& horizontal_crs,
                                            PjPtr& vertical, PJ_TYPE htype,
                                            const sources::SourceInfo& info,
                                            const ReprojectOptions& options) {
  PJ_CONTEXT* pctx = ctx.get();
  const std::string& file = info.path;
  if (options.z_unit) {
    return invalid_argument(file +
                            ": a z unit cannot be combined with vertical_datum=crs: PROJ "
                            "takes heights in the vertical CRS's own unit");
  }
  PjPtr source3d;
  if (vertical && compound) {
    source3d.reset(proj_clone(pctx, compound.get()));
  } else if (htype == PJ_TYPE_GEOGRAPHIC_3D_CRS) {
    source3d.reset(proj_clone(pctx, horizontal_crs.get()));
  } else if (!info.vertical_crs.empty() && options.crs.empty()) {
    PjPtr v(proj_create(pctx, info.vertical_crs.c_str()));
    if (!v || proj_get_type(v.get()) != PJ_TYPE_VERTICAL_CRS) {
      return unsupported(
          file + ": the file's vertical CRS code " + info.vertical_crs +
          " is not a vertical CRS that PROJ knows (LAS writers sometimes store the datum code, "
          "e.g. EPSG:5103 for NAVD88, whose height CRSs are EPSG:5703 in metres and EPSG:6360 "
          "in US feet): give a compound CRS with --crs, e.g. EPSG:2903+6360");
    }
    source3d.reset(proj_create_compound_crs(pctx, "source", horizontal_crs.get(), v.get()));
    vertical = std::move(v);
  }
  if (!source3d) {
    return invalid_argument(file +
                            ": vertical_datum=crs needs a vertical CRS: give a compound "
                            "CRS such as EPSG:32633+5773 with --crs");
  }
  const PJ* vcrs = vertical ? vertical.get() : source3d.get();
  const std::string vname = proj_get_name(vcrs) != nullptr ? proj_get_name(vcrs) : "?";
  if (auto vu = axis_unit(pctx, vcrs, vertical ? 0 : 2)) {
    plan.z_unit = sources::LinearUnit{vu->name, vu->factor};
  }
  plan.z_unit_rule = "the vertical CRS (" + vname + "), converted by PROJ";
  plan.notes.clear();

  // Area of interest from the file's bounds, so that PROJ picks the operation valid there.
  std::optional<std::array<double, 4>> area;
  if (info.bounds) {
    PJ_COORD corners[4] = {proj_coord(info.bounds->min_x, info.bounds->min_y, 0, 0),
                           proj_coord(info.bounds->max_x, info.bounds->min_y, 0, 0),
                           proj_coord(info.bounds->min_x, info.bounds->max_y, 0, 0),
                           proj_coord(info.bounds->max_x, info.bounds->max_y, 0, 0)};
    std::array<double, 4> a = {180, 90, -180, -90};
    bool ok = true;
    for (PJ_COORD& c : corners) {
      c = proj_trans(horizontal.get(), PJ_FWD, c);
      if (!std::isfinite(c.v[0]) || !std::isfinite(c.v[1])) ok = false;
      a[0] = std::min(a[0], c.v[0]), a[1] = std::min(a[1], c.v[1]);
      a[2] = std::max(a[2], c.v[0]), a[3] = std::max(a[3], c.v[1]);
    }
    if (ok) area = a;
  }
  PjPtr target(proj_create(pctx, "EPSG:4979"));
  if (!target) return Error(ErrorCode::internal, "PROJ cannot build EPSG:4979");
  auto usable =
      candidate_operations(pctx, source3d.get(), target.get(),
                           PROJ_GRID_AVAILABILITY_DISCARD_OPERATION_IF_MISSING_GRID, area);
  PjPtr chosen;
  for (PjPtr& op : usable) {
    if (op && proj_coordoperation_has_ballpark_transformation(pctx, op.get()) == 0) {
      chosen = std::move(op);
      break;
    }
  }
  if (!chosen) {
    auto all = candidate_operations(pctx, source3d.get(), target.get(),
                                    PROJ_GRID_AVAILABILITY_IGNORED, area);
    std::string missing;
    for (PjPtr& op : all) {
      if (op && proj_coordoperation_has_ballpark_transformation(pctx, op.get()) == 0) {
        missing = grids_of(pctx, op.get(), true);
        if (!missing.empty()) break;
      }
    }
    if (!missing.empty()) {
      const std::string first = missing.substr(0, missing.find(','));
      const PJ_INFO pinfo = proj_info();
      return not_found(file + ": converting heights in " + vname +
                       " to WGS84 ellipsoidal heights needs the grid(s) " + missing +
                       ", which PROJ cannot find (searched: " +
                       (pinfo.searchpath != nullptr ? pinfo.searchpath : "?") +
                       "). Install it: `projsync --file " + first +
                       "` (or download it from https://cdn.proj.org/" + first +
                       ") into a directory listed in PROJ_DATA; or choose another "
                       "--vertical-datum (ellipsoidal, egm96, egm2008)");
    }
    return unsupported(file + ": PROJ knows no transformation from heights in " + vname +
                       " to WGS84 ellipsoidal heights other than a ballpark no-op; "
                       "choose --vertical-datum explicitly (ellipsoidal, egm96, egm2008)");
  }
  plan.geoid_grid = grids_of(pctx, chosen.get(), false);
  if (const char* name = proj_get_name(chosen.get())) {
    plan.notes.push_back(std::string("heights converted by PROJ operation: ") + name);
  }
  full3d.reset(proj_normalize_for_visualization(pctx, chosen.get()));
  if (!full3d) return unsupported(file + ": cannot normalise the 3D operation axis order");
  return {};
}

Reprojector::Reprojector(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Reprojector::Reprojector(Reprojector&&) noexcept = default;
Reprojector& Reprojector::operator=(Reprojector&&) noexcept = default;
Reprojector::~Reprojector() = default;
const ReprojectionPlan& Reprojector::plan() const { return impl_->plan; }

Result<std::vector<std::string>> geoid_grid_candidates(const std::string& vertical_datum) {
  if (vertical_datum.empty() || vertical_datum == "ellipsoidal" || vertical_datum == "crs") {
    return std::vector<std::string>{};
  }
  if (vertical_datum == "egm96") {
    return std::vector<std::string>{"us_nga_egm96_15.tif", "egm96_15.gtx"};
  }
  if (vertical_datum == "egm2008" || vertical_datum == "egm08") {
    return std::vector<std::string>{"us_nga_egm08_25.tif", "egm08_25.gtx"};
  }
  if (is_grid_file_name(vertical_datum)) return std::vector<std::string>{vertical_datum};
  return invalid_argument("unknown vertical datum '" + shorten(vertical_datum, 60) +
                          "': use ellipsoidal, egm96, egm2008, crs or the file name of a PROJ "
                          "geoid grid (letters, digits, '.', '_', '-', ending in .tif, .gtx or "
                          ".gtg; no directory: PROJ looks for it in its data directories)");
}

bool is_grid_file_name(std::string_view name) {
  if (name.empty() || name.size() > 128) return false;
  if (!std::isalnum(static_cast<unsigned char>(name.front()))) return false;
  for (const char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-') {
      return false;
    }
  }
  const std::string n(name);
  return ends_with(n, ".tif") || ends_with(n, ".gtx") || ends_with(n, ".gtg");
}

bool is_authority_code(std::string_view crs) {
  // AUTH:code, optionally +code (a compound of two codes of the same authority).
  const auto colon = crs.find(':');
  if (colon == std::string_view::npos || colon == 0 || colon > 16) return false;
  for (std::size_t i = 0; i < colon; ++i) {
    if (!std::isupper(static_cast<unsigned char>(crs[i]))) return false;
  }
  const std::string_view codes = crs.substr(colon + 1);
  if (codes.empty() || codes.size() > 24) return false;
  bool digit_before = false;
  for (const char c : codes) {
    if (std::isdigit(static_cast<unsigned char>(c))) {
      digit_before = true;
    } else if (c == '+' && digit_before) {
      digit_before = false;
    } else {
      return false;
    }
  }
  return digit_before;
}

Result<Reprojector> Reprojector::create(const sources::SourceInfo& info,
                                        const ReprojectOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->path = info.path;
  impl->ctx.reset(proj_context_create());
  PJ_CONTEXT* ctx = impl->ctx.get();
  if (ctx == nullptr) return Error(ErrorCode::internal, "cannot create a PROJ context");
  proj_log_level(ctx, PJ_LOG_NONE);
  if (options.confined) {
    proj_context_set_enable_network(ctx, 0);  // no download of grids (PROJ_NETWORK)
    if (Status s = check_confined_crs(info, options); !s) return s.error();
  }
  auto crs = impl->open_crs(info, options);
  if (!crs) return crs.error();
  if (Status s = impl->plan_z_unit(*crs, info, options); !s) return s.error();
  if (Status s = impl->plan_horizontal(*crs); !s) return s.error();
  const Status vertical = options.vertical_datum == "crs"
                              ? impl->plan_vertical_crs(crs->whole, crs->horizontal, crs->vertical,
                                                        crs->htype, info, options)
                              : impl->plan_geoid(options);
  if (!vertical) return vertical.error();
  return Reprojector(std::move(impl));
}

// The source CRS (the option's, else the file's), checked to be geographic or projected, split
// into its parts; sets plan.crs, crs_name and horizontal_unit.
Result<SourceCrs> Reprojector::Impl::open_crs(const sources::SourceInfo& info,
                                              const ReprojectOptions& options) {
  PJ_CONTEXT* pctx = ctx.get();
  const std::string& file = info.path;
  plan.crs = !options.crs.empty() ? options.crs : info.crs;
  if (plan.crs.empty()) {
    return invalid_argument(file + ": the file has no CRS" +
                            (info.format == "GDAL AAIGrid"
                                 ? std::string(" (ESRI ASCII grids carry none without a .prj)")
                                 : std::string()) +
                            ": give one with --crs (e.g. --crs EPSG:4326)");
  }
  SourceCrs out;
  PjPtr crs(proj_create(pctx, plan.crs.c_str()));
  if (!crs) {
    return unsupported(file + ": unknown or invalid CRS '" + shorten(plan.crs) +
                       "': " + proj_message(pctx));
  }
  if (proj_is_crs(crs.get()) == 0) {
    return unsupported(file + ": '" + shorten(plan.crs) + "' is not a CRS");
  }
  if (const char* name = proj_get_name(crs.get())) plan.crs_name = name;
  if (proj_get_type(crs.get()) == PJ_TYPE_COMPOUND_CRS) {
    out.horizontal.reset(proj_crs_get_sub_crs(pctx, crs.get(), 0));
    out.vertical.reset(proj_crs_get_sub_crs(pctx, crs.get(), 1));
    out.whole = std::move(crs);
  } else {
    out.horizontal = std::move(crs);
  }
  if (!out.horizontal) return unsupported(file + ": cannot take the horizontal part of the CRS");
  out.unit_crs = out.horizontal.get();
  if (proj_get_type(out.horizontal.get()) == PJ_TYPE_BOUND_CRS) {
    out.base.reset(proj_get_source_crs(pctx, out.horizontal.get()));
    if (out.base) out.unit_crs = out.base.get();
  }
  out.htype = proj_get_type(out.unit_crs);
  out.geographic = out.htype == PJ_TYPE_GEOGRAPHIC_2D_CRS || out.htype == PJ_TYPE_GEOGRAPHIC_3D_CRS;
  if (!out.geographic && out.htype != PJ_TYPE_PROJECTED_CRS) {
    return unsupported(file + ": CRS '" + plan.crs_name +
                       "' is neither geographic nor projected (geocentric, engineering and "
                       "vertical-only CRSs cannot be placed on the globe)");
  }
  out.hunit = axis_unit(pctx, out.unit_crs, 0);
  plan.horizontal_unit = out.hunit ? out.hunit->name : "";
  return out;
}

// The z unit rule (see the header): the user's, the file's, the CRS's vertical axis, the
// horizontal CRS's linear unit, else metre.
Status Reprojector::Impl::plan_z_unit(const SourceCrs& crs, const sources::SourceInfo& info,
                                      const ReprojectOptions& options) {
  PJ_CONTEXT* pctx = ctx.get();
  if (options.z_unit) {
    plan.z_unit = *options.z_unit;
    plan.z_unit_rule = "given by the user";
  } else if (info.z_unit) {
    plan.z_unit = *info.z_unit;
    plan.z_unit_rule = "stated by the file";
  } else if (auto vu = crs.vertical ? axis_unit(pctx, crs.vertical.get(), 0)
                                    : (crs.htype == PJ_TYPE_GEOGRAPHIC_3D_CRS
                                           ? axis_unit(pctx, crs.unit_crs, 2)
                                           : std::nullopt)) {
    plan.z_unit = sources::LinearUnit{vu->name, vu->factor};
    plan.z_unit_rule = "the CRS's vertical axis";
  } else if (!crs.geographic && crs.hunit && crs.hunit->linear) {
    plan.z_unit = sources::LinearUnit{crs.hunit->name, crs.hunit->factor};
    plan.z_unit_rule = "no vertical CRS: z taken in the horizontal CRS's linear unit";
  } else {
    plan.z_unit = sources::LinearUnit{"metre", 1.0};
    plan.z_unit_rule = "no vertical unit known: metre";
  }
  if (!(plan.z_unit.to_metre > 0) || !std::isfinite(plan.z_unit.to_metre)) {
    return unsupported(info.path + ": z unit '" + plan.z_unit.name +
                       "' has no usable metre factor");
  }
  if (crs.vertical || !info.vertical_crs.empty()) {
    plan.notes.push_back(
        "the source declares a vertical CRS (" +
        (crs.vertical ? std::string(proj_get_name(crs.vertical.get())) : info.vertical_crs) +
        "); heights are converted as vertical_datum=" + options.vertical_datum);
  }
  return {};
}

// The horizontal operation: source horizontal CRS → EPSG:4326 in lon/lat order.
Status Reprojector::Impl::plan_horizontal(const SourceCrs& crs) {
  PJ_CONTEXT* pctx = ctx.get();
  PjPtr wgs84(proj_create(pctx, "EPSG:4326"));
  if (!wgs84)
    return Error(ErrorCode::internal, "PROJ cannot build EPSG:4326: " + proj_message(pctx));
  PjPtr op(
      proj_create_crs_to_crs_from_pj(pctx, crs.horizontal.get(), wgs84.get(), nullptr, nullptr));
  if (!op) {
    return unsupported(path + ": no transformation from '" + plan.crs_name +
                       "' to WGS84: " + proj_message(pctx));
  }
  horizontal.reset(proj_normalize_for_visualization(pctx, op.get()));
  if (!horizontal) {
    return unsupported(path +
                       ": cannot normalise the transformation axis order: " + proj_message(pctx));
  }
  return {};
}

// vertical_datum ellipsoidal, egm96, egm2008 or a grid file: the geoid grid's vgridshift (none for
// ellipsoidal heights).
Status Reprojector::Impl::plan_geoid(const ReprojectOptions& options) {
  auto grids = geoid_grid_candidates(options.vertical_datum);
  if (!grids.ok()) return Error(grids.error().code, path + ": " + grids.error().message);
  if (grids->empty()) return {};
  for (const std::string& g : *grids) {
    const std::string pipeline =
        "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
        "+step +proj=vgridshift +grids=" +
        g +
        " +multiplier=1 "
        "+step +proj=unitconvert +xy_in=rad +xy_out=deg";
    PjPtr shift(proj_create(ctx.get(), pipeline.c_str()));
    if (shift) {
      geoid = std::move(shift);
      plan.geoid_grid = g;
      return {};
    }
  }
  std::string names;
  for (const auto& g : *grids) names += (names.empty() ? "" : " or ") + g;
  const PJ_INFO pinfo = proj_info();
  return not_found(
      path + ": vertical datum '" + options.vertical_datum + "' needs the geoid grid " + names +
      ", which PROJ cannot find (searched: " +
      (pinfo.searchpath != nullptr ? pinfo.searchpath : "?") +
      "). Install it with `projsync --file " + grids->front() +
      "`, or download https://cdn.proj.org/" + grids->front() +
      " into a directory listed in PROJ_DATA (Debian's proj-data package holds only a few "
      "grids); or use --vertical-datum ellipsoidal if the heights are already ellipsoidal");
}

Status Reprojector::transform_3d(std::span<const sources::SourcePoint> in,
                                 std::vector<GeoPoint>& out) {
  for (std::size_t i = 0; i < in.size(); ++i) out[i] = GeoPoint{in[i].x, in[i].y, in[i].z};
  if (in.empty()) return {};
  PJ* op = impl_->full3d.get();
  proj_errno_reset(op);
  proj_trans_generic(op, PJ_FWD, &out[0].lon, sizeof(GeoPoint), out.size(), &out[0].lat,
                     sizeof(GeoPoint), out.size(), &out[0].h, sizeof(GeoPoint), out.size(), nullptr,
                     0, 0);
  for (std::size_t i = 0; i < out.size(); ++i) {
    GeoPoint& g = out[i];
    if (!std::isfinite(g.lon) || !std::isfinite(g.lat) || !std::isfinite(g.h) ||
        std::abs(g.lat) > 90 || std::abs(g.lon) > 360) {
      return corrupt_data(impl_->path + ": record " + std::to_string(in[i].record) + ": (" +
                          std::to_string(in[i].x) + ", " + std::to_string(in[i].y) + ", " +
                          std::to_string(in[i].z) + ") cannot be transformed from " +
                          impl_->plan.crs_name +
                          " to WGS84 ellipsoidal height (outside the "
                          "CRS's domain or the vertical grid?)");
    }
    if (g.lon > 180 || g.lon < -180) g.lon = std::remainder(g.lon, 360.0);
  }
  return {};
}

Status Reprojector::transform(std::span<const sources::SourcePoint> in,
                              std::vector<GeoPoint>& out) {
  out.resize(in.size());
  if (impl_->full3d) return transform_3d(in, out);
  const double zf = impl_->plan.z_unit.to_metre;
  for (std::size_t i = 0; i < in.size(); ++i) {
    out[i] = GeoPoint{in[i].x, in[i].y, in[i].z * zf};
  }
  if (in.empty()) return {};
  PJ* op = impl_->horizontal.get();
  proj_errno_reset(op);
  proj_trans_generic(op, PJ_FWD, &out[0].lon, sizeof(GeoPoint), out.size(), &out[0].lat,
                     sizeof(GeoPoint), out.size(), nullptr, 0, 0, nullptr, 0, 0);
  for (std::size_t i = 0; i < out.size(); ++i) {
    GeoPoint& g = out[i];
    // |lon| > 360 never comes out of a real transformation: it is a projected coordinate read
    // as degrees (a wrong CRS label), and wrapping it would hide that.
    if (!std::isfinite(g.lon) || !std::isfinite(g.lat) || std::abs(g.lat) > 90 ||
        std::abs(g.lon) > 360) {
      return corrupt_data(impl_->path + ": record " + std::to_string(in[i].record) + ": (" +
                          std::to_string(in[i].x) + ", " + std::to_string(in[i].y) +
                          ") cannot be transformed from " + impl_->plan.crs_name +
                          " to WGS84 (outside the CRS's domain, or wrong CRS?)");
    }
    if (g.lon > 180 || g.lon < -180) g.lon = std::remainder(g.lon, 360.0);
  }
  if (impl_->geoid) {
    PJ* geoid = impl_->geoid.get();
    proj_errno_reset(geoid);
    proj_trans_generic(geoid, PJ_FWD, &out[0].lon, sizeof(GeoPoint), out.size(), &out[0].lat,
                       sizeof(GeoPoint), out.size(), &out[0].h, sizeof(GeoPoint), out.size(),
                       nullptr, 0, 0);
    for (std::size_t i = 0; i < out.size(); ++i) {
      if (!std::isfinite(out[i].h) || !std::isfinite(out[i].lon)) {
        return corrupt_data(impl_->path + ": record " + std::to_string(in[i].record) +
                            ": no geoid undulation from " + impl_->plan.geoid_grid +
                            " at this position (outside the grid?)");
      }
    }
  }
  return {};
}

}  // namespace tinstream::transform
