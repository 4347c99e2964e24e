// Total potential energy of the garment (the quasi-static equilibrium's objective and the
// implicit function of the equilibrium adjoint, issue 4):
//   E(x; θ) = Σ_tri U_stretch + Σ_hinge U_bend + Σ_seam U_seam + Σ_contact U_contact − Σ_i m_i g·x_i
//             (+ ½ κ Σ_i m_i |x_i − a_i|², see EnergyContext::anchor)
// with the kernels of stretch_kernel.hpp, bending_kernel.hpp, seam_kernel.hpp, contact_kernel.hpp
// (J; x in m). XPBD minimises the same energies (paper Eq. 1–2: U = ½ Cᵀ α⁻¹ C), so a
// converged XPBD drape and the Newton-refined equilibrium are the same physical state.
// Derivatives are exact (autodiff/jet.hpp): ∇ₓE, ∇ₓ²E (optionally projected per element to
// be positive semi-definite, for Newton steps) and the mixed products μᵀ ∂(∇ₓE)/∂θ for
// θ = rest coordinates, stretch compliances, bending stiffness and body vertices.
#pragma once
#include <Eigen/Sparse>
#include <vector>

#include "common/types.hpp"
#include "sim/body_collider.hpp"
#include "sim/cloth_control.hpp"
#include "sim/cloth_model.hpp"

namespace diffavatar {

struct EnergyContext {
  const ClothModel& model;
  const ClothControl& control;
  const RestCache& cache;
  const std::vector<Contact>& contacts;
  const std::vector<ContactFrame>& frames;  // the contacts' planes on the control's body, same order
  Vec3 gravity;  // m/s²
  // Static-friction proxy of the quasi-static refinement: E += ½ κ Σ m_i |x_i − a_i|² with
  // anchors a (the settled XPBD positions) and κ in 1/s²; κ = 0 or a == nullptr disables it.
  const RowMatX3d* anchor = nullptr;
  double anchor_stiffness = 0.0;
  // project_psd: each hinge's block clamped to its non-negative eigenvalues (the Newton of stops
  // 31–58, kept as bench/newton.py's reference) instead of its Gauss–Newton part.
  bool hinge_clamp = false;
};

double total_energy(const EnergyContext& ctx, const RowMatX3d& x);
/// ∇ₓE (#V×3, N); rows of pinned vertices included (the caller masks them).
RowMatX3d energy_gradient(const EnergyContext& ctx, const RowMatX3d& x);
/// ∇ₓ²E over the free DOFs: dof[i] = first row of vertex i in the reduced system, −1 if pinned.
Eigen::SparseMatrix<double> energy_hessian(const EnergyContext& ctx, const RowMatX3d& x, const std::vector<int>& dof,
                                           bool project_psd);

/// The element Hessians ∇ₓ²E sums (J/m²): stretch per triangle (9×9 over its corners) and bending
/// per hinge (12×12; zero for a degenerate hinge or k_b = 0). When project_psd (Newton far from
/// equilibrium) each is positive semi-definite: a triangle's clamped to its non-negative
/// eigenvalues, a hinge's its Gauss–Newton part k w ∇θ ∇θᵀ (bending_kernel.hpp; clamped too when
/// ctx.hinge_clamp).
struct ElementHessians {
  std::vector<Eigen::Matrix<double, 9, 9>> tri;
  std::vector<Eigen::Matrix<double, 12, 12>> hinge;
};
ElementHessians element_hessians(const EnergyContext& ctx, const RowMatX3d& x, bool project_psd);

/// Every entry (row, col, value) of ∇ₓ²E over the free DOFs, in the one order both assemblies
/// sum duplicates in (energy_hessian's triplets, NewtonSystem's in-place values): the element
/// blocks of triangles, hinges and seams — a pattern fixed by the mesh and `dof` — go to
/// fixed(row, col, value); the state-dependent entries, which lie in single vertices' diagonal
/// 3×3 blocks (penetrating contacts' k_c n̂n̂ᵀ, the anchors' κ m_i), to diag(vertex, i, j, value)
/// for row dof[vertex] + i, column dof[vertex] + j.
template <class Fixed, class Diag>
void scatter_hessian(const EnergyContext& ctx, const RowMatX3d& x, const std::vector<int>& dof,
                     const ElementHessians& eh, Fixed&& fixed, Diag&& diag);

}  // namespace diffavatar

#include "sim/hessian_scatter.hpp"

namespace diffavatar {

/// μᵀ ∂(∇ₓE)/∂θ for every control kind (same shapes as the control).
struct ControlGradient {
  RowMatX2d rest;
  RowMatX3d stretch_compliance;
  VecXd bend_stiffness;
  RowMatX3d body_vertices;
};
ControlGradient mixed_product(const EnergyContext& ctx, const RowMatX3d& x, const RowMatX3d& mu);

}  // namespace diffavatar
