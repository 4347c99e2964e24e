#include "geometry/mesh_quality.hpp"

#include <Eigen/Geometry>  // cross()

namespace diffavatar {

VecXd triangle_quality(const RefX3d& V, const RefX3i& F) {
  VecXd q(F.rows());
#pragma omp parallel for schedule(static)
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Vec3 a = V.row(F(t, 0)), b = V.row(F(t, 1)), c = V.row(F(t, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const double l2 = (b - a).squaredNorm() + (c - b).squaredNorm() + (a - c).squaredNorm();
    q[t] = l2 > 0.0 ? 3.0 * area / l2 : 0.0;
  }
  return q;
}

}  // namespace diffavatar
