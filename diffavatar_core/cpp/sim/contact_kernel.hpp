// One-sided cloth–body contact (paper Eq. 6) of a cloth vertex p against the plane of its
// closest body triangle (b0, b1, b2; outward unit normal n by the right-hand rule):
// C = n·(p − b0) − h ≥ 0 with collision thickness h (m). The plane of the triangle, not the
// closest point, makes C a smooth function of p and of the three body vertices while the
// contact's triangle is fixed (it is re-detected every step). Compliant penalty form:
// U = ½ k_c min(0, C)², k_c in N/m; the XPBD projection clamps λ ≥ 0 (push only).
#pragma once
#include "autodiff/jet.hpp"
#include "common/types.hpp"

namespace diffavatar {

template <class T>
T contact_gap(const V3<T>& p, const V3<T>& b0, const V3<T>& b1, const V3<T>& b2, double h) {
  V3<T> n = cross(b1 - b0, b2 - b0);
  return dot(n, p - b0) / norm(n) - h;
}

template <class T>
T contact_energy(const V3<T>& p, const V3<T>& b0, const V3<T>& b1, const V3<T>& b2, double h, double k) {
  T C = contact_gap(p, b0, b1, b2, h);
  if (value_of(C) >= 0.0) return T(0.0);
  return 0.5 * k * C * C;
}

/// XPBD projection with fixed plane (n, b0): Δλ = −(C + α̃λ)/(w + α̃), λ clamped ≥ 0.
inline void project_contact(Vec3& p, double w, const Vec3& n, const Vec3& b0, double h, double alpha_tilde,
                            double* lambda) {
  double C = n.dot(p - b0) - h;
  double dl = -(C + alpha_tilde * (*lambda)) / (w + alpha_tilde);
  double nl = *lambda + dl;
  if (nl < 0.0) nl = 0.0;
  dl = nl - *lambda;
  *lambda = nl;
  p += w * dl * n;
}

}  // namespace diffavatar
