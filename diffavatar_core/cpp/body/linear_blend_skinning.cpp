#include "body/linear_blend_skinning.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <stdexcept>
#include <string>

namespace diffavatar {

namespace {
Eigen::Matrix3d skew(const Vec3& a) {
  Eigen::Matrix3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}
Eigen::Matrix3d rot_axis(int axis, double angle) {
  return Eigen::AngleAxisd(angle, Vec3::Unit(axis)).toRotationMatrix();
}
}  // namespace

Eigen::Matrix3d axis_angle_matrix(const Vec3& r) {
  const double th = r.norm();
  if (th < 1e-12) return Eigen::Matrix3d::Identity() + skew(r);
  return Eigen::AngleAxisd(th, r / th).toRotationMatrix();
}

void axis_angle_derivatives(const Vec3& r, Eigen::Matrix3d dR[3]) {
  const double th2 = r.squaredNorm();
  if (th2 < 1e-16) {
    for (int a = 0; a < 3; ++a) dR[a] = skew(Vec3::Unit(a));
    return;
  }
  const Eigen::Matrix3d R = axis_angle_matrix(r);
  const Eigen::Matrix3d I_R = Eigen::Matrix3d::Identity() - R;
  for (int a = 0; a < 3; ++a)
    dR[a] = (r(a) * skew(r) + skew(r.cross(I_R.col(a)))) / th2 * R;
}

LinearBlendSkinning::LinearBlendSkinning(const RowMatX3d& V0, const RowMatXd& S, const RowMatX3d& J0,
                                         const RowMatXd& SJ, const VecXi& parents, const RowMatXd& W,
                                         const RowMatX3d& lo, const RowMatX3d& hi)
    : V0_(V0), J0_(J0), S_(S), SJ_(SJ), lo_(lo), hi_(hi) {
  const long nv = V0.rows(), nj = J0.rows();
  if (S.rows() != 3 * nv) throw std::invalid_argument("shapedirs: expected 3#V rows");
  if (SJ.rows() != 3 * nj || SJ.cols() != S.cols()) throw std::invalid_argument("joint shapedirs: expected 3#J×K");
  if (parents.size() != nj || W.rows() != nv || W.cols() != nj || lo.rows() != nj || hi.rows() != nj)
    throw std::invalid_argument("parents/weights/limits: sizes disagree with #V, #J");
  parent_.resize(nj);
  for (long j = 0; j < nj; ++j) {
    parent_[j] = parents(j);
    if ((j == 0) != (parents(j) < 0) || parents(j) >= j)
      throw std::invalid_argument("parents: joint 0 must be the only root and parents[j] < j");
  }
  w_start_.assign(1, 0);
  for (long v = 0; v < nv; ++v) {
    for (long j = 0; j < nj; ++j)
      if (W(v, j) != 0.0) {
        w_joint_.push_back(static_cast<int>(j));
        w_val_.push_back(W(v, j));
      }
    w_start_.push_back(static_cast<int>(w_joint_.size()));
  }
}

void LinearBlendSkinning::check(const BodyPose& p) const {
  if (p.shape.size() != num_shape()) throw std::invalid_argument("shape: expected K = " + std::to_string(num_shape()));
  if (p.angles.rows() != num_joints()) throw std::invalid_argument("pose: expected #J×3 angles");
  if (p.bone_scales.size() != num_joints()) throw std::invalid_argument("bone_scales: expected #J values");
}

RowMatX3d LinearBlendSkinning::clamp_angles(const RowMatX3d& angles) const {
  return angles.cwiseMax(lo_).cwiseMin(hi_);
}

RowMatX3d LinearBlendSkinning::shaped_vertices(const VecXd& shape) const {
  VecXd flat = S_ * shape;
  RowMatX3d out = V0_;
  for (long v = 0; v < out.rows(); ++v) out.row(v) += flat.segment<3>(3 * v).transpose();
  return out;
}

LinearBlendSkinning::Frames LinearBlendSkinning::frames(const BodyPose& p) const {
  check(p);
  const int nj = num_joints();
  Frames f;
  f.psi = clamp_angles(p.angles);
  f.J = J0_;
  VecXd dj = SJ_ * p.shape;
  for (int j = 0; j < nj; ++j) f.J.row(j) += dj.segment<3>(3 * j).transpose();
  f.G.resize(nj);
  f.g.resize(nj);
  f.omega.resize(nj);
  for (int j = 0; j < nj; ++j) {
    const Eigen::Matrix3d Rz = rot_axis(2, f.psi(j, 2)), Ry = rot_axis(1, f.psi(j, 1)), Rx = rot_axis(0, f.psi(j, 0));
    const int q = parent_[j];
    const Eigen::Matrix3d Gp = q < 0 ? Eigen::Matrix3d::Identity() : f.G[q];
    f.G[j] = Gp * Rz * Ry * Rx;
    f.g[j] = q < 0 ? Vec3(f.J.row(j).transpose())
                   : Vec3(f.g[q] + p.bone_scales(j) * Gp * (f.J.row(j) - f.J.row(q)).transpose());
    f.omega[j].col(2) = Gp.col(2);
    f.omega[j].col(1) = Gp * Rz.col(1);
    f.omega[j].col(0) = Gp * Rz * Ry.col(0);
  }
  return f;
}

RowMatX3d LinearBlendSkinning::pose(const BodyPose& p) const {
  const Frames f = frames(p);
  const Eigen::Matrix3d R = axis_angle_matrix(p.rotation);
  const RowMatX3d v = shaped_vertices(p.shape);
  RowMatX3d out(v.rows(), 3);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < v.rows(); ++i) {
    Vec3 y = Vec3::Zero();
    for (int k = w_start_[i]; k < w_start_[i + 1]; ++k) {
      const int j = w_joint_[k];
      y += w_val_[k] * (f.G[j] * (v.row(i) - f.J.row(j)).transpose() + f.g[j]);
    }
    out.row(i) = (R * y + p.translation).transpose();
  }
  return out;
}

RowMatX3d LinearBlendSkinning::joints(const BodyPose& p) const {
  const Frames f = frames(p);
  const Eigen::Matrix3d R = axis_angle_matrix(p.rotation);
  RowMatX3d out(num_joints(), 3);
  for (int j = 0; j < num_joints(); ++j) out.row(j) = (R * f.g[j] + p.translation).transpose();
  return out;
}

RowMatXd LinearBlendSkinning::jacobian(const BodyPose& p, const VecXi& vertices) const {
  const Frames f = frames(p);
  const int nj = num_joints(), K = num_shape(), P = num_params();
  const int c_psi = K, c_s = K + 3 * nj, c_r = K + 4 * nj, c_t = c_r + 3;
  const Eigen::Matrix3d R = axis_angle_matrix(p.rotation);
  Eigen::Matrix3d dR[3];
  axis_angle_derivatives(p.rotation, dR);

  // ∂g_j/∂ν (3×K per joint) and E_j = ∂g_j/∂ν − G_j SJ_j
  std::vector<Eigen::MatrixXd> Dg(nj), E(nj);
  for (int j = 0; j < nj; ++j) {
    const int q = parent_[j];
    if (q < 0) {
      Dg[j] = SJ_.middleRows(3 * j, 3);
    } else {
      Dg[j] = Dg[q] + p.bone_scales(j) * f.G[q] * (SJ_.middleRows(3 * j, 3) - SJ_.middleRows(3 * q, 3));
    }
    E[j] = Dg[j] - f.G[j] * SJ_.middleRows(3 * j, 3);
  }
  // bone direction d_i = G_p (J_i − J_p) and whether each angle is inside its limits
  std::vector<Vec3> dbone(nj, Vec3::Zero());
  for (int j = 1; j < nj; ++j) dbone[j] = f.G[parent_[j]] * (f.J.row(j) - f.J.row(parent_[j])).transpose();
  Eigen::Matrix<double, Eigen::Dynamic, 3> active(nj, 3);
  for (int j = 0; j < nj; ++j)
    for (int a = 0; a < 3; ++a)
      active(j, a) = (lo_(j, a) < hi_(j, a) && p.angles(j, a) >= lo_(j, a) && p.angles(j, a) <= hi_(j, a)) ? 1.0 : 0.0;

  const long n = vertices.size() == 0 ? num_vertices() : vertices.size();
  RowMatXd Jac = RowMatXd::Zero(3 * n, P);
#pragma omp parallel
  {
    std::vector<double> wsum(nj);
    std::vector<Vec3> ysum(nj);
#pragma omp for schedule(static)
    for (long i = 0; i < n; ++i) {
      const long v = vertices.size() == 0 ? i : vertices(i);
      if (v < 0 || v >= num_vertices()) continue;  // validated in Python
      const Vec3 rest = V0_.row(v).transpose() + S_.middleRows(3 * v, 3) * p.shape;
      std::fill(wsum.begin(), wsum.end(), 0.0);
      std::fill(ysum.begin(), ysum.end(), Vec3::Zero());
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::MatrixXd dnu = Eigen::MatrixXd::Zero(3, K);
      Vec3 y = Vec3::Zero();
      for (int k = w_start_[v]; k < w_start_[v + 1]; ++k) {
        const int j = w_joint_[k];
        const double w = w_val_[k];
        const Vec3 yj = f.G[j] * (rest - f.J.row(j).transpose()) + f.g[j];
        y += w * yj;
        A += w * f.G[j];
        dnu += w * E[j];
        for (int a = j; a >= 0; a = parent_[a]) {  // every ancestor's subtree holds j
          wsum[a] += w;
          ysum[a] += w * yj;
        }
      }
      dnu += A * S_.middleRows(3 * v, 3);
      auto rows = Jac.middleRows(3 * i, 3);
      rows.leftCols(K) = R * dnu;
      for (int a = 0; a < nj; ++a) {
        if (wsum[a] == 0.0) continue;
        const Vec3 lever = ysum[a] - wsum[a] * f.g[a];
        for (int c = 0; c < 3; ++c)
          if (active(a, c) != 0.0) rows.col(c_psi + 3 * a + c) = R * f.omega[a].col(c).cross(lever);
        if (a > 0) rows.col(c_s + a) = R * (wsum[a] * dbone[a]);
      }
      for (int c = 0; c < 3; ++c) rows.col(c_r + c) = dR[c] * y;
      rows.middleCols(c_t, 3).setIdentity();
    }
  }
  return Jac;
}

}  // namespace diffavatar
