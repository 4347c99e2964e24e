#include "adjoint/equilibrium_adjoint.hpp"

#include <Eigen/SparseCholesky>
#include <chrono>
#include <stdexcept>

namespace diffavatar {

ControlGradient equilibrium_adjoint(const XpbdSolver& solver, const RowMatX3d& x, const RowMatX3d& dphi_dx,
                                    const Vec3& gravity, RunControl& rc, AdjointReport* report) {
  auto t0 = std::chrono::steady_clock::now();
  const ClothModel& m = solver.model();
  if (x.rows() != m.num_vertices || dphi_dx.rows() != m.num_vertices)
    throw std::invalid_argument("equilibrium adjoint: x and dphi_dx must be #V×3");
  EnergyContext ctx = solver.energy_context(gravity);
  const std::vector<int> dof = solver.free_dofs();
  int n = 0;
  for (int d : dof) n = std::max(n, d + 3);
  rc.check("equilibrium adjoint");
  rc.report({"adjoint", 0, 2, 0.0}, true);
  Eigen::SparseMatrix<double> H = energy_hessian(ctx, x, dof, false);
  VecXd b(n);
  for (int i = 0; i < m.num_vertices; ++i)
    if (dof[i] >= 0) b.segment<3>(dof[i]) = dphi_dx.row(i).transpose();
  rc.check("equilibrium adjoint");
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  if (ldlt.info() != Eigen::Success)
    throw std::runtime_error("equilibrium adjoint: the energy Hessian is singular at this state (not an isolated "
                             "equilibrium: unconstrained rigid motion or an unconverged drape)");
  VecXd mu = ldlt.solve(b);
  RowMatX3d MU = RowMatX3d::Zero(m.num_vertices, 3);
  for (int i = 0; i < m.num_vertices; ++i)
    if (dof[i] >= 0) MU.row(i) = mu.segment<3>(dof[i]).transpose();
  ControlGradient g = mixed_product(ctx, x, MU);
  g.rest *= -1.0;
  g.stretch_compliance *= -1.0;
  g.bend_stiffness *= -1.0;
  g.body_vertices *= -1.0;
  if (report) {
    double bn = b.norm();
    report->solve_residual = bn > 0 ? (H * mu - b).norm() / bn : 0.0;
    report->dofs = n;
    report->mu = MU;
    report->wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  rc.report({"adjoint", 2, 2, 0.0}, true);
  return g;
}

}  // namespace diffavatar
