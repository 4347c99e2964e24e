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

/// ∇θ of dihedral_gradient and its directional derivative D(∇θ)[v], the same closed form
/// differentiated once (forward mode, by hand): the trajectory adjoint's Hessian-vector products
/// and, column by column, the Newton Hessian ∇²θ. θ itself is not computed (the tape or
/// dihedral_gradient has it).
/// `ok` is false when degenerate (the same test as dihedral_gradient).
struct HingeGeom {
  using V = Eigen::Vector3d;
  V e, ca, da, eh, n1, n2, m1, m2;
  double el, q1, q2, t3, t4, iel, iq1, iq2;  // iel = 1/|e|, iq = 1/q
  bool ok;
  V g[4];  // ∇_a θ, ∇_b θ, ∇_c θ, ∇_d θ

  // With c − b = (c − a) − e and e·ê = |e|: (c−b)·ê = t3 − |e|, (d−b)·ê = t4 − |e|, and
  // ∇_a θ = −(∇_b θ + ∇_c θ + ∇_d θ) (translation invariance); likewise for the tangent.
  explicit HingeGeom(const double* x) {
    const Eigen::Map<const V> a(x), b(x + 3), c(x + 6), d(x + 9);
    e = b - a;
    ca = c - a;
    da = d - a;
    el = e.norm();
    n1 = e.cross(ca);
    n2 = da.cross(e);
    q1 = n1.squaredNorm();
    q2 = n2.squaredNorm();
    ok = !(el < 1e-12 || q1 < 1e-30 || q2 < 1e-30);
    if (!ok) return;
    iel = 1.0 / el;
    iq1 = 1.0 / q1;
    iq2 = 1.0 / q2;
    eh = e * iel;
    m1 = n1 * iq1;
    m2 = n2 * iq2;
    t3 = ca.dot(eh);
    t4 = da.dot(eh);
    g[1] = t3 * m1 + t4 * m2;
    g[2] = -el * m1;
    g[3] = -el * m2;
    g[0] = -(g[1] + g[2] + g[3]);
  }
  /// gt[k] = D(∇_k θ)[v], v = (v_a, v_b, v_c, v_d) as 12 doubles.
  void tangent(const double* v, V gt[4]) const {
    const Eigen::Map<const V> va(v), vb(v + 3), vc(v + 6), vd(v + 9);
    const V de = vb - va, dca = vc - va, dda = vd - va;
    const V dn1 = de.cross(ca) + e.cross(dca), dn2 = dda.cross(e) + da.cross(de);
    const double del = eh.dot(de);
    const V deh = (de - eh * del) * iel;
    const V dm1 = (dn1 - m1 * (2.0 * n1.dot(dn1))) * iq1, dm2 = (dn2 - m2 * (2.0 * n2.dot(dn2))) * iq2;
    const double dt3 = dca.dot(eh) + ca.dot(deh), dt4 = dda.dot(eh) + da.dot(deh);
    gt[1] = dt3 * m1 + t3 * dm1 + dt4 * m2 + t4 * dm2;
    gt[2] = -del * m1 - el * dm1;
    gt[3] = -del * m2 - el * dm2;
    gt[0] = -(gt[1] + gt[2] + gt[3]);
  }
  /// ∇²θ (12×12, 1/m²) over (a, b, c, d): the tangents along the unit vectors, symmetrized.
  Eigen::Matrix<double, 12, 12> hessian() const {
    Eigen::Matrix<double, 12, 12> H;
    double v[12] = {0.0};
    V gt[4];
    for (int j = 0; j < 12; ++j) {
      v[j] = 1.0;
      tangent(v, gt);
      for (int k = 0; k < 4; ++k) H.block<3, 1>(3 * k, j) = gt[k];
      v[j] = 0.0;
    }
    return 0.5 * (H + H.transpose());
  }
};

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
