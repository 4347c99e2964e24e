// Camera model shared by the rasterizer and the shader (headless previews and the SSIM metric of
// paper §5 / Table 1: scan and result are rendered "under the exact same rendering conditions").
#pragma once
#include <Eigen/Geometry>

#include "common/types.hpp"

namespace diffavatar {

/// A camera at `eye` (m) looking at `target` (m) with `up` as the approximate up direction.
/// Perspective: vertical field of view `fov_y` (radians). Orthographic: the image spans
/// `ortho_height` m vertically. Image `width`×`height` pixels; pixel (i, j) has its centre at
/// screen (i + ½, j + ½), i to the right, j downwards. Geometry nearer than `near` m along the
/// view axis is not drawn (perspective only).
struct Camera {
  Vec3 eye = Vec3(0, 1, 3), target = Vec3(0, 1, 0), up = Vec3(0, 1, 0);
  bool orthographic = false;
  double fov_y = 0.6;
  double ortho_height = 2.0;
  int width = 256, height = 256;
  double near = 1e-3;
};

/// Orthonormal camera frame: forward `f` (eye → target), right `r`, true up `u` (r × f... = u).
struct CameraFrame {
  Vec3 f, r, u;
  explicit CameraFrame(const Camera& cam);
};

/// Validates a camera (positive size, non-degenerate view direction/up, fov in (0, π),
/// positive ortho height); throws std::invalid_argument naming the bad field.
void check_camera(const Camera& cam);

}  // namespace diffavatar
