// Sewing constraint between paired boundary vertices of two panels (zero rest length):
// C = x_i − x_j (3 components, m), energy U = |x_i − x_j|²/(2 α_seam), α_seam in m/N.
#pragma once
#include "autodiff/jet.hpp"
#include "common/types.hpp"

namespace diffavatar {

template <class T>
T seam_energy(const V3<T>& xi, const V3<T>& xj, double alpha) {
  V3<T> d = xi - xj;
  return dot(d, d) * (0.5 / alpha);
}

/// XPBD projection (components decouple): Δλ = −(C + α̃λ)/(w_i + w_j + α̃).
inline void project_seam(Vec3& xi, Vec3& xj, double wi, double wj, double alpha_tilde, double* lambda) {
  double denom = wi + wj + alpha_tilde;
  if (denom <= 0.0) return;
  Vec3 C = xi - xj;
  for (int a = 0; a < 3; ++a) {
    double dl = -(C[a] + alpha_tilde * lambda[a]) / denom;
    lambda[a] += dl;
    xi[a] += wi * dl;
    xj[a] -= wj * dl;
  }
}

}  // namespace diffavatar
