// Gauss–Newton normal equations of a weighted least-squares problem (body fitting, paper
// §4.1): H = Jᵀ W J, g = Jᵀ W r for residuals r (n, units of the data, here m), Jacobian J
// (n×P row-major) and weights w (n, ≥ 0); and the damped solve (H + λ diag(H) + εI) δ = −g.
// Computed here rather than with numpy so that the core's OpenMP threads and a multi-threaded
// BLAS do not contend on a shared machine.
#pragma once
#include <utility>

#include "common/types.hpp"

namespace diffavatar {

/// (H: P×P, g: P) of the weighted problem; throws std::invalid_argument on size mismatch.
std::pair<Eigen::MatrixXd, VecXd> normal_equations(const Eigen::Ref<const RowMatXd>& J, const RefXd& w,
                                                   const RefXd& r);

/// Levenberg–Marquardt step δ solving (H + λ diag(H) + 1e-12 I) δ = −g (LDLᵀ).
VecXd damped_step(const Eigen::MatrixXd& H, const VecXd& g, double lambda);

}  // namespace diffavatar
