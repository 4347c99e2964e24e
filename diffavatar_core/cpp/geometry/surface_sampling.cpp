#include "geometry/surface_sampling.hpp"

#include <Eigen/Geometry>  // cross()
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace diffavatar {

RowMatX3d sample_surface(const RefX3d& V, const RefX3i& F, int n, uint64_t seed, VecXi* tri_of) {
  if (n < 0) throw std::invalid_argument("sample_surface: negative sample count");
  std::vector<double> cum(F.rows());
  double total = 0.0;
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Vec3 a = V.row(F(t, 0)), b = V.row(F(t, 1)), c = V.row(F(t, 2));
    total += 0.5 * (b - a).cross(c - a).norm();
    cum[t] = total;
  }
  if (!(total > 0.0)) throw std::invalid_argument("sample_surface: the mesh has zero surface area");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  RowMatX3d P(n, 3);
  if (tri_of) tri_of->resize(n);
  for (int i = 0; i < n; ++i) {
    const double r = u01(rng) * total;
    const int t = static_cast<int>(std::min<std::ptrdiff_t>(
        std::upper_bound(cum.begin(), cum.end(), r) - cum.begin(), F.rows() - 1));
    // uniform point in a triangle: (1-√r1) a + √r1 (1-r2) b + √r1 r2 c
    const double s = std::sqrt(u01(rng)), r2 = u01(rng);
    P.row(i) = (1.0 - s) * V.row(F(t, 0)) + s * (1.0 - r2) * V.row(F(t, 1)) + s * r2 * V.row(F(t, 2));
    if (tri_of) (*tri_of)[i] = t;
  }
  return P;
}

}  // namespace diffavatar
