// Lambert + ambient shading of a rasterized mesh with a fixed, camera-attached light rig, and
// optional supersampling anti-aliasing: the image used for previews and the SSIM metric.
#pragma once
#include "common/types.hpp"
#include "render/camera.hpp"

namespace diffavatar {

/// Shading settings. Colours are linear RGB in [0, 1].
struct ShadingOptions {
  bool smooth = false;          ///< per-vertex (area-weighted) normals interpolated, else face normals
  double ambient = 0.25;        ///< ambient term k_a
  Vec3 background = Vec3(1, 1, 1);
  int supersample = 1;          ///< s: render at s·W × s·H and box-filter down (s×s samples/pixel)
};

/// 8-bit RGB image, #H × 3#W row-major (numpy reshape to H×W×3).
using ImageRGB8 = Eigen::Matrix<uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// The fixed light rig, directions towards the lights in camera coordinates (right r, up u,
/// back b = −f): key light l₁ ∝ (−0.5, 0.6, 1) with intensity 0.65, fill light l₂ ∝ (0.6, 0.1, 1)
/// with intensity 0.3. Attached to the camera so every view of an orbit is lit alike.
///
/// Pixel colour c = albedo ⊙ min(1, k_a + Σ_k I_k max(0, n·l_k)), with n the unit normal
/// flipped to face the camera (two-sided: cloth has no inside). Background pixels get
/// `background`. With supersampling, the s×s sample colours are averaged, then quantized to
/// 8 bits by round(255 c).
///
/// V: #V×3 (m); F: #F×3 int32; face_colors: #F×3 albedo in [0, 1].
/// Deterministic for any thread count (see rasterize).
ImageRGB8 render_image(const RefX3d& V, const RefX3i& F, const RefX3d& face_colors, const Camera& cam,
                       const ShadingOptions& opt);

}  // namespace diffavatar
