// Headless z-buffer triangle rasterizer (no display, no GPU) for previews and the SSIM metric.
#pragma once
#include "common/types.hpp"
#include "render/camera.hpp"

namespace diffavatar {

/// Per-pixel visibility of a triangle mesh. All images are #H×#W row-major (row j = image row j
/// from the top). `face`: index of the visible triangle, -1 for background. `depth`: distance
/// along the view axis in m (+inf for background). `bary`: #H·#W×3 barycentric coordinates of
/// the pixel centre on the visible triangle (perspective-correct), zero for background.
struct RasterResult {
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> face;
  RowMatXd depth;
  RowMatX3d bary;
};

/// Rasterizes triangles V (#V×3, m), F (#F×3 int32) seen by `cam`.
///
/// Projection: perspective x_s = W/2 + φ (d·r)/(d·f), y_s = H/2 − φ (d·u)/(d·f) with
/// d = X − eye, φ = (H/2)/tan(fov_y/2); orthographic x_s = W/2 + s d·r, y_s = H/2 − s d·u with
/// s = H/ortho_height. A pixel is covered by a triangle when its centre lies inside or on it
/// (edge functions e_k ≥ 0 after orienting the triangle; no back-face culling — cloth is
/// two-sided). Depth z = d·f is interpolated as 1/z linearly in screen space (perspective) or
/// as z (orthographic); the nearest triangle wins, ties go to the lower face index.
/// Perspective triangles with a vertex nearer than cam.near are skipped (no clipping): callers
/// place cameras outside the scene's bounding box.
///
/// Parallel over bands of image rows (OpenMP); every pixel is written by exactly one thread in
/// face-index order, so the result is bitwise identical for any thread count.
RasterResult rasterize(const RefX3d& V, const RefX3i& F, const Camera& cam);

}  // namespace diffavatar
