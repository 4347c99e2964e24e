// Sparse LDLᵀ (no pivoting) of a symmetric matrix by supernodes: the linear solve of the Newton
// refinement (sim/newton_system.hpp: the quasi-static drape's equilibrium ∇ₓE = 0). Columns of L
// with the same structure below them (a vertex's three DOFs at least; small groups merged with
// their parent as CHOLMOD relaxes them) are factorized together as one dense frontal matrix
// (multifrontal: a dense partial LDLᵀ, then the Schur complement added into the parent's front),
// so the work is dense matrix products instead of Eigen::SimplicialLDLT's row-by-row sparse
// updates. The same AMD ordering as SimplicialLDLT's, the same factors up to round-off; a zero
// pivot fails as SimplicialLDLT's does (info() = NumericalIssue). The symbolic analysis depends
// only on the pattern and is kept for every factorize() of a matrix with that pattern.
#pragma once
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "linalg/sparsity_pattern.hpp"

namespace diffavatar {

class SupernodalLdlt {
 public:
  using Matrix = Eigen::SparseMatrix<double>;  // column-major; the lower triangle is read

  /// Ordering, elimination tree, supernodes and every entry's place in its front (pattern only).
  void analyzePattern(const Matrix& A);
  /// Numeric factorization of A (the pattern analyzePattern saw; std::invalid_argument otherwise).
  void factorize(const Matrix& A);
  Eigen::ComputationInfo info() const { return info_; }
  /// x = A⁻¹ b (units: b's over A's). Throws std::logic_error without a successful factorize()
  /// since the last analyzePattern(), std::invalid_argument when b's size is not A's.
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const;
  Eigen::Index rows() const { return n_; }

 private:
  void relax();
  struct Supernode {
    int first = 0, cols = 0;   // columns [first, first + cols) of the permuted matrix
    std::vector<int> rows;     // rows of L below the supernode (permuted, ascending)
    int parent = -1;           // supernode owning rows[0]'s column (−1: a root)
    std::vector<int> relind;   // rows[i]'s local index in the parent's front
  };
  int n_ = 0;
  std::vector<int> perm_;      // perm_[original] = permuted index
  std::vector<Supernode> sn_;
  std::vector<int> col_sn_;    // supernode of each permuted column
  std::vector<std::vector<int>> children_;  // per supernode, those whose parent it is
  // A's lower-triangle entries (value index in A) and their offset in their supernode's front
  std::vector<int> a_src_;
  std::vector<int> a_sn_begin_;  // per supernode, its slice of a_src_/a_dst_
  std::vector<int> a_dst_;
  std::vector<Eigen::MatrixXd> panel_;  // per supernode, (cols + rows) × cols: unit L11 over L21
  Eigen::VectorXd d_;                   // D, permuted order
  Eigen::ComputationInfo info_ = Eigen::Success;
  bool factorized_ = false;  // a factorize() succeeded since the last analyzePattern()
  SparsityPattern pattern_;  // the analysed pattern
};

}  // namespace diffavatar
