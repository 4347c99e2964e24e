#include "render/rasterize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace diffavatar {

namespace {

constexpr int kBandRows = 8;  // rows per work item: a band is filled by one thread

/// Screen-space set-up of one triangle: edge functions e_k(x, y) = a_k x + b_k y + c_k, each
/// ≥ 0 inside (the triangle is oriented so that this holds), normalized so e_0 + e_1 + e_2 = 1
/// (screen barycentrics); per-vertex depth z_k (m) and its inverse.
struct TriSetup {
  double a[3], b[3], c[3];
  double z[3], iz[3];
  int x0, x1, y0, y1;  // inclusive pixel bounds
};

}  // namespace

RasterResult rasterize(const RefX3d& V, const RefX3i& F, const Camera& cam) {
  check_camera(cam);
  const int W = cam.width, H = cam.height;
  const CameraFrame fr(cam);
  RasterResult out;
  out.face.setConstant(H, W, -1);
  out.depth.setConstant(H, W, std::numeric_limits<double>::infinity());
  out.bary.setZero(static_cast<Eigen::Index>(H) * W, 3);

  const bool ortho = cam.orthographic;
  const double focal = ortho ? H / cam.ortho_height : 0.5 * H / std::tan(0.5 * cam.fov_y);
  const Eigen::Index nv = V.rows();
  RowMatX3d P(nv, 3);  // screen x, screen y, depth along f (m)
  for (Eigen::Index i = 0; i < nv; ++i) {
    const Vec3 d = V.row(i).transpose() - cam.eye;
    const double z = d.dot(fr.f);
    const double s = ortho ? focal : (z > cam.near ? focal / z : 0.0);
    P(i, 0) = 0.5 * W + s * d.dot(fr.r);
    P(i, 1) = 0.5 * H - s * d.dot(fr.u);
    P(i, 2) = z;
  }

  // Triangle set-up and binning into row bands (in face order, which fixes tie-breaking).
  const int nb = (H + kBandRows - 1) / kBandRows;
  std::vector<TriSetup> tris;
  std::vector<int> tri_face;
  std::vector<std::vector<int>> bands(nb);
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    int id[3] = {F(t, 0), F(t, 1), F(t, 2)};
    if (!ortho && (P(id[0], 2) <= cam.near || P(id[1], 2) <= cam.near || P(id[2], 2) <= cam.near)) continue;
    double x[3], y[3];
    for (int k = 0; k < 3; ++k) x[k] = P(id[k], 0), y[k] = P(id[k], 1);
    const double area2 = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
    if (!(std::abs(area2) > 0.0) || !std::isfinite(area2)) continue;
    const double xmin = std::min({x[0], x[1], x[2]}), xmax = std::max({x[0], x[1], x[2]});
    const double ymin = std::min({y[0], y[1], y[2]}), ymax = std::max({y[0], y[1], y[2]});
    // pixel bounds, clamped in double first: near-plane vertices project far off screen
    auto lo = [](double v, int n) { return static_cast<int>(std::clamp(std::ceil(v - 0.5), 0.0, double(n))); };
    auto hi = [](double v, int n) { return static_cast<int>(std::clamp(std::floor(v - 0.5), -1.0, double(n - 1))); };
    TriSetup s;
    s.x0 = lo(xmin, W), s.x1 = hi(xmax, W);
    s.y0 = lo(ymin, H), s.y1 = hi(ymax, H);
    if (s.x0 > s.x1 || s.y0 > s.y1) continue;
    // e_k is the signed area opposite vertex k: e_k(p) = cross(v_{k+2} - v_{k+1}, p - v_{k+1}) / area2
    for (int k = 0; k < 3; ++k) {
      const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
      s.a[k] = -(y[k2] - y[k1]) / area2;
      s.b[k] = (x[k2] - x[k1]) / area2;
      s.c[k] = ((y[k2] - y[k1]) * x[k1] - (x[k2] - x[k1]) * y[k1]) / area2;
      s.z[k] = P(id[k], 2);
      s.iz[k] = ortho ? 0.0 : 1.0 / s.z[k];
    }
    const int idx = static_cast<int>(tris.size());
    tris.push_back(s);
    tri_face.push_back(static_cast<int>(t));
    for (int bnd = s.y0 / kBandRows; bnd <= s.y1 / kBandRows; ++bnd) bands[bnd].push_back(idx);
  }

#pragma omp parallel for schedule(dynamic, 1)
  for (int bnd = 0; bnd < nb; ++bnd) {
    const int r0 = bnd * kBandRows, r1 = std::min(H - 1, r0 + kBandRows - 1);
    for (int idx : bands[bnd]) {
      const TriSetup& s = tris[idx];
      const int j0 = std::max(r0, s.y0), j1 = std::min(r1, s.y1);
      for (int j = j0; j <= j1; ++j) {
        const double py = j + 0.5;
        for (int i = s.x0; i <= s.x1; ++i) {
          const double px = i + 0.5;
          const double e0 = s.a[0] * px + s.b[0] * py + s.c[0];
          const double e1 = s.a[1] * px + s.b[1] * py + s.c[1];
          const double e2 = s.a[2] * px + s.b[2] * py + s.c[2];
          if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) continue;
          double z, b0, b1, b2;
          if (ortho) {
            z = e0 * s.z[0] + e1 * s.z[1] + e2 * s.z[2];
            b0 = e0, b1 = e1, b2 = e2;
          } else {
            const double q0 = e0 * s.iz[0], q1 = e1 * s.iz[1], q2 = e2 * s.iz[2];
            const double iz = q0 + q1 + q2;
            z = 1.0 / iz;
            b0 = q0 * z, b1 = q1 * z, b2 = q2 * z;
          }
          if (z < out.depth(j, i)) {
            out.depth(j, i) = z;
            out.face(j, i) = tri_face[idx];
            const Eigen::Index p = static_cast<Eigen::Index>(j) * W + i;
            out.bary(p, 0) = b0, out.bary(p, 1) = b1, out.bary(p, 2) = b2;
          }
        }
      }
    }
  }
  return out;
}

}  // namespace diffavatar
