// The linear system of the quasi-static refinement's Newton steps (XpbdSolver::refine): ∇ₓ²E over
// the free DOFs and its LDLᵀ factorization. Every Newton iteration of every refine() has the same
// sparsity — the mesh's element blocks; contacts and anchors add to vertices' diagonal blocks —
// so the pattern, each element entry's slot in it and the factorization's symbolic analysis (the
// fill-reducing ordering; the supernodes) are computed once and kept while `dof` and the pattern
// stay the same; an iteration only writes values. The matrix is energy_hessian's bit for bit (the
// same entries summed in the same order, cloth_energy.hpp scatter_hessian), so the Newton iterates
// are too. Copies start with an empty cache and the same choice of LDLᵀ. Units: J/m² (N/m).
#pragma once
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

#include "linalg/sparsity_pattern.hpp"
#include "linalg/supernodal_ldlt.hpp"
#include "sim/cloth_energy.hpp"

namespace diffavatar {

class NewtonSystem {
 public:
  using Matrix = Eigen::SparseMatrix<double>;

  NewtonSystem() = default;
  NewtonSystem(const NewtonSystem& o) : supernodal_(o.supernodal_) {}
  NewtonSystem& operator=(const NewtonSystem& o) {
    *this = NewtonSystem();
    supernodal_ = o.supernodal_;
    return *this;
  }
  NewtonSystem(NewtonSystem&&) = default;
  NewtonSystem& operator=(NewtonSystem&&) = default;

  /// ∇ₓ²E at x over the free DOFs (dof as energy_hessian's), element Hessians PSD-projected when
  /// project_psd: equal to energy_hessian(ctx, x, dof, project_psd) in pattern and every value.
  const Matrix& assemble(const EnergyContext& ctx, const RowMatX3d& x, const std::vector<int>& dof, bool project_psd);
  /// LDLᵀ of A (the assembled matrix or one with the same pattern, e.g. a damped diagonal); the
  /// symbolic analysis is redone only when A's pattern differs from the last one factorized.
  /// False on a zero pivot.
  bool factorize(const Matrix& A);
  /// A⁻¹ b by the last factorize().
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const;
  /// Which LDLᵀ: Eigen's SimplicialLDLT (the default here) or linalg/supernodal_ldlt.hpp (the same
  /// AMD ordering, the same solution up to round-off, 1.9–3.2× faster on the t-shirt's Hessians;
  /// docs/simulation.md "Newton's linear solver" says where each is used).
  void set_supernodal(bool on);
  bool supernodal() const { return supernodal_; }

 private:
  void build(const EnergyContext& ctx, const RowMatX3d& x, const std::vector<int>& dof, const ElementHessians& eh);
  std::vector<int> dof_;        // the free DOFs the pattern was built for
  Matrix H_;                    // the pattern; values of the last assemble()
  std::vector<int> slot_;       // value index of every fixed (element) entry, in scatter order (empty: no pattern)
  std::vector<int> diag_slot_;  // 9 per vertex: value index of (dof+i, dof+j), −1 if not in the pattern
  bool supernodal_ = false;
  std::unique_ptr<Eigen::SimplicialLDLT<Matrix>> simplicial_;
  std::unique_ptr<SupernodalLdlt> supernodal_ldlt_;
  SparsityPattern pattern_;  // the pattern the current factorization's symbolic analysis is of
};

}  // namespace diffavatar
