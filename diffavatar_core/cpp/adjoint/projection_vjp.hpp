// Reverse mode of one XPBD constraint-block projection (paper Eq. 2; DiffXPBD, supplement
// Eq. 1–4). Forward, for a block with m components over z = (x (n dofs), q (params)):
//   G = ∂C/∂x, A = G W Gᵀ + diag(α̃), r = C + α̃∘λ, Δλ = −A⁻¹ r, x' = x + W Gᵀ Δλ, λ' = λ + Δλ
// (for a one-sided contact with λ + Δλ < 0: Δλ = −λ). Given x̄', λ̄' block_adjoint returns the
// adjoints of λ and α̃ and the adjoints of the block's two z-dependent inputs, C̄ and Ḡ; the
// adjoint of z (beyond the identity pass-through of x) is then
//   z̄ = ∇_z ψ(z),  ψ(z) = Σ_a C̄_a C_a(z) + Σ_a Ḡ_a · ∇ₓC_a(z),
// i.e. Jᵀ C̄ + Σ_a (∂²C_a/∂z∂x) Ḡ_aᵀ, the Hessian-vector products of the constraint without its
// Hessian. The reverse kernels (trajectory_adjoint.cpp) differentiate ψ in closed form: the
// stretch block and the hinge specialise this function to their structure, the seam and the
// contact call it. All sizes are fixed at compile time (no heap allocation per projection).
#pragma once
#include <Eigen/Dense>

namespace diffavatar {

template <int M, int N>
struct BlockAdjoint {
  Eigen::Matrix<double, M, N> Gbar;  // adjoint of G = ∂C/∂x
  Eigen::Matrix<double, M, 1> Cbar;  // adjoint of C
  Eigen::Matrix<double, M, 1> lbar;  // adjoint of λ before the projection
  Eigen::Matrix<double, M, 1> atbar; // adjoint of α̃
};

template <int M, int N>
inline BlockAdjoint<M, N> block_adjoint(const Eigen::Matrix<double, M, 1>& C, const Eigen::Matrix<double, M, N>& G,
                                        const Eigen::Matrix<double, N, 1>& wdof, const Eigen::Matrix<double, M, 1>& at,
                                        const Eigen::Matrix<double, M, 1>& lam, bool clamp_nonneg,
                                        const Eigen::Matrix<double, N, 1>& xbar_out,
                                        const Eigen::Matrix<double, M, 1>& lbar_out) {
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM = Eigen::Matrix<double, M, M>;
  const Eigen::Matrix<double, M, N> GW = G * wdof.asDiagonal();
  MatM A = GW * G.transpose();
  A.diagonal() += at;
  const VecM r = C + at.cwiseProduct(lam);
  // A is SPD (α̃ > 0) and at most 3×3: Eigen's closed-form inverse, as in the forward projection.
  const MatM Ainv = A.inverse();
  VecM dl = -(Ainv * r);
  const Eigen::Matrix<double, N, 1> s = wdof.cwiseProduct(xbar_out);
  BlockAdjoint<M, N> out;
  if (clamp_nonneg && lam[0] + dl[0] < 0.0) {
    dl = -lam;
    out.Gbar = dl * s.transpose();
    out.lbar = -(G * s);
    out.Cbar.setZero();
    out.atbar.setZero();
  } else {
    const VecM dlbar = G * s + lbar_out;
    out.Gbar = dl * s.transpose();
    const VecM u = Ainv * dlbar;
    const MatM Abar = -u * dl.transpose();
    out.Gbar += (Abar + Abar.transpose()) * GW;
    out.atbar = Abar.diagonal() - u.cwiseProduct(lam);
    out.lbar = lbar_out - at.cwiseProduct(u);
    out.Cbar = -u;
  }
  return out;
}

}  // namespace diffavatar
