#include "render/shade.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "render/rasterize.hpp"

namespace diffavatar {

ImageRGB8 render_image(const RefX3d& V, const RefX3i& F, const RefX3d& face_colors, const Camera& cam,
                       const ShadingOptions& opt) {
  check_camera(cam);
  if (face_colors.rows() != F.rows()) throw std::invalid_argument("face_colors: expected one row per face");
  if (opt.supersample < 1 || opt.supersample > 8) throw std::invalid_argument("supersample: expected 1..8");
  const int s = opt.supersample;
  Camera hi = cam;
  hi.width = cam.width * s;
  hi.height = cam.height * s;
  const RasterResult rr = rasterize(V, F, hi);
  const CameraFrame fr(cam);

  // Face normals (unnormalized: |n| = 2·area) and area-weighted vertex normals.
  RowMatX3d FN(F.rows(), 3);
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Vec3 a = V.row(F(t, 0)), b = V.row(F(t, 1)), c = V.row(F(t, 2));
    FN.row(t) = (b - a).cross(c - a).transpose();
  }
  RowMatX3d VN;
  if (opt.smooth) {
    VN.setZero(V.rows(), 3);
    for (Eigen::Index t = 0; t < F.rows(); ++t)
      for (int k = 0; k < 3; ++k) VN.row(F(t, k)) += FN.row(t);
  }
  const Vec3 back = -fr.f;
  const Vec3 l1 = (-0.5 * fr.r + 0.6 * fr.u + 1.0 * back).normalized();
  const Vec3 l2 = (0.6 * fr.r + 0.1 * fr.u + 1.0 * back).normalized();
  const double I1 = 0.65, I2 = 0.3;

  const int Wh = hi.width;
  ImageRGB8 img(cam.height, 3 * cam.width);
  const double inv_n = 1.0 / (s * s);
#pragma omp parallel for schedule(static)
  for (int j = 0; j < cam.height; ++j) {
    for (int i = 0; i < cam.width; ++i) {
      Vec3 acc = Vec3::Zero();
      for (int sj = 0; sj < s; ++sj) {
        for (int si = 0; si < s; ++si) {
          const int y = j * s + sj, x = i * s + si;
          const int t = rr.face(y, x);
          if (t < 0) {
            acc += opt.background;
            continue;
          }
          const Eigen::Index p = static_cast<Eigen::Index>(y) * Wh + x;
          const Vec3 nf = FN.row(t).transpose();
          Vec3 n = nf;
          if (opt.smooth) {
            n = rr.bary(p, 0) * VN.row(F(t, 0)).transpose() + rr.bary(p, 1) * VN.row(F(t, 1)).transpose() +
                rr.bary(p, 2) * VN.row(F(t, 2)).transpose();
            if (!(n.norm() > 0.0)) n = nf;
          }
          // view direction towards the camera at this sample
          Vec3 to_eye;
          if (cam.orthographic) {
            to_eye = back;
          } else {
            const Vec3 X = rr.bary(p, 0) * V.row(F(t, 0)).transpose() + rr.bary(p, 1) * V.row(F(t, 1)).transpose() +
                           rr.bary(p, 2) * V.row(F(t, 2)).transpose();
            to_eye = cam.eye - X;
          }
          if (nf.dot(to_eye) < 0.0) n = -n;  // two-sided: orient by the geometric face normal
          n.normalize();
          const double light = std::min(1.0, opt.ambient + I1 * std::max(0.0, n.dot(l1)) + I2 * std::max(0.0, n.dot(l2)));
          acc += light * face_colors.row(t).transpose();
        }
      }
      acc *= inv_n;
      for (int c = 0; c < 3; ++c)
        img(j, 3 * i + c) = static_cast<uint8_t>(std::lround(255.0 * std::clamp(acc[c], 0.0, 1.0)));
    }
  }
  return img;
}

}  // namespace diffavatar
