// The real heights the pyramid tests share: a square crop of the Big Tujunga SRTM DEM in
// ../shared/data (bigtujunga_srtm30m_utm11.tif), read with GDAL.
#pragma once

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cstddef>
#include <filesystem>
#include <optional>
#include <vector>

namespace tinstream::lod::testing {

// side × side heights (row-major, north first) from column 420, row 180 of the DEM; nullopt when
// the shared data is absent (the caller skips). A failed read is a test failure and gives an
// empty crop.
inline std::optional<std::vector<float>> big_tujunga_crop(int side) {
  const std::filesystem::path dem =
      std::filesystem::path(TINSTREAM_SHARED_DATA) / "bigtujunga_srtm30m_utm11.tif";
  if (!std::filesystem::exists(dem)) return std::nullopt;
  GDALAllRegister();
  auto* ds = static_cast<GDALDataset*>(GDALOpen(dem.c_str(), GA_ReadOnly));
  if (ds == nullptr) {
    ADD_FAILURE() << "GDAL cannot open " << dem;
    return std::vector<float>{};
  }
  std::vector<float> crop(static_cast<std::size_t>(side) * static_cast<std::size_t>(side));
  const CPLErr read = ds->GetRasterBand(1)->RasterIO(GF_Read, 420, 180, side, side, crop.data(),
                                                     side, side, GDT_Float32, 0, 0);
  GDALClose(ds);
  if (read != CE_None) {
    ADD_FAILURE() << "reading a " << side << "² crop of " << dem << " failed";
    crop.clear();
  }
  return crop;
}

}  // namespace tinstream::lod::testing
