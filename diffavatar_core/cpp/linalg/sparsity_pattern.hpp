// The pattern of a compressed column-major sparse matrix (its outer and inner index arrays), kept
// to tell whether a later matrix has the same one: what decides whether an LDLᵀ's symbolic
// analysis (ordering, elimination tree, supernodes) can be reused for its values.
#pragma once
#include <Eigen/SparseCore>
#include <algorithm>
#include <vector>

namespace diffavatar {

struct SparsityPattern {
  std::vector<int> outer, inner;

  void assign(const Eigen::SparseMatrix<double>& A) {
    outer.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1);
    inner.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
  }
  void clear() {
    outer.clear();
    inner.clear();
  }
  /// Whether A is compressed and has exactly this pattern (index arrays compared, not only sizes).
  bool matches(const Eigen::SparseMatrix<double>& A) const {
    return !outer.empty() && A.isCompressed() && static_cast<std::size_t>(A.outerSize() + 1) == outer.size() &&
           static_cast<std::size_t>(A.nonZeros()) == inner.size() &&
           std::equal(outer.begin(), outer.end(), A.outerIndexPtr()) &&
           std::equal(inner.begin(), inner.end(), A.innerIndexPtr());
  }
  /// The columns of the pattern (0 when none is kept).
  Eigen::Index cols() const { return outer.empty() ? 0 : static_cast<Eigen::Index>(outer.size()) - 1; }
};

}  // namespace diffavatar
