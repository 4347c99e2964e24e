#include "body/normal_equations.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <stdexcept>

namespace diffavatar {

std::pair<Eigen::MatrixXd, VecXd> normal_equations(const Eigen::Ref<const RowMatXd>& J, const RefXd& w,
                                                   const RefXd& r) {
  if (w.size() != J.rows() || r.size() != J.rows())
    throw std::invalid_argument("normal_equations: J, w and r must have the same number of rows");
  const long P = J.cols();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(P, P);
  VecXd g = VecXd::Zero(P);
  // single-threaded GEMM: P is small (~100) and the core's OpenMP pool is busy elsewhere
  const int threads = Eigen::nbThreads();
  Eigen::setNbThreads(1);
  RowMatXd WJ = w.asDiagonal() * J;
  H.noalias() = J.transpose() * WJ;
  g.noalias() = WJ.transpose() * r;
  Eigen::setNbThreads(threads);
  return {H, g};
}

VecXd damped_step(const Eigen::MatrixXd& H, const VecXd& g, double lambda) {
  Eigen::MatrixXd A = H;
  A.diagonal() += lambda * H.diagonal() + VecXd::Constant(H.rows(), 1e-12);
  return A.ldlt().solve(-g);
}

}  // namespace diffavatar
