// Dihedral-angle (hinge) bending on an interior edge (DiffXPBD's bending constraint; paper
// §3.2): hinge vertices (a, b) = shared edge, c and d the opposite vertices of its two
// triangles. θ = atan2((n1×n2)·ê, n1·n2) with n1 = (b−a)×(c−a), n2 = (d−a)×(b−a), so θ = 0 for
// a flat hinge. C = θ − θ0 (rad), energy U = ½ k w (θ − θ0)² with bending stiffness k (N·m)
// and the rest-shape weight w = 3|ē|²/(Ā1 + Ā2) (dimensionless) from the pattern; compliance
// α̃ = 1/(k w dt²).
#pragma once
#include <Eigen/Geometry>
#include <cmath>

#include "autodiff/jet.hpp"
#include "common/types.hpp"

namespace diffavatar {

template <class T>
T dihedral_angle(const V3<T>& a, const V3<T>& b, const V3<T>& c, const V3<T>& d) {
  V3<T> e = b - a;
  V3<T> n1 = cross(e, c - a), n2 = cross(d - a, e);
  T s = dot(cross(n1, n2), e) / norm(e);
  return atan2(s, dot(n1, n2));
}

/// Hinge weight w = 3|ē|²/(Ā1+Ā2) from the rest (pattern) coordinates of a, b, c, d (m).
template <class T>
T hinge_weight(const T a[2], const T b[2], const T c[2], const T d[2]) {
  auto area = [](const T p[2], const T q[2], const T r[2]) {
    T s = (q[0] - p[0]) * (r[1] - p[1]) - (r[0] - p[0]) * (q[1] - p[1]);
    return value_of(s) >= 0 ? 0.5 * s : -0.5 * s;
  };
  T ex = b[0] - a[0], ey = b[1] - a[1];
  return 3.0 * (ex * ex + ey * ey) / (area(a, b, c) + area(a, b, d));
}

template <class T>
T bending_energy(const V3<T> x[4], const T u[4][2], const T& k, double theta0) {
  T th = dihedral_angle(x[0], x[1], x[2], x[3]) - theta0;
  return 0.5 * k * hinge_weight(u[0], u[1], u[2], u[3]) * th * th;
}

/// Closed-form ∇θ of the dihedral angle (Bridson et al. 2003, in this file's orientation):
/// with n1 = e×(c−a), n2 = (d−a)×e, e = b − a:
///   ∇_c θ = −|e| n1/|n1|²,  ∇_d θ = −|e| n2/|n2|²,
///   ∇_a θ = −((c−b)·ê) n1/|n1|² − ((d−b)·ê) n2/|n2|²,  ∇_b θ = ((c−a)·ê) n1/|n1|² + ((d−a)·ê) n2/|n2|²
/// (Σ_k ∇_k θ = 0). Checked against the autodiff version in the tests. False if degenerate.
inline bool dihedral_gradient(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, double* theta,
                              Vec3 g[4]) {
  Vec3 e = b - a;
  double el = e.norm();
  Vec3 n1 = e.cross(c - a), n2 = (d - a).cross(e);
  double q1 = n1.squaredNorm(), q2 = n2.squaredNorm();
  if (el < 1e-12 || q1 < 1e-30 || q2 < 1e-30) return false;
  Vec3 eh = e / el;
  *theta = std::atan2(n1.cross(n2).dot(eh), n1.dot(n2));
  Vec3 m1 = n1 / q1, m2 = n2 / q2;
  g[2] = -el * m1;
  g[3] = -el * m2;
  g[0] = -((c - b).dot(eh)) * m1 - ((d - b).dot(eh)) * m2;
  g[1] = ((c - a).dot(eh)) * m1 + ((d - a).dot(eh)) * m2;
  return true;
}

/// One XPBD projection of a hinge: Δλ = −(C + α̃λ)/(Σ w_k|∇_k C|² + α̃), Δx_k = w_k ∇_k C Δλ.
/// theta_out (or null) receives the measured θ (rad) for the adjoint's tape.
inline void project_bending(Vec3* p[4], const double w[4], double theta0, double alpha_tilde, double* lambda,
                            double* theta_out = nullptr) {
  double th;
  Vec3 g[4];
  if (!dihedral_gradient(*p[0], *p[1], *p[2], *p[3], &th, g)) return;
  if (theta_out) *theta_out = th;
  double C = th - theta0;
  double denom = alpha_tilde;
  for (int k = 0; k < 4; ++k) denom += w[k] * g[k].squaredNorm();
  if (denom <= 0.0) return;
  double dl = -(C + alpha_tilde * (*lambda)) / denom;
  *lambda += dl;
  for (int k = 0; k < 4; ++k)
    if (w[k] != 0.0) *p[k] += w[k] * dl * g[k];
}

}  // namespace diffavatar
