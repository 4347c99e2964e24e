#include "linalg/supernodal_ldlt.hpp"

#include <Eigen/OrderingMethods>
#include <algorithm>
#include <stdexcept>
#include <string>

namespace diffavatar {

void SupernodalLdlt::relax() {
  // Relaxed amalgamation (as CHOLMOD's defaults): a supernode whose columns end where its
  // parent's begin is merged into it when the explicit zeros this adds stay few, so the dense
  // kernels work on larger blocks.
  std::vector<Supernode> out;
  std::vector<double> zeros;  // explicit zeros each merged supernode holds
  for (std::size_t s = 0; s < sn_.size(); ++s) {
    Supernode cur = sn_[s];
    double z = 0.0;
    // Merge the preceding supernode into cur while it is cur's child (its first row below is one
    // of cur's columns) and the merged one is small or has few zeros (the child's columns gain
    // every row of cur's front they lacked).
    while (!out.empty()) {
      Supernode& c = out.back();
      if (c.first + c.cols != cur.first || c.rows.empty() || c.rows[0] >= cur.first + cur.cols) break;
      const int cols = c.cols + cur.cols, rows = static_cast<int>(cur.rows.size());
      const double added = static_cast<double>(c.cols) * (cur.cols + rows - static_cast<double>(c.rows.size()));
      const double zt = zeros.back() + z + added;
      const double total = 0.5 * cols * (cols + 1.0) + static_cast<double>(cols) * rows;
      const double zf = zt / total;
      const bool ok = cols <= 4 || (cols <= 16 && zf < 0.8) || (cols <= 48 && zf < 0.1) || zf < 0.05;
      if (!ok) break;
      cur.first = c.first;
      cur.cols = cols;
      z = zt;
      out.pop_back();
      zeros.pop_back();
    }
    out.push_back(std::move(cur));
    zeros.push_back(z);
  }
  sn_ = std::move(out);
  for (std::size_t s = 0; s < sn_.size(); ++s)
    for (int j = sn_[s].first; j < sn_[s].first + sn_[s].cols; ++j) col_sn_[j] = static_cast<int>(s);
}

void SupernodalLdlt::analyzePattern(const Matrix& A) {
  if (A.rows() != A.cols()) throw std::invalid_argument("SupernodalLdlt: matrix must be square");
  if (!A.isCompressed()) throw std::invalid_argument("SupernodalLdlt: matrix must be compressed");
  n_ = static_cast<int>(A.rows());
  // AMD on the symmetric pattern, as Eigen::SimplicialLDLT orders it.
  {
    Matrix C = A.selfadjointView<Eigen::Lower>();
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> pinv;
    Eigen::AMDOrdering<int>()(C, pinv);
    const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> P = pinv.inverse();
    perm_.assign(P.indices().data(), P.indices().data() + n_);
  }
  // The permuted lower triangle: per column j the rows i > j (the diagonal is implied).
  std::vector<std::vector<int>> lower(n_), upper(n_);
  for (int c = 0; c < A.outerSize(); ++c)
    for (Matrix::InnerIterator it(A, c); it; ++it) {
      if (it.row() < c) continue;
      const int i = std::max(perm_[it.row()], perm_[c]), j = std::min(perm_[it.row()], perm_[c]);
      if (i == j) continue;
      lower[j].push_back(i);
      upper[i].push_back(j);
    }
  // Elimination tree (Liu, with path compression).
  std::vector<int> parent(n_, -1), ancestor(n_, -1);
  for (int k = 0; k < n_; ++k)
    for (int i : upper[k])
      while (i != -1 && i < k) {
        const int next = ancestor[i];
        ancestor[i] = k;
        if (next == -1) parent[i] = k;
        i = next;
      }
  upper.clear();
  upper.shrink_to_fit();
  // Column structures of L below the diagonal: A's rows ∪ the children's structures (minus j).
  std::vector<std::vector<int>> children(n_);
  for (int j = 0; j < n_; ++j)
    if (parent[j] >= 0) children[parent[j]].push_back(j);
  std::vector<std::vector<int>> lstruct(n_);
  std::vector<int> mark(n_, -1);
  for (int j = 0; j < n_; ++j) {
    std::vector<int>& s = lstruct[j];
    mark[j] = j;
    for (int i : lower[j])
      if (mark[i] != j) mark[i] = j, s.push_back(i);
    for (int c : children[j])
      for (int i : lstruct[c])
        if (mark[i] != j) mark[i] = j, s.push_back(i);
    std::sort(s.begin(), s.end());
  }
  // Fundamental supernodes: j joins j−1's when j is j−1's parent and L_j's structure is L_{j−1}'s
  // without j.
  sn_.clear();
  col_sn_.assign(n_, -1);
  for (int j = 0; j < n_; ++j) {
    const bool join = j > 0 && parent[j - 1] == j && lstruct[j - 1].size() == lstruct[j].size() + 1;
    if (!join) {
      sn_.emplace_back();
      sn_.back().first = j;
    }
    ++sn_.back().cols;
    col_sn_[j] = static_cast<int>(sn_.size()) - 1;
  }
  for (Supernode& s : sn_) s.rows = lstruct[s.first + s.cols - 1];
  lstruct.clear();
  lstruct.shrink_to_fit();
  relax();
  auto local = [&](const Supernode& s, int i) {  // i's index in s's front
    if (i < s.first + s.cols) return i - s.first;
    return s.cols + static_cast<int>(std::lower_bound(s.rows.begin(), s.rows.end(), i) - s.rows.begin());
  };
  for (Supernode& s : sn_) {
    s.parent = s.rows.empty() ? -1 : col_sn_[s.rows[0]];
    s.relind.clear();
    if (s.parent >= 0)
      for (int i : s.rows) s.relind.push_back(local(sn_[s.parent], i));
  }
  children_.assign(sn_.size(), {});
  for (std::size_t s = 0; s < sn_.size(); ++s)
    if (sn_[s].parent >= 0) children_[sn_[s].parent].push_back(static_cast<int>(s));
  // Every lower-triangle entry of A: its value index and its place in its supernode's front.
  const int ns = static_cast<int>(sn_.size());
  std::vector<std::vector<std::pair<int, int>>> per(ns);
  for (int c = 0; c < A.outerSize(); ++c)
    for (Matrix::InnerIterator it(A, c); it; ++it) {
      if (it.row() < c) continue;
      const int i = std::max(perm_[it.row()], perm_[c]), j = std::min(perm_[it.row()], perm_[c]);
      const int k = static_cast<int>(&it.value() - A.valuePtr());
      const Supernode& s = sn_[col_sn_[j]];
      const int m = s.cols + static_cast<int>(s.rows.size());
      per[col_sn_[j]].emplace_back(k, (j - s.first) * m + local(s, i));
    }
  a_sn_begin_.assign(ns + 1, 0);
  a_src_.clear();
  a_dst_.clear();
  for (int s = 0; s < ns; ++s) {
    for (auto [k, d] : per[s]) a_src_.push_back(k), a_dst_.push_back(d);
    a_sn_begin_[s + 1] = static_cast<int>(a_src_.size());
  }
  panel_.resize(ns);
  for (int s = 0; s < ns; ++s) panel_[s].resize(sn_[s].cols + static_cast<int>(sn_[s].rows.size()), sn_[s].cols);
  d_.resize(n_);
  info_ = Eigen::Success;
  factorized_ = false;
  pattern_.assign(A);
}

void SupernodalLdlt::factorize(const Matrix& A) {
  if (A.rows() != n_ || !pattern_.matches(A)) throw std::invalid_argument("SupernodalLdlt::factorize: not the pattern analyzePattern saw");
  const int ns = static_cast<int>(sn_.size());
  const double* val = A.valuePtr();
  std::vector<Eigen::MatrixXd> update(ns);  // each supernode's Schur complement, for its parent
  Eigen::MatrixXd F;  // the current supernode's front (lower triangle)
  info_ = Eigen::Success;
  factorized_ = false;
  for (int s = 0; s < ns; ++s) {
    const Supernode& sn = sn_[s];
    const int k = sn.cols, r = static_cast<int>(sn.rows.size()), m = k + r;
    F.setZero(m, m);
    double* f = F.data();
    for (int e = a_sn_begin_[s]; e < a_sn_begin_[s + 1]; ++e) f[a_dst_[e]] += val[a_src_[e]];
    for (int c : children_[s]) {  // extend-add of the children's Schur complements (lower triangles)
      const std::vector<int>& ri = sn_[c].relind;
      const int rc = static_cast<int>(ri.size());
      for (int jj = 0; jj < rc; ++jj) {
        double* fc = f + static_cast<Eigen::Index>(ri[jj]) * m;
        const double* uc = update[c].data() + static_cast<Eigen::Index>(jj) * rc;
        for (int ii = jj; ii < rc; ++ii) fc[ri[ii]] += uc[ii];
      }
      update[c].resize(0, 0);
    }
    // Dense partial LDLᵀ: the diagonal block F11 = L11 D L11ᵀ column by column, then
    // L21 = F21 L11⁻ᵀ D⁻¹ (a triangular solve) and the Schur complement F22 − L21 D L21ᵀ.
    for (int j = 0; j < k; ++j) {
      const double d = F(j, j);
      if (d == 0.0) {
        info_ = Eigen::NumericalIssue;
        return;
      }
      d_[sn.first + j] = d;
      F.col(j).segment(j + 1, k - j - 1) /= d;
      for (int q = j + 1; q < k; ++q) F.col(q).segment(q, k - q) -= (d * F(q, j)) * F.col(j).segment(q, k - q);
    }
    if (r > 0) {
      auto F21 = F.bottomLeftCorner(r, k);
      F.topLeftCorner(k, k).transpose().triangularView<Eigen::UnitUpper>().solveInPlace<Eigen::OnTheRight>(F21);
      Eigen::MatrixXd W = F21;  // L21 D
      F21 = W * d_.segment(sn.first, k).cwiseInverse().asDiagonal();
      Eigen::MatrixXd U = F.bottomRightCorner(r, r);
      U.triangularView<Eigen::Lower>() -= F21 * W.transpose();
      update[s] = std::move(U);
    }
    panel_[s] = F.leftCols(k);
  }
  factorized_ = true;
}

Eigen::VectorXd SupernodalLdlt::solve(const Eigen::VectorXd& b) const {
  if (!factorized_) throw std::logic_error("SupernodalLdlt::solve: no successful factorize() of the analysed pattern");
  if (b.size() != n_) throw std::invalid_argument("SupernodalLdlt::solve: b has " + std::to_string(b.size()) +
                                                  " entries, the matrix " + std::to_string(n_) + " rows");
  Eigen::VectorXd y(n_);
  for (int i = 0; i < n_; ++i) y[perm_[i]] = b[i];
  const int ns = static_cast<int>(sn_.size());
  Eigen::VectorXd t;
  for (int s = 0; s < ns; ++s) {  // L y = P b
    const Supernode& sn = sn_[s];
    const int k = sn.cols, r = static_cast<int>(sn.rows.size());
    auto ys = y.segment(sn.first, k);
    panel_[s].topRows(k).triangularView<Eigen::UnitLower>().solveInPlace(ys);
    if (r > 0) {
      t.noalias() = panel_[s].bottomRows(r) * ys;
      for (int i = 0; i < r; ++i) y[sn.rows[i]] -= t[i];
    }
  }
  y.array() /= d_.array();
  for (int s = ns - 1; s >= 0; --s) {  // Lᵀ x' = D⁻¹ y
    const Supernode& sn = sn_[s];
    const int k = sn.cols, r = static_cast<int>(sn.rows.size());
    auto ys = y.segment(sn.first, k);
    if (r > 0) {
      t.resize(r);
      for (int i = 0; i < r; ++i) t[i] = y[sn.rows[i]];
      ys.noalias() -= panel_[s].bottomRows(r).transpose() * t;
    }
    panel_[s].topRows(k).transpose().triangularView<Eigen::UnitUpper>().solveInPlace(ys);
  }
  Eigen::VectorXd x(n_);
  for (int i = 0; i < n_; ++i) x[i] = y[perm_[i]];
  return x;
}

}  // namespace diffavatar
