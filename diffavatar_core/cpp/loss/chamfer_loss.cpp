#include "loss/chamfer_loss.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "geometry/aabb_tree.hpp"
#include "geometry/triangle_mesh_bvh.hpp"

namespace diffavatar {

ChamferLossResult chamfer_loss(const RefX3d& X, const RefX3i& F, const SurfaceSamples& samples,
                               const RefX3d& scan, double trim_distance, RunControl& rc,
                               const TriangleMeshBvh* scan_surface) {
  const Eigen::Index S = samples.tri.size(), T = scan.rows();
  if (samples.bary.rows() != S) throw std::invalid_argument("chamfer_loss: samples.tri and samples.bary differ in length");
  if (S == 0 || T == 0) throw std::invalid_argument("chamfer_loss: no garment samples or no scan points");
  for (Eigen::Index i = 0; i < S; ++i)
    if (samples.tri[i] < 0 || samples.tri[i] >= F.rows()) throw std::invalid_argument("chamfer_loss: sample triangle index out of range");
  const double trim_sq = trim_distance > 0 ? trim_distance * trim_distance : std::numeric_limits<double>::infinity();

  ChamferLossResult out;
  out.grad = RowMatX3d::Zero(X.rows(), 3);

  // garment samples → closest point of the scan surface, or nearest scan point
  rc.check("chamfer loss");
  AabbTree scan_tree;
  if (!scan_surface) {
    std::vector<AabbTree::Box> boxes(T);
    for (Eigen::Index j = 0; j < T; ++j) boxes[j] = AabbTree::Box(scan.row(j).transpose(), scan.row(j).transpose());
    scan_tree.build(boxes);
  }
  const double trim = std::isfinite(trim_sq) ? std::sqrt(trim_sq) : std::numeric_limits<double>::infinity();
  RowMatX3d g_res(S, 3);           // g_i − t_i (zero when trimmed)
  std::vector<char> g_keep(S);
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < S; ++i) {
    const int t = samples.tri[i];
    const Vec3 g = samples.bary(i, 0) * X.row(F(t, 0)).transpose() + samples.bary(i, 1) * X.row(F(t, 1)).transpose() +
                   samples.bary(i, 2) * X.row(F(t, 2)).transpose();
    if (scan_surface) {
      const SurfaceHit h = scan_surface->closest(g, trim);
      g_keep[i] = h.tri >= 0;
      g_res.row(i) = h.tri >= 0 ? Eigen::RowVector3d((g - h.point).transpose()) : Eigen::RowVector3d::Zero();
      continue;
    }
    double d_sq;
    const int j = scan_tree.closest(g, [&](int k) { return (scan.row(k).transpose() - g).squaredNorm(); }, trim_sq, d_sq);
    g_keep[i] = j >= 0;
    g_res.row(i) = j >= 0 ? Eigen::RowVector3d((g - scan.row(j).transpose()).transpose()) : Eigen::RowVector3d::Zero();
  }

  // scan points → closest point on the garment surface
  rc.check("chamfer loss");
  TriangleMeshBvh garment(X, F);
  RowMatX3d s_res(T, 3);           // c_j − s_j (zero when trimmed)
  std::vector<SurfaceHit> hits(T);
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < T; ++j) {
    const Vec3 s = scan.row(j);
    hits[j] = garment.closest(s, trim);
    s_res.row(j) = hits[j].tri >= 0 ? Eigen::RowVector3d((hits[j].point - s).transpose()) : Eigen::RowVector3d::Zero();
  }

  // serial accumulation in a fixed order: deterministic for any thread count
  int ng = 0, ns = 0;
  for (Eigen::Index i = 0; i < S; ++i) ng += g_keep[i];
  for (Eigen::Index j = 0; j < T; ++j) ns += hits[j].tri >= 0;
  out.garment_trimmed = static_cast<int>(S) - ng;
  out.scan_trimmed = static_cast<int>(T) - ns;
  if (ng > 0) {
    for (Eigen::Index i = 0; i < S; ++i) {
      if (!g_keep[i]) continue;
      out.garment_to_scan += g_res.row(i).squaredNorm();
      const int t = samples.tri[i];
      for (int k = 0; k < 3; ++k) out.grad.row(F(t, k)) += (samples.bary(i, k) / ng) * g_res.row(i);
    }
    out.garment_to_scan /= ng;
  }
  if (ns > 0) {
    for (Eigen::Index j = 0; j < T; ++j) {
      if (hits[j].tri < 0) continue;
      out.scan_to_garment += s_res.row(j).squaredNorm();
      for (int k = 0; k < 3; ++k) out.grad.row(F(hits[j].tri, k)) += (hits[j].bary[k] / ns) * s_res.row(j);
    }
    out.scan_to_garment /= ns;
  }
  out.value = 0.5 * (out.garment_to_scan + out.scan_to_garment);
  rc.report({"chamfer loss", 1, 1, out.value}, true);
  return out;
}

}  // namespace diffavatar
