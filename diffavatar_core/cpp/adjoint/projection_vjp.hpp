// Reverse mode of one XPBD constraint-block projection (paper Eq. 2; DiffXPBD, supplement
// Eq. 1–4). Forward, for a block with m components over z = (x (n dofs), q (params)):
//   G = ∂C/∂x, A = G W Gᵀ + diag(α̃), r = C + α̃∘λ, Δλ = −A⁻¹ r, x' = x + W Gᵀ Δλ, λ' = λ + Δλ
// (for a one-sided contact with λ + Δλ < 0: Δλ = −λ). Given x̄', λ̄' this returns the adjoints
// of z (beyond the identity pass-through of x), λ and α̃, using C, its gradient J = ∂C/∂z and the
// Hessians ∂²C_a/∂z² (from autodiff/jet.hpp), so the result is exact.
#pragma once
#include <Eigen/Dense>
#include <vector>

namespace diffavatar {

struct BlockVjp {
  Eigen::VectorXd zbar;   // n + np: adjoint of z (add x̄' for the x part yourself)
  Eigen::VectorXd lbar;   // m: adjoint of λ before the projection
  Eigen::VectorXd atbar;  // m: adjoint of α̃
};

inline BlockVjp block_vjp(int n, const Eigen::VectorXd& C, const Eigen::MatrixXd& J,
                          const std::vector<Eigen::MatrixXd>& H, const Eigen::VectorXd& wdof,
                          const Eigen::VectorXd& at, const Eigen::VectorXd& lam, bool clamp_nonneg,
                          const Eigen::VectorXd& xbar_out, const Eigen::VectorXd& lbar_out) {
  const int m = static_cast<int>(C.size());
  const int nz = static_cast<int>(J.cols());
  Eigen::MatrixXd G = J.leftCols(n);
  Eigen::MatrixXd GW = G * wdof.asDiagonal();
  Eigen::MatrixXd A = GW * G.transpose();
  A.diagonal() += at;
  Eigen::VectorXd r = C + at.cwiseProduct(lam);
  Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
  Eigen::VectorXd dl = -ldlt.solve(r);
  BlockVjp out{Eigen::VectorXd::Zero(nz), Eigen::VectorXd::Zero(m), Eigen::VectorXd::Zero(m)};
  Eigen::VectorXd s = wdof.cwiseProduct(xbar_out);
  Eigen::MatrixXd Gbar;
  if (clamp_nonneg && lam[0] + dl[0] < 0.0) {
    dl = -lam;
    Gbar = dl * s.transpose();
    out.lbar = -(G * s);
  } else {
    Eigen::VectorXd dlbar = G * s + lbar_out;
    Gbar = dl * s.transpose();
    Eigen::VectorXd u = ldlt.solve(dlbar);
    Eigen::MatrixXd Abar = -u * dl.transpose();
    Gbar += (Abar + Abar.transpose()) * GW;
    out.atbar = Abar.diagonal() - u.cwiseProduct(lam);
    out.lbar = lbar_out - at.cwiseProduct(u);
    out.zbar += J.transpose() * (-u);
  }
  for (int a = 0; a < m; ++a) out.zbar += H[a].leftCols(n) * Gbar.row(a).transpose();
  return out;
}

}  // namespace diffavatar
