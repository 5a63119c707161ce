// Elevation maps (thesis sec. 6.2.1), their GeoTIFF storage (GDAL) and a viewable PNG.
#include "sonar3d/mapping/elevation_map.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"

namespace sonar3d {

void ElevationFileConfig::validate() const {
  params::check(*this, "elevation");
  map.validate();
}

namespace {

constexpr std::uint16_t kUInt16NoData = 65535;

// GDAL reports errors through a handler; keep the last message so an Error can carry it instead
// of GDAL printing on stderr.
thread_local std::string g_last_gdal_error;
void CPL_STDCALL gdal_error_handler(CPLErr level, CPLErrorNum, const char* msg) {
  if (level >= CE_Failure) g_last_gdal_error = msg ? msg : "";
}

void init_gdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(gdal_error_handler);
  });
}

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(d); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

std::string gdal_reason() {
  return g_last_gdal_error.empty() ? std::string("GDAL failed") : g_last_gdal_error;
}

// The grid cell k with k·c <= v < (k+1)·c. Points of a voxel map at the same resolution sit on
// cell boundaries, and float32 rounding would scatter them over two cells (leaving stripes of
// empty cells): a value within a hair (0.1 % of a cell, or the float32 precision at that
// magnitude) below a boundary counts as on it.
double cell_index(double v, double c) {
  const double u = v / c;
  const double eps = std::max(1e-3, 4.0 * std::numeric_limits<float>::epsilon() * std::abs(u));
  return std::floor(u + eps);
}

}  // namespace

std::size_t ElevationMap::num_valid() const {
  return static_cast<std::size_t>(
      std::count_if(z.begin(), z.end(), [](float v) { return v == v; }));
}

void ElevationMapConfig::validate() const {
  require_positive(cell_m, "cell_m", "m");
  const bool has_region = region_min_xy.x() <= region_max_xy.x();
  if (has_region) {
    require(region_min_xy.allFinite() && region_max_xy.allFinite() &&
                region_min_xy.y() <= region_max_xy.y(),
            "region: min and max must be finite with min <= max (x and y, m)");
  }
  require(max_cells > 0, "max_cells must be > 0");
}

namespace {

// The map's grid (cell indices of its corners) for a cloud and a config.
struct Grid {
  double kx0 = 0, kx1 = 0, ky0 = 0, ky1 = 0;
  double cols() const { return kx1 - kx0 + 1; }
  double rows() const { return ky1 - ky0 + 1; }
};

Grid grid_of(const PointCloud& cloud_world, const ElevationMapConfig& config) {
  config.validate();
  Eigen::Vector2d lo = config.region_min_xy, hi = config.region_max_xy;
  if (lo.x() > hi.x()) {
    require(!cloud_world.empty(), "elevation map: the point cloud is empty (nothing to map)");
    lo.setConstant(std::numeric_limits<double>::infinity());
    hi = -lo;
    for (std::size_t i = 0; i < cloud_world.size(); ++i) {
      const Eigen::Vector3f& p = cloud_world.points[i];
      if (!p.allFinite()) {  // (the message is built only on failure: this loop is hot)
        throw Error("elevation map: point " + std::to_string(i) + " is not finite");
      }
      lo = lo.cwiseMin(p.head<2>().cast<double>());
      hi = hi.cwiseMax(p.head<2>().cast<double>());
    }
  }
  const double c = config.cell_m;
  // Cells sit on one world grid, cell k along an axis covering [k·c, (k+1)·c): maps of different
  // swaths at one resolution then share their grid (swath registration needs that). Columns run
  // west → east, rows north → south.
  return {cell_index(lo.x(), c), cell_index(hi.x(), c), cell_index(lo.y(), c),
          cell_index(hi.y(), c)};
}

}  // namespace

double elevation_map_cells(const PointCloud& cloud_world, const ElevationMapConfig& config) {
  const Grid grid = grid_of(cloud_world, config);
  return grid.cols() * grid.rows();
}

MemoryEstimate estimate_elevation_memory(const PointCloud& cloud_world,
                                         const ElevationMapConfig& config,
                                         const ElevationWriteOptions& write, bool png,
                                         const std::string& cell_option) {
  const Grid grid = grid_of(cloud_world, config);
  const double cells = grid.cols() * grid.rows();
  char what[160];
  std::snprintf(what, sizeof what, "elevation map of %.0f x %.0f cells of %.3g m", grid.cols(),
                grid.rows(), config.cell_m);
  MemoryEstimate e;
  e.add(what, cells * sizeof(float), cell_option);
  if (write.uint16_step_m) {
    e.add("its uint16 GeoTIFF band", cells * sizeof(std::uint16_t), cell_option);
  }
  // The picture: grey and validity masks, the colour-mapped image and the canvas (8-bit BGR),
  // and the encoded PNG (at most the canvas).
  if (png) e.add("its PNG picture", cells * (1 + 1 + 3 + 3 + 3), cell_option);
  return e;
}

ElevationMap elevation_map_from_points(const PointCloud& cloud_world,
                                       const ElevationMapConfig& config) {
  const Grid grid = grid_of(cloud_world, config);
  const double c = config.cell_m;
  const double kx0 = grid.kx0, ky1 = grid.ky1;
  const double ncols = grid.cols(), nrows = grid.rows();
  require(ncols * nrows <= static_cast<double>(config.max_cells),
          "elevation map: " + std::to_string(static_cast<long long>(ncols)) + " x " +
              std::to_string(static_cast<long long>(nrows)) + " cells of " + std::to_string(c) +
              " m exceed max_cells = " + std::to_string(config.max_cells) +
              ": use a larger cell_m or a region");
  ElevationMap map;
  map.cell_m = c;
  map.cols = static_cast<int>(ncols);
  map.rows = static_cast<int>(nrows);
  map.origin_xy = {kx0 * c, (ky1 + 1) * c};
  map.z.assign(static_cast<std::size_t>(map.rows) * map.cols, ElevationMap::kNoData);
  for (std::size_t i = 0; i < cloud_world.size(); ++i) {
    const Eigen::Vector3f& p = cloud_world.points[i];
    if (!p.allFinite()) throw Error("elevation map: point " + std::to_string(i) + " is not finite");
    const double col = cell_index(p.x(), c) - kx0;
    const double row = ky1 - cell_index(p.y(), c);
    if (col < 0 || row < 0 || col >= map.cols || row >= map.rows) continue;  // outside region
    float& cell = map.at(static_cast<int>(row), static_cast<int>(col));
    // Sec. 6.2.1: the highest point of the cell.
    if (!(cell == cell) || p.z() > cell) cell = p.z();
  }
  return map;
}

void write_elevation_geotiff(const std::string& path, const ElevationMap& map,
                             const ElevationWriteOptions& options) {
  require(!map.empty() && map.z.size() == static_cast<std::size_t>(map.rows) * map.cols,
          "cannot write '" + path + "': the elevation map is empty or inconsistent");
  require_positive(map.cell_m, "cell_m", "m");
  init_gdal();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  require(driver != nullptr, "cannot write '" + path + "': GDAL has no GTiff driver");

  const bool quantised = options.uint16_step_m.has_value();
  double offset = 0, scale = 1;
  std::vector<std::uint16_t> q;
  if (quantised) {
    require_positive(*options.uint16_step_m, "uint16_step_m", "m");
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (float v : map.z) {
      if (v == v) lo = std::min(lo, v), hi = std::max(hi, v);
    }
    scale = *options.uint16_step_m;
    offset = lo == lo && std::isfinite(lo) ? lo : 0.0;
    require(!std::isfinite(hi) || (hi - offset) / scale <= kUInt16NoData - 1,
            "cannot write '" + path + "' as uint16: the height range " +
                std::to_string(hi - offset) + " m needs more than 65535 steps of " +
                std::to_string(scale) + " m: use a larger uint16_step_m or float32");
    q.resize(map.z.size());
    for (std::size_t i = 0; i < q.size(); ++i) {
      const float v = map.z[i];
      q[i] = v == v ? static_cast<std::uint16_t>(std::lround((v - offset) / scale)) : kUInt16NoData;
    }
  }

  AtomicPath out(path);
  char** create_options = nullptr;
  create_options = CSLSetNameValue(create_options, "COMPRESS", "DEFLATE");
  create_options = CSLSetNameValue(create_options, "PREDICTOR", quantised ? "2" : "3");
  create_options = CSLSetNameValue(create_options, "TILED", "YES");
  g_last_gdal_error.clear();
  DatasetPtr ds(driver->Create(out.temp().c_str(), map.cols, map.rows, 1,
                               quantised ? GDT_UInt16 : GDT_Float32, create_options));
  CSLDestroy(create_options);
  require(ds != nullptr, "cannot write '" + path + "': " + gdal_reason());
  // North-up geotransform: x = x0 + col·c, y = y0 − row·c at the cell corners.
  double transform[6] = {map.origin_xy.x(), map.cell_m, 0, map.origin_xy.y(), 0, -map.cell_m};
  ds->SetGeoTransform(transform);
  OGRSpatialReference srs;
  srs.SetLocalCS("sonar3d local ENU (x East, y North, z up), metres");
  srs.SetLinearUnits(SRS_UL_METER, 1.0);
  ds->SetSpatialRef(&srs);
  ds->SetMetadataItem("SONAR3D_CONTENT", "elevation: highest observed height z per cell, m");
  ds->SetMetadataItem("TIFFTAG_SOFTWARE", "sonar3d");  // is_sonar3d_output(OutputKind::GeoTiff)
  GDALRasterBand* band = ds->GetRasterBand(1);
  CPLErr err;
  if (quantised) {
    band->SetNoDataValue(kUInt16NoData);
    band->SetOffset(offset);
    band->SetScale(scale);
    err = band->RasterIO(GF_Write, 0, 0, map.cols, map.rows, q.data(), map.cols, map.rows,
                         GDT_UInt16, 0, 0);
  } else {
    band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
    err = band->RasterIO(GF_Write, 0, 0, map.cols, map.rows, const_cast<float*>(map.z.data()),
                         map.cols, map.rows, GDT_Float32, 0, 0);
  }
  band->SetUnitType("m");
  require(err == CE_None, "cannot write '" + path + "': " + gdal_reason());
  ds->FlushCache();
  ds.reset();  // closes the file before it is renamed
  require(g_last_gdal_error.empty(), "cannot write '" + path + "': " + gdal_reason());
  out.commit();
}

ElevationMap read_elevation_geotiff(const std::string& path) {
  init_gdal();
  g_last_gdal_error.clear();
  // GeoTIFF only: GDAL's other drivers are parsers we neither need nor test.
  const char* const drivers[] = {"GTiff", nullptr};
  DatasetPtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, drivers));
  require(ds != nullptr, "cannot read elevation map '" + path + "': " +
                             (g_last_gdal_error.empty()
                                  ? std::string("not a raster GDAL can read (a GeoTIFF written by "
                                                "`sonar3d elevation` is expected)")
                                  : g_last_gdal_error));
  require(ds->GetRasterCount() == 1, "elevation map '" + path + "': expected 1 band, found " +
                                         std::to_string(ds->GetRasterCount()));
  double t[6];
  require(ds->GetGeoTransform(t) == CE_None,
          "elevation map '" + path + "': no geotransform (cell size and origin are needed)");
  require(t[2] == 0 && t[4] == 0 && t[1] > 0 && std::abs(t[5] + t[1]) <= 1e-9 * t[1],
          "elevation map '" + path + "': only north-up rasters with square cells are supported");
  const int cols = ds->GetRasterXSize(), rows = ds->GetRasterYSize();
  // A size the file can justify: real maps compress to about 2 bytes a cell; no more than 10^4
  // cells per byte of file (and 10^8 in all, 400 MB) are read, so a small corrupt file cannot
  // make us allocate gigabytes.
  std::error_code ec;
  const double file_bytes = static_cast<double>(std::filesystem::file_size(path, ec));
  const double cells = static_cast<double>(cols) * rows;
  require(cols > 0 && rows > 0 && cells <= 1e8 && cells <= 1e6 + 1e4 * file_bytes,
          "elevation map '" + path + "': " + std::to_string(cols) + " x " + std::to_string(rows) +
              " cells is empty, beyond the 1e8-cell limit, or more than its " +
              std::to_string(static_cast<long long>(file_bytes)) + " bytes can hold");
  GDALRasterBand* band = ds->GetRasterBand(1);
  ElevationMap map;
  map.origin_xy = {t[0], t[3]};
  map.cell_m = t[1];
  map.rows = rows;
  map.cols = cols;
  map.z.resize(static_cast<std::size_t>(rows) * cols);
  require(band->RasterIO(GF_Read, 0, 0, cols, rows, map.z.data(), cols, rows, GDT_Float32, 0, 0) ==
              CE_None,
          "cannot read elevation map '" + path + "': " + gdal_reason());
  int has_nodata = 0, has_offset = 0, has_scale = 0;
  const double nodata = band->GetNoDataValue(&has_nodata);
  double offset = band->GetOffset(&has_offset), scale = band->GetScale(&has_scale);
  if (!has_offset) offset = 0;
  if (!has_scale) scale = 1;
  require(std::isfinite(offset) && std::isfinite(scale),
          "elevation map '" + path + "': its offset or scale is not finite");
  const float nodata_f = static_cast<float>(nodata);
  for (float& v : map.z) {  // uint16 values are exact in float32
    const bool missing = !std::isfinite(v) || (has_nodata && v == nodata_f);
    v = missing ? ElevationMap::kNoData : static_cast<float>(offset + scale * v);
  }
  return map;
}

Eigen::Vector2f write_elevation_png(const std::string& path, const ElevationMap& map) {
  require(!map.empty(), "cannot write '" + path + "': the elevation map is empty");
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (float v : map.z) {
    if (v == v) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  require(std::isfinite(lo), "cannot write '" + path + "': the elevation map has no data");
  const float span = std::max(hi - lo, 1e-6f);
  cv::Mat grey(map.rows, map.cols, CV_8UC1), valid(map.rows, map.cols, CV_8UC1);
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const float v = map.at(r, c);
      grey.at<std::uint8_t>(r, c) =
          v == v ? static_cast<std::uint8_t>(std::lround(255.0f * (v - lo) / span)) : 0;
      valid.at<std::uint8_t>(r, c) = v == v ? 255 : 0;
    }
  }
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_TURBO);
  colour.setTo(cv::Scalar(0, 0, 0), valid == 0);
  // Colour bar: a strip as tall as the map (at least 200 px) with the range written beside it.
  const int h = std::max(map.rows, 200), bar_w = 24, label_w = 110;
  cv::Mat canvas(h, map.cols + bar_w + label_w + 10, CV_8UC3, cv::Scalar(255, 255, 255));
  colour.copyTo(canvas(cv::Rect(0, 0, map.cols, map.rows)));
  cv::Mat ramp(h, 1, CV_8UC1);
  for (int r = 0; r < h; ++r)
    ramp.at<std::uint8_t>(r) = static_cast<std::uint8_t>(255 - (255 * r) / (h - 1));
  cv::Mat ramp_colour;
  cv::applyColorMap(ramp, ramp_colour, cv::COLORMAP_TURBO);
  cv::resize(ramp_colour, ramp_colour, cv::Size(bar_w, h), 0, 0, cv::INTER_NEAREST);
  ramp_colour.copyTo(canvas(cv::Rect(map.cols + 5, 0, bar_w, h)));
  char top[64], bottom[64];
  std::snprintf(top, sizeof top, "%.3f m", hi);
  std::snprintf(bottom, sizeof bottom, "%.3f m", lo);
  const int tx = map.cols + bar_w + 10;
  cv::putText(canvas, top, {tx, 16}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  cv::putText(canvas, bottom, {tx, h - 6}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  cv::putText(canvas, "height z", {tx, h / 2}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0),
              1, cv::LINE_AA);
  AtomicPath out(path);
  std::vector<int> params;
  require(cv::imwrite(out.temp().string() + ".png", canvas, params), "cannot write '" + path + "'");
  mark_png_as_sonar3d(out.temp().string() + ".png");  // replaceable by sonar3d only
  std::filesystem::rename(out.temp().string() + ".png", out.temp());
  out.commit();
  return {lo, hi};
}

}  // namespace sonar3d
