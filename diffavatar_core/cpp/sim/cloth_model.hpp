// Model = what does not change while simulating or optimizing: topology (faces, hinges,
// seams), masses, pinned vertices, material groups, body topology, contact/seam constants,
// and the constraint colouring used to run XPBD in parallel. Rest shape, material values
// and body vertex positions are the Control (cloth_control.hpp); x, v, λ the State. With
// masses_follow_rest the lumped masses are a function of the Control's rest shape instead:
// the solver recomputes them at every set_control (a pattern with more area weighs more).
#pragma once
#include <Eigen/Core>
#include <vector>

#include "common/types.hpp"
#include "sim/grain_frame.hpp"

namespace diffavatar {

using RowMatX4i = Eigen::Matrix<int32_t, Eigen::Dynamic, 4, Eigen::RowMajor>;

struct ClothModel {
  int num_vertices = 0;
  RowMatX3i faces;        // #F×3, counter-clockwise in the pattern plane
  VecXi tri_group;        // #F material group of each triangle
  VecXd tri_grain;        // #F warp direction (rad from the pattern x axis, CCW); 0 = pattern x
  std::vector<GrainRotation> tri_frame;  // #F R(−grain) of each triangle (grain_frame.hpp)
  RowMatX4i hinges;       // #H×4 (a, b, c, d): shared edge a→b as in triangle (a, b, c)
  VecXi hinge_group;      // #H material group (that of triangle (a, b, c))
  VecXd hinge_rest_angle; // #H θ0 (rad), 0 = flat
  RowMatX2i seams;        // #S×2 vertex pairs sewn together
  VecXd mass;             // #V kg (areal density × one third of the adjacent rest areas)
  VecXd inv_mass;         // #V 1/kg, 0 for pinned vertices
  double density = 0.15;  // areal density ρ (kg/m²) the masses come from
  std::vector<int> pinned;          // pinned vertex indices (inv_mass 0)
  bool masses_follow_rest = false;  // masses from the control's rest areas (set_lumped_masses)
  int num_groups = 1;
  RowMatX3i body_faces;   // #Fb×3 body triangles (outward normals by the right-hand rule)
  double thickness = 0.004;          // collision thickness h (m)
  double contact_stiffness = 2.0e3;  // k_c (N/m)
  bool smooth_contact = false;       // contact plane: interpolated vertex normal (true) or the face's (contact_kernel.hpp)
  bool valley_contact = false;       // face planes; over a concave body edge both faces' in the quasi-static solves
                                     // (BodyCollider::detect valleys)
  double seam_compliance = 1.0e-5;   // α_seam (m/N)
  // Constraint colouring: each colour lists constraints sharing no vertex.
  std::vector<std::vector<int>> tri_colors, hinge_colors, seam_colors;
};

/// Builds the model: hinges from interior edges, masses from `density` (kg/m²) and the rest
/// areas of `rest` (m), colouring; `tri_grain` (#F rad, or empty = 0 everywhere) the fabric
/// grain of each triangle. Throws std::invalid_argument naming a bad input.
ClothModel build_cloth_model(int num_vertices, const RefX3i& faces, const RefX2d& rest, const VecXi& tri_group,
                             const RefX2i& seams, const std::vector<int>& pinned, const RefX3i& body_faces,
                             double density, double thickness, double contact_stiffness, double seam_compliance,
                             const VecXd& tri_grain = VecXd(), bool masses_follow_rest = false,
                             bool smooth_contact = false, bool valley_contact = false);

/// m.mass[i] = ρ Σ_{t∋i} A_t(rest)/3 (kg) and m.inv_mass (0 for m.pinned) from the rest areas of
/// `rest` (#V×2, m). Throws std::invalid_argument for a degenerate or clockwise rest triangle.
void set_lumped_masses(ClothModel& m, const RefX2d& rest);

/// Greedy colouring of constraints given as vertex lists; deterministic (input order).
std::vector<std::vector<int>> color_constraints(const std::vector<std::vector<int>>& verts, int num_vertices);

}  // namespace diffavatar
