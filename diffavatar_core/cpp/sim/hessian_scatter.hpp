// scatter_hessian (declared in cloth_energy.hpp): the entries of ∇ₓ²E over the free DOFs in their
// one summation order — triangles, hinges, seams (fixed pattern), then penetrating contacts and
// anchors (diagonal vertex blocks). Both assemblies visit this order, so a duplicate (row, col)
// sums its contributions in the same sequence in each and the matrices agree bit for bit.
// Units: J/m² (N/m).
#pragma once
#include "sim/cloth_energy.hpp"
#include "sim/contact_kernel.hpp"

namespace diffavatar {

template <class Fixed, class Diag>
void scatter_hessian(const EnergyContext& c, const RowMatX3d& x, const std::vector<int>& dof,
                     const ElementHessians& eh, Fixed&& fixed, Diag&& diag) {
  const ClothModel& m = c.model;
  auto block = [&](const auto& H, const int* vs, int nvs) {
    for (int a = 0; a < nvs; ++a) {
      const int ra = dof[vs[a]];
      if (ra < 0) continue;
      for (int b = 0; b < nvs; ++b) {
        const int rb = dof[vs[b]];
        if (rb < 0) continue;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) fixed(ra + i, rb + j, H(3 * a + i, 3 * b + j));
      }
    }
  };
  for (int t = 0; t < m.faces.rows(); ++t) block(eh.tri[t], &m.faces(t, 0), 3);
  for (int h = 0; h < m.hinges.rows(); ++h) block(eh.hinge[h], &m.hinges(h, 0), 4);
  Eigen::Matrix<double, 6, 6> Hs;  // ½|x_a − x_b|²/α_seam
  Hs << Eigen::Matrix3d::Identity(), -Eigen::Matrix3d::Identity(), -Eigen::Matrix3d::Identity(),
      Eigen::Matrix3d::Identity();
  Hs /= m.seam_compliance;
  for (int s = 0; s < m.seams.rows(); ++s) block(Hs, &m.seams(s, 0), 2);
  for (std::size_t j = 0; j < c.contacts.size(); ++j) {
    const int v = c.contacts[j].vertex;
    const ContactFrame& f = c.frames[j];
    if (dof[v] < 0 || contact_gap(x.row(v).transpose(), f, m.thickness) >= 0.0) continue;
    const Eigen::Matrix3d H = m.contact_stiffness * f.n * f.n.transpose();  // C linear in p: ∇ₚ²U = k_c n̂ n̂ᵀ
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) diag(v, a, b, H(a, b));
  }
  if (c.anchor && c.anchor_stiffness > 0)
    for (int i = 0; i < m.num_vertices; ++i)
      if (dof[i] >= 0)
        for (int k = 0; k < 3; ++k) diag(i, k, k, c.anchor_stiffness * m.mass[i]);
}

}  // namespace diffavatar
