#include "sim/newton_system.hpp"

#include <algorithm>

namespace diffavatar {

void NewtonSystem::build(const EnergyContext& ctx, const RowMatX3d& x, const std::vector<int>& dof,
                         const ElementHessians& eh) {
  int n = 0;
  for (int d : dof) n = std::max(n, d + 3);
  // The fixed entries' pattern: setFromTriplets as energy_hessian, without the diagonal extras
  // (they land in blocks every vertex of a triangle has).
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(ctx.model.faces.rows() * 81 + ctx.model.hinges.rows() * 144 + ctx.model.seams.rows() * 36);
  scatter_hessian(
      ctx, x, dof, eh, [&](int r, int c, double) { trip.emplace_back(r, c, 0.0); }, [](int, int, int, double) {});
  H_ = Matrix(n, n);
  H_.setFromTriplets(trip.begin(), trip.end());
  H_.makeCompressed();
  const int* outer = H_.outerIndexPtr();
  const int* inner = H_.innerIndexPtr();
  auto find = [&](int r, int c) -> int {  // value index of (r, c), −1 if absent (column-major)
    const int* lo = inner + outer[c];
    const int* hi = inner + outer[c + 1];
    const int* it = std::lower_bound(lo, hi, r);
    return it != hi && *it == r ? static_cast<int>(it - inner) : -1;
  };
  slot_.resize(trip.size());
  for (std::size_t k = 0; k < trip.size(); ++k) slot_[k] = find(trip[k].row(), trip[k].col());
  diag_slot_.assign(dof.size() * 9, -1);
  for (std::size_t v = 0; v < dof.size(); ++v)
    if (dof[v] >= 0)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) diag_slot_[9 * v + 3 * i + j] = find(dof[v] + i, dof[v] + j);
  dof_ = dof;
}

const NewtonSystem::Matrix& NewtonSystem::assemble(const EnergyContext& ctx, const RowMatX3d& x,
                                                   const std::vector<int>& dof, bool project_psd) {
  const ElementHessians eh = element_hessians(ctx, x, project_psd);
  if (slot_.empty() || dof != dof_) build(ctx, x, dof, eh);
  double* val = H_.valuePtr();
  std::fill(val, val + H_.nonZeros(), 0.0);
  std::size_t k = 0;
  bool outside = false;  // a diagonal entry the pattern lacks (a vertex in no element)
  scatter_hessian(
      ctx, x, dof, eh, [&](int, int, double v) { val[slot_[k++]] += v; },
      [&](int vtx, int i, int j, double v) {
        const int s = diag_slot_[9 * vtx + 3 * i + j];
        if (s < 0)
          outside = true;
        else
          val[s] += v;
      });
  if (outside) {  // the triplet assembly's pattern has it: use that matrix (and rebuild next time)
    H_ = energy_hessian(ctx, x, dof, project_psd);
    slot_.clear();
  }
  return H_;
}

bool NewtonSystem::factorize(const Matrix& A) {
  const bool same = pattern_.matches(A);
  const bool fresh = supernodal_ ? !supernodal_ldlt_ : !simplicial_;
  if (supernodal_ && !supernodal_ldlt_) supernodal_ldlt_ = std::make_unique<SupernodalLdlt>();
  if (!supernodal_ && !simplicial_) simplicial_ = std::make_unique<Eigen::SimplicialLDLT<Matrix>>();
  if (!same || fresh) {
    if (supernodal_)
      supernodal_ldlt_->analyzePattern(A);
    else
      simplicial_->analyzePattern(A);
    pattern_.assign(A);
  }
  if (supernodal_) {
    supernodal_ldlt_->factorize(A);
    return supernodal_ldlt_->info() == Eigen::Success;
  }
  simplicial_->factorize(A);
  return simplicial_->info() == Eigen::Success;
}

Eigen::VectorXd NewtonSystem::solve(const Eigen::VectorXd& b) const {
  return supernodal_ ? supernodal_ldlt_->solve(b) : Eigen::VectorXd(simplicial_->solve(b));
}

void NewtonSystem::set_supernodal(bool on) {
  if (on == supernodal_) return;
  supernodal_ = on;
  simplicial_.reset();
  supernodal_ldlt_.reset();
  pattern_.clear();
}

}  // namespace diffavatar
