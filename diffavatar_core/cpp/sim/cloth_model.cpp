#include "sim/cloth_model.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

#include "geometry/edge_triangles.hpp"
#include "sim/stretch_kernel.hpp"

namespace diffavatar {

void set_lumped_masses(ClothModel& m, const RefX2d& rest) {
  const int nv = m.num_vertices;
  VecXd mass = VecXd::Zero(nv);
  for (int t = 0; t < m.faces.rows(); ++t) {
    double u[3][2];
    for (int k = 0; k < 3; ++k) { u[k][0] = rest(m.faces(t, k), 0); u[k][1] = rest(m.faces(t, k), 1); }
    const double A = rest_area(u);
    if (!(A > 0)) throw std::invalid_argument("cloth model: rest triangle " + std::to_string(t) +
                                              " is degenerate or clockwise in the pattern plane");
    for (int k = 0; k < 3; ++k) mass[m.faces(t, k)] += m.density * A / 3.0;
  }
  VecXd inv_mass = VecXd::Zero(nv);
  for (int i = 0; i < nv; ++i) {
    if (!(mass[i] > 0)) throw std::invalid_argument("cloth model: vertex " + std::to_string(i) + " is in no triangle");
    inv_mass[i] = 1.0 / mass[i];
  }
  for (int p : m.pinned) inv_mass[p] = 0.0;
  m.mass = std::move(mass);
  m.inv_mass = std::move(inv_mass);
}

std::vector<std::vector<int>> color_constraints(const std::vector<std::vector<int>>& verts, int num_vertices) {
  std::vector<std::vector<int>> used(num_vertices);  // colours used at each vertex
  std::vector<std::vector<int>> colors;
  std::vector<char> taken;
  for (int c = 0; c < static_cast<int>(verts.size()); ++c) {
    taken.assign(colors.size() + 1, 0);
    for (int v : verts[c])
      for (int k : used[v]) taken[k] = 1;
    int k = 0;
    while (taken[k]) ++k;
    if (k == static_cast<int>(colors.size())) colors.emplace_back();
    colors[k].push_back(c);
    for (int v : verts[c]) used[v].push_back(k);
  }
  return colors;
}

ClothModel build_cloth_model(int nv, const RefX3i& F, const RefX2d& rest, const VecXi& tri_group,
                             const RefX2i& seams, const std::vector<int>& pinned, const RefX3i& body_faces,
                             double density, double thickness, double contact_stiffness, double seam_compliance,
                             const VecXd& tri_grain, bool masses_follow_rest, bool smooth_contact,
                             bool valley_contact) {
  if (nv <= 0) throw std::invalid_argument("cloth model: no vertices");
  if (rest.rows() != nv) throw std::invalid_argument("cloth model: rest must have one row per vertex");
  if (tri_group.size() != F.rows()) throw std::invalid_argument("cloth model: tri_group must have one entry per face");
  if (!(density > 0) || !(thickness >= 0) || !(contact_stiffness > 0) || !(seam_compliance > 0))
    throw std::invalid_argument("cloth model: density, contact stiffness, seam compliance must be > 0, thickness >= 0");
  if (tri_grain.size() != 0 && tri_grain.size() != F.rows())
    throw std::invalid_argument("cloth model: tri_grain must have one entry per face (rad) or be empty");
  if (!tri_grain.allFinite()) throw std::invalid_argument("cloth model: tri_grain must be finite (rad)");
  if (smooth_contact && valley_contact)
    throw std::invalid_argument("cloth model: valley contacts hold face planes; not with smooth_contact");
  ClothModel m;
  m.num_vertices = nv;
  m.smooth_contact = smooth_contact;
  m.valley_contact = valley_contact;
  m.tri_grain = tri_grain.size() ? tri_grain : VecXd::Zero(F.rows());
  m.tri_frame.resize(F.rows());
  for (int t = 0; t < F.rows(); ++t) m.tri_frame[t] = grain_rotation(m.tri_grain[t]);
  m.faces = F;
  m.tri_group = tri_group;
  m.num_groups = F.rows() ? tri_group.maxCoeff() + 1 : 1;
  m.seams = seams;
  m.body_faces = body_faces;
  m.thickness = thickness;
  m.contact_stiffness = contact_stiffness;
  m.seam_compliance = seam_compliance;
  m.density = density;
  for (int p : pinned)
    if (p < 0 || p >= nv) throw std::invalid_argument("cloth model: pinned index out of range");
  m.pinned = pinned;
  m.masses_follow_rest = masses_follow_rest;
  set_lumped_masses(m, rest);
  // Hinges: interior edges shared by exactly two consistently oriented triangles.
  const auto edges = edge_triangles(F);  // (min,max) -> (tri, local k)
  std::vector<std::array<int, 4>> hs;
  std::vector<int> hg;
  for (const auto& [key, lst] : edges) {
    if (lst.size() != 2) continue;
    auto [t1, k1] = lst[0];
    auto [t2, k2] = lst[1];
    int a = F(t1, k1), b = F(t1, (k1 + 1) % 3), c = F(t1, (k1 + 2) % 3);
    int d = F(t2, (k2 + 2) % 3);
    if (F(t2, k2) != b) continue;  // inconsistent orientation: no hinge
    hs.push_back({a, b, c, d});
    hg.push_back(tri_group[t1]);
  }
  m.hinges.resize(hs.size(), 4);
  m.hinge_group.resize(hs.size());
  for (size_t h = 0; h < hs.size(); ++h) {
    for (int k = 0; k < 4; ++k) m.hinges(h, k) = hs[h][k];
    m.hinge_group[h] = hg[h];
  }
  m.hinge_rest_angle = VecXd::Zero(hs.size());
  // Colouring.
  std::vector<std::vector<int>> vt(F.rows()), vh(hs.size()), vs(seams.rows());
  for (int t = 0; t < F.rows(); ++t) vt[t] = {F(t, 0), F(t, 1), F(t, 2)};
  for (size_t h = 0; h < hs.size(); ++h) vh[h] = {hs[h][0], hs[h][1], hs[h][2], hs[h][3]};
  for (int s = 0; s < seams.rows(); ++s) {
    if (seams(s, 0) < 0 || seams(s, 0) >= nv || seams(s, 1) < 0 || seams(s, 1) >= nv || seams(s, 0) == seams(s, 1))
      throw std::invalid_argument("cloth model: seam " + std::to_string(s) + " has a bad vertex pair");
    vs[s] = {seams(s, 0), seams(s, 1)};
  }
  m.tri_colors = color_constraints(vt, nv);
  m.hinge_colors = color_constraints(vh, nv);
  m.seam_colors = color_constraints(vs, nv);
  return m;
}

}  // namespace diffavatar
