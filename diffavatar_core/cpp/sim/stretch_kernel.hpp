// Orthotropic StVK stretching/shearing of one triangle as one XPBD constraint block
// (paper §3.2 Eq. 1–2; supplement Eq. 9): C = [ε00, ε11, ε01] of the Green strain
// ε = ½(FᵀF − I), F = D D̄⁻¹, D = [x1−x0, x2−x0] (3×2, m), D̄ = [ū1−ū0, ū2−ū0] (2×2, m, the
// sewing pattern, expressed in the fabric's grain frame by the caller: grain_frame.hpp). With the
// rest corners in that frame, component 0 is the warp, 1 the weft, 2 the shear.
// Energy U = Ā (ε00²/2α_warp + ε11²/2α_weft + ε01²/2α_shear), i.e. ½ Cᵀ α̃⁻¹ C with
// α̃ = diag(α)/Ā; α in m/N (inverse 2D stiffness), Ā the rest area (m²), U in J.
#pragma once
#include <Eigen/Dense>
#include <Eigen/LU>
#include <array>

#include "autodiff/jet.hpp"
#include "common/types.hpp"

namespace diffavatar {

/// Green strain [ε00, ε11, ε01] (dimensionless) of a triangle with deformed corners x (m) and
/// rest corners u (m). Generic in the scalar for exact derivatives.
template <class T>
std::array<T, 3> green_strain(const V3<T> x[3], const T u[3][2]) {
  T a = u[1][0] - u[0][0], b = u[2][0] - u[0][0];  // D̄ = [[a, b], [c, d]]
  T c = u[1][1] - u[0][1], d = u[2][1] - u[0][1];
  T det = a * d - b * c;
  // B = D̄⁻¹ = [[d, -b], [-c, a]] / det
  T B00 = d / det, B01 = -b / det, B10 = -c / det, B11 = a / det;
  V3<T> d1 = x[1] - x[0], d2 = x[2] - x[0];
  V3<T> f0 = d1 * B00 + d2 * B10, f1 = d1 * B01 + d2 * B11;
  return {0.5 * (dot(f0, f0) - 1.0), 0.5 * (dot(f1, f1) - 1.0), 0.5 * dot(f0, f1)};
}

/// Signed rest area ½ det D̄ (m²); positive for a counter-clockwise rest triangle.
template <class T>
T rest_area(const T u[3][2]) {
  return 0.5 * ((u[1][0] - u[0][0]) * (u[2][1] - u[0][1]) - (u[2][0] - u[0][0]) * (u[1][1] - u[0][1]));
}

/// Stretch energy (J); alpha = (α_warp, α_weft, α_shear) in m/N.
template <class T>
T stretch_energy(const V3<T> x[3], const T u[3][2], const T alpha[3]) {
  auto e = green_strain(x, u);
  T A = rest_area(u);
  return A * (0.5 * e[0] * e[0] / alpha[0] + 0.5 * e[1] * e[1] / alpha[1] + 0.5 * e[2] * e[2] / alpha[2]);
}

/// Per-triangle rest data cached from the control (rest shape): B = D̄⁻¹ and area Ā.
struct StretchRest {
  Eigen::Matrix2d B;
  double area;
};

inline StretchRest stretch_rest(const Vec2& u0, const Vec2& u1, const Vec2& u2) {
  Eigen::Matrix2d Dm;
  Dm.col(0) = u1 - u0;
  Dm.col(1) = u2 - u0;
  return {Dm.inverse(), 0.5 * Dm.determinant()};
}

/// Closed-form gradient (9) and Hessian (9×9) of the stretch energy over the corners
/// [x0 x1 x2] (m) — what Newton and the equilibrium adjoint need per step, without the jets of
/// the generic kernels. With f_j = Σ_k c_j[k] x_k the columns of F (c_j[k] = ∂f_j/∂x_k, from B),
/// κ_a = Ā/α_a (J) and ε as in green_strain:
///   ∂U/∂f0 = κ0 ε00 f0 + ½κ2 ε01 f1,  ∂U/∂f1 = κ1 ε11 f1 + ½κ2 ε01 f0,
///   ∂²U/∂f0² = κ0 (f0 f0ᵀ + ε00 I) + ¼κ2 f1 f1ᵀ,  ∂²U/∂f1² = κ1 (f1 f1ᵀ + ε11 I) + ¼κ2 f0 f0ᵀ,
///   ∂²U/∂f0∂f1 = ¼κ2 f1 f0ᵀ + ½κ2 ε01 I;
/// ∇_k U = Σ_j c_j[k] ∂U/∂f_j and ∇²_{kl} U = Σ_{ij} c_i[k] c_j[l] ∂²U/∂f_i∂f_j (J/m, J/m²).
/// g or H may be null (not wanted). alpha = (α_warp, α_weft, α_shear) in m/N.
inline void stretch_derivatives(const Vec3 x[3], const StretchRest& r, const Vec3& alpha,
                                Eigen::Matrix<double, 9, 1>* g, Eigen::Matrix<double, 9, 9>* H) {
  const Eigen::Matrix2d& B = r.B;
  const Vec3 d1 = x[1] - x[0], d2 = x[2] - x[0];
  const Vec3 f0 = d1 * B(0, 0) + d2 * B(1, 0), f1 = d1 * B(0, 1) + d2 * B(1, 1);
  const double e0 = 0.5 * (f0.squaredNorm() - 1.0), e1 = 0.5 * (f1.squaredNorm() - 1.0), e2 = 0.5 * f0.dot(f1);
  const double k0 = r.area / alpha[0], k1 = r.area / alpha[1], k2 = r.area / alpha[2];
  const double c[2][3] = {{-(B(0, 0) + B(1, 0)), B(0, 0), B(1, 0)}, {-(B(0, 1) + B(1, 1)), B(0, 1), B(1, 1)}};
  if (g) {
    const Vec3 P0 = k0 * e0 * f0 + 0.5 * k2 * e2 * f1, P1 = k1 * e1 * f1 + 0.5 * k2 * e2 * f0;
    for (int k = 0; k < 3; ++k) g->segment<3>(3 * k) = c[0][k] * P0 + c[1][k] * P1;
  }
  if (!H) return;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d Hf[2][2];
  Hf[0][0] = k0 * (f0 * f0.transpose() + e0 * I) + 0.25 * k2 * f1 * f1.transpose();
  Hf[1][1] = k1 * (f1 * f1.transpose() + e1 * I) + 0.25 * k2 * f0 * f0.transpose();
  Hf[0][1] = 0.25 * k2 * f1 * f0.transpose() + 0.5 * k2 * e2 * I;
  Hf[1][0] = Hf[0][1].transpose();
  for (int k = 0; k < 3; ++k)
    for (int l = 0; l < 3; ++l)
      H->block<3, 3>(3 * k, 3 * l) = c[0][k] * c[0][l] * Hf[0][0] + c[0][k] * c[1][l] * Hf[0][1] +
                                     c[1][k] * c[0][l] * Hf[1][0] + c[1][k] * c[1][l] * Hf[1][1];
}

/// One XPBD projection of the triangle block (3×3 solve of paper Eq. 2):
/// Δλ = −(∇C W ∇Cᵀ + α̃)⁻¹ (C + α̃ λ), Δx_k = w_k ∇_k Cᵀ Δλ. alpha_tilde = diag(α)/(Ā dt²).
/// Returns nothing; updates p[0..2] and lambda in place.
inline void project_stretch(Vec3* p[3], const double w[3], const StretchRest& r, const Vec3& alpha_tilde,
                            double* lambda) {
  const Eigen::Matrix2d& B = r.B;
  Vec3 d1 = *p[1] - *p[0], d2 = *p[2] - *p[0];
  Vec3 f0 = d1 * B(0, 0) + d2 * B(1, 0), f1 = d1 * B(0, 1) + d2 * B(1, 1);
  Vec3 C(0.5 * (f0.squaredNorm() - 1.0), 0.5 * (f1.squaredNorm() - 1.0), 0.5 * f0.dot(f1));
  // coefficients c_k0, c_k1 of ∂f0/∂x_k, ∂f1/∂x_k (times identity)
  double c0[3] = {-(B(0, 0) + B(1, 0)), B(0, 0), B(1, 0)};
  double c1[3] = {-(B(0, 1) + B(1, 1)), B(0, 1), B(1, 1)};
  Vec3 grad[3][3];  // grad[a][k] = ∂C_a/∂x_k
  for (int k = 0; k < 3; ++k) {
    grad[0][k] = c0[k] * f0;
    grad[1][k] = c1[k] * f1;
    grad[2][k] = 0.5 * (c0[k] * f1 + c1[k] * f0);
  }
  Eigen::Matrix3d A = alpha_tilde.asDiagonal();
  for (int a = 0; a < 3; ++a)
    for (int b = a; b < 3; ++b) {
      double s = 0.0;
      for (int k = 0; k < 3; ++k) s += w[k] * grad[a][k].dot(grad[b][k]);
      A(a, b) += s;
      if (b != a) A(b, a) += s;
    }
  Vec3 lam(lambda[0], lambda[1], lambda[2]);
  Vec3 rhs = -(C + alpha_tilde.cwiseProduct(lam));
  Vec3 dl = A.inverse() * rhs;  // SPD 3×3: closed-form cofactor inverse
  for (int a = 0; a < 3; ++a) lambda[a] += dl[a];
  for (int k = 0; k < 3; ++k) {
    if (w[k] == 0.0) continue;
    *p[k] += w[k] * (grad[0][k] * dl[0] + grad[1][k] * dl[1] + grad[2][k] * dl[2]);
  }
}

}  // namespace diffavatar
