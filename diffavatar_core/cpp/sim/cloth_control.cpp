#include "sim/cloth_control.hpp"

#include <stdexcept>
#include <string>

#include "geometry/vertex_normals.hpp"
#include "sim/bending_kernel.hpp"
#include "sim/grain_frame.hpp"

namespace diffavatar {

RestCache prepare_control(const ClothModel& m, const ClothControl& c) {
  if (c.rest.rows() != m.num_vertices) throw std::invalid_argument("control: rest must be #V×2");
  if (c.stretch_compliance.rows() != m.num_groups || c.bend_stiffness.size() != m.num_groups)
    throw std::invalid_argument("control: one material row per group (" + std::to_string(m.num_groups) + ")");
  if (!(c.stretch_compliance.array() > 0).all() || !c.stretch_compliance.allFinite())
    throw std::invalid_argument("control: stretch compliances must be finite and > 0 (m/N)");
  if (!(c.bend_stiffness.array() >= 0).all() || !c.bend_stiffness.allFinite())
    throw std::invalid_argument("control: bending stiffness must be finite and >= 0 (N·m)");
  if (!c.rest.allFinite()) throw std::invalid_argument("control: rest coordinates must be finite");
  int nb = m.body_faces.rows() ? m.body_faces.maxCoeff() + 1 : 0;
  if (c.body_vertices.rows() < nb) throw std::invalid_argument("control: body_vertices has fewer rows than body_faces index");
  if (!c.body_vertices.allFinite()) throw std::invalid_argument("control: body vertices must be finite");
  RestCache rc;
  rc.tri.resize(m.faces.rows());
  for (int t = 0; t < m.faces.rows(); ++t) {
    // D̄ in the fabric's grain frame (grain_frame.hpp): strain components are warp/weft/shear.
    double u[3][2], ug[3][2];
    for (int k = 0; k < 3; ++k) { u[k][0] = c.rest(m.faces(t, k), 0); u[k][1] = c.rest(m.faces(t, k), 1); }
    to_grain_frame(m.tri_frame[t], u, ug);
    rc.tri[t] = stretch_rest(Vec2(ug[0][0], ug[0][1]), Vec2(ug[1][0], ug[1][1]), Vec2(ug[2][0], ug[2][1]));
    if (!(rc.tri[t].area > 0))
      throw std::invalid_argument("control: rest triangle " + std::to_string(t) + " is inverted or degenerate");
  }
  rc.hinge_weight.resize(m.hinges.rows());
  for (int h = 0; h < m.hinges.rows(); ++h) {
    double u[4][2];
    for (int k = 0; k < 4; ++k) { u[k][0] = c.rest(m.hinges(h, k), 0); u[k][1] = c.rest(m.hinges(h, k), 1); }
    rc.hinge_weight[h] = hinge_weight(u[0], u[1], u[2], u[3]);
  }
  rc.body_normals = vertex_normals(c.body_vertices, m.body_faces);
  return rc;
}

}  // namespace diffavatar
