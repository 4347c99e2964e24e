#include "render/rasterize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace diffavatar {

RasterResult rasterize(const RefX3d& V, const RefX3i& F, const Camera& cam) {
  const int W = cam.width, H = cam.height;
  RasterResult out;
  out.face.setConstant(H, W, -1);
  out.depth.setConstant(H, W, std::numeric_limits<double>::infinity());
  // camera frame: forward f, right r, true up u
  const Vec3 f = (cam.target - cam.eye).normalized();
  const Vec3 r = f.cross(cam.up).normalized();
  const Vec3 u = r.cross(f);
  const double focal = 0.5 * H / std::tan(0.5 * cam.fov_y);
  const double near = 0.01;
  // project every vertex: screen x right, y down, z = depth along f
  RowMatX3d P(V.rows(), 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const Vec3 d = V.row(i).transpose() - cam.eye;
    const double z = d.dot(f);
    P(i, 2) = z;
    P(i, 0) = z > near ? 0.5 * W + focal * d.dot(r) / z : 0.0;
    P(i, 1) = z > near ? 0.5 * H - focal * d.dot(u) / z : 0.0;
  }
  // bin triangles by the rows they span, then fill rows in parallel (no write conflicts)
  std::vector<std::vector<int>> rows(H);
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const int a = F(t, 0), b = F(t, 1), c = F(t, 2);
    if (P(a, 2) <= near || P(b, 2) <= near || P(c, 2) <= near) continue;
    const double ymin = std::min({P(a, 1), P(b, 1), P(c, 1)}), ymax = std::max({P(a, 1), P(b, 1), P(c, 1)});
    const int j0 = std::max(0, static_cast<int>(std::ceil(ymin - 0.5))), j1 = std::min(H - 1, static_cast<int>(std::floor(ymax - 0.5)));
    for (int j = j0; j <= j1; ++j) rows[j].push_back(static_cast<int>(t));
  }
#pragma omp parallel for schedule(dynamic, 8)
  for (int j = 0; j < H; ++j) {
    const double py = j + 0.5;
    for (int t : rows[j]) {
      const int ia = F(t, 0), ib = F(t, 1), ic = F(t, 2);
      const double ax = P(ia, 0), ay = P(ia, 1), bx = P(ib, 0), by = P(ib, 1), cx = P(ic, 0), cy = P(ic, 1);
      const double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
      if (area == 0.0) continue;
      const double xmin = std::min({ax, bx, cx}), xmax = std::max({ax, bx, cx});
      const int i0 = std::max(0, static_cast<int>(std::ceil(xmin - 0.5))), i1 = std::min(W - 1, static_cast<int>(std::floor(xmax - 0.5)));
      for (int i = i0; i <= i1; ++i) {
        const double px = i + 0.5;
        double w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) / area;
        double w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) / area;
        double w2 = 1.0 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        // perspective-correct depth: 1/z interpolates linearly in screen space
        const double inv_z = w0 / P(ia, 2) + w1 / P(ib, 2) + w2 / P(ic, 2);
        const double z = 1.0 / inv_z;
        if (z < out.depth(j, i)) {
          out.depth(j, i) = z;
          out.face(j, i) = t;
        }
      }
    }
  }
  return out;
}

}  // namespace diffavatar
