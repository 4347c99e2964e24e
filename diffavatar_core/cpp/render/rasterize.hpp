// Headless z-buffer rasterizer for previews and the SSIM metric (paper §5, Table 1: renders of
// scan and result "using the exact same rendering conditions"). No GPU, no display.
#pragma once
#include "common/types.hpp"

namespace diffavatar {

/// Pinhole camera looking from `eye` towards `target` with `up`; vertical field of view in
/// radians; image width×height pixels. Positions in m.
struct Camera {
  Vec3 eye = Vec3(0, 1, 3), target = Vec3(0, 1, 0), up = Vec3(0, 1, 0);
  double fov_y = 0.6;
  int width = 256, height = 256;
};

/// Per-pixel visibility: `face` (#H×#W, row-major, -1 = background) and camera-space `depth`
/// (m along the view axis; +inf for background).
struct RasterResult {
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> face;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> depth;
};

/// Rasterizes triangles (V: #V×3 m, F: #F×3) with perspective-correct depth; pixel centres at
/// (i + ½, j + ½); a pixel is covered by the nearest triangle whose interior (edge-function test,
/// top-left ties) contains its centre. Triangles behind the near plane (0.01 m) are skipped.
/// Deterministic for any thread count (rows are independent).
RasterResult rasterize(const RefX3d& V, const RefX3i& F, const Camera& cam);

}  // namespace diffavatar
