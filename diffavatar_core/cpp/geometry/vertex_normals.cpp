#include "geometry/vertex_normals.hpp"

#include <Eigen/Geometry>

namespace diffavatar {
namespace {

RowMatX3d area_weighted_sums(const RowMatX3d& V, const RowMatX3i& F) {
  RowMatX3d S = RowMatX3d::Zero(V.rows(), 3);
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Vec3 a = V.row(F(t, 0)), b = V.row(F(t, 1)), c = V.row(F(t, 2));
    const Eigen::RowVector3d n = (b - a).cross(c - a).transpose();
    for (int k = 0; k < 3; ++k) S.row(F(t, k)) += n;
  }
  return S;
}

}  // namespace

RowMatX3d vertex_normals(const RowMatX3d& V, const RowMatX3i& F) {
  RowMatX3d N = area_weighted_sums(V, F);
  for (Eigen::Index i = 0; i < N.rows(); ++i) {
    const double l = N.row(i).norm();
    N.row(i) = l > 0 ? Eigen::RowVector3d(N.row(i) / l) : Eigen::RowVector3d::Zero();
  }
  return N;
}

RowMatX3d vertex_normals_vjp(const RowMatX3d& V, const RowMatX3i& F, const RowMatX3d& gN) {
  // ∂N/∂S = (I − N Nᵀ)/|S| per vertex; then S_i ∋ n_f = e1 × e2 (e1 = b − a, e2 = c − a):
  // d(z·n_f) = de1·(e2 × z) + de2·(z × e1).
  const RowMatX3d S = area_weighted_sums(V, F);
  RowMatX3d Z = RowMatX3d::Zero(V.rows(), 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const double l = S.row(i).norm();
    if (!(l > 0)) continue;
    const Vec3 n = S.row(i).transpose() / l, g = gN.row(i).transpose();
    Z.row(i) = ((g - n * n.dot(g)) / l).transpose();
  }
  RowMatX3d gV = RowMatX3d::Zero(V.rows(), 3);
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Vec3 a = V.row(F(t, 0)), e1 = V.row(F(t, 1)).transpose() - a, e2 = V.row(F(t, 2)).transpose() - a;
    const Vec3 z = (Z.row(F(t, 0)) + Z.row(F(t, 1)) + Z.row(F(t, 2))).transpose();
    const Vec3 g1 = e2.cross(z), g2 = z.cross(e1);
    gV.row(F(t, 0)) -= (g1 + g2).transpose();
    gV.row(F(t, 1)) += g1.transpose();
    gV.row(F(t, 2)) += g2.transpose();
  }
  return gV;
}

}  // namespace diffavatar
