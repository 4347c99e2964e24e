// Linear blend skinning of a parametric body (paper §3.1: shape coefficients ν over a mean
// shape, a skeleton with joint angles ψ and bone lengths, linear blend skinning) with analytic
// Jacobians of the posed vertices w.r.t. all parameters.
//
// Model (constant in a run; SI units, metres):
//   V0: #V×3 mean rest vertices, S: (3#V)×K shape basis (row 3v+c), J0: #J×3 rest joint
//   centres, SJ: (3#J)×K joint shape basis, parents: #J (parents[0] = -1, parents[j] < j),
//   skinning weights (#V×#J, rows summing to 1, stored sparse), limits lo/hi: #J×3 (rad).
// Parameters (the Control):
//   ν: K shape coefficients (unit-variance prior N(0, I)); ψ: #J×3 Euler angles (rad) per
//   joint, R_j = R_z(ψ_j,z) R_y(ψ_j,y) R_x(ψ_j,x) about the world axes of the rest pose;
//   s: #J bone-length scales (the offset from the parent's joint centre to joint j is scaled
//   by s_j; s_0 has no effect); r: global axis-angle rotation (rad), t: translation (m).
// Forward (x_v posed vertex, m):
//   v(ν) = V0 + S ν,  J(ν) = J0 + SJ ν
//   G_0 = R_0, g_0 = J_0;  G_j = G_p R_j,  g_j = g_p + s_j G_p (J_j − J_p)   (p = parent)
//   y_v = Σ_j w_vj (G_j (v_v − J_j) + g_j),   x_v = exp([r]×) y_v + t
// Joint limits: ψ is clamped to [lo, hi] component-wise before posing (never violated); the
// Jacobian is that of the clamped map (columns of clamped components, and of angles fixed by
// lo = hi, are zero; at a bound the one-sided derivative from inside is returned).
// Jacobian column order (P = K + 3#J + #J + 6):
//   [ν_0..ν_{K-1}, ψ_{0,x} ψ_{0,y} ψ_{0,z} ... , s_0..s_{#J-1}, r_x r_y r_z, t_x t_y t_z].
// Derivatives (paper §3.1 posing, derived here): with ω_{i,a} the world angular velocity of
// joint i per unit ψ_{i,a} (ω_z = G_p e_z, ω_y = G_p R_z e_y, ω_x = G_p R_z R_y e_x),
//   ∂y_v/∂ψ_{i,a} = ω_{i,a} × (Σ_{j∈sub(i)} w_vj y_vj − (Σ_{j∈sub(i)} w_vj) g_i)
//   ∂y_v/∂s_i     = (Σ_{j∈sub(i)} w_vj) G_p (J_i − J_p)
//   ∂y_v/∂ν_k     = Σ_j w_vj (G_j (S_vk − SJ_jk) + ∂g_j/∂ν_k)
// and x = R y + t chains them through R = exp([r]×).
#pragma once
#include <vector>

#include "common/types.hpp"

namespace diffavatar {

struct BodyPose {
  VecXd shape;        ///< K shape coefficients ν (unit variance)
  RowMatX3d angles;   ///< #J×3 Euler angles ψ (rad), clamped to the limits when posing
  VecXd bone_scales;  ///< #J bone-length scales (1 = rest length)
  Vec3 rotation = Vec3::Zero();     ///< global axis-angle (rad)
  Vec3 translation = Vec3::Zero();  ///< global translation (m)
};

class LinearBlendSkinning {
 public:
  /// Shapes as in the file header; W is dense #V×#J (zeros dropped). Throws
  /// std::invalid_argument on inconsistent sizes or a parent order that is not topological.
  LinearBlendSkinning(const RowMatX3d& V0, const RowMatXd& S, const RowMatX3d& J0, const RowMatXd& SJ,
                      const VecXi& parents, const RowMatXd& W, const RowMatX3d& lo, const RowMatX3d& hi);

  int num_vertices() const { return static_cast<int>(V0_.rows()); }
  int num_joints() const { return static_cast<int>(J0_.rows()); }
  int num_shape() const { return static_cast<int>(S_.cols()); }
  int num_params() const { return num_shape() + 4 * num_joints() + 6; }

  /// ψ clamped to the joint limits (#J×3, rad).
  RowMatX3d clamp_angles(const RowMatX3d& angles) const;
  /// Posed vertices x (#V×3, m).
  RowMatX3d pose(const BodyPose& p) const;
  /// Posed joint centres R g_j + t (#J×3, m).
  RowMatX3d joints(const BodyPose& p) const;
  /// Rest (unposed, unscaled) vertices V0 + S ν (#V×3, m).
  RowMatX3d shaped_vertices(const VecXd& shape) const;
  /// Jacobian ∂x_v/∂θ for the listed vertices (all when `vertices` is empty):
  /// (3n)×P row-major, row 3i+c is coordinate c of vertices[i], columns as in the header.
  RowMatXd jacobian(const BodyPose& p, const VecXi& vertices) const;

 private:
  struct Frames {
    std::vector<Eigen::Matrix3d> G;         // world rotation of each joint
    std::vector<Vec3> g;                    // world position of each joint (before global)
    std::vector<Eigen::Matrix3d> omega;     // columns ω_{j,x}, ω_{j,y}, ω_{j,z}
    RowMatX3d J;                            // rest joints J(ν)
    RowMatX3d psi;                          // clamped angles
  };
  void check(const BodyPose& p) const;
  Frames frames(const BodyPose& p) const;

  RowMatX3d V0_, J0_;
  RowMatXd S_, SJ_;
  std::vector<int> parent_;
  std::vector<int> w_start_, w_joint_;
  std::vector<double> w_val_;
  RowMatX3d lo_, hi_;
};

/// Rotation matrix exp([r]×) of an axis-angle vector r (rad).
Eigen::Matrix3d axis_angle_matrix(const Vec3& r);
/// ∂exp([r]×)/∂r_a for a = 0,1,2 (Gallego & Yezzi 2015, eq. 9; [e_a]× at r = 0).
void axis_angle_derivatives(const Vec3& r, Eigen::Matrix3d dR[3]);

}  // namespace diffavatar
