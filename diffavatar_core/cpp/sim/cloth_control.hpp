// Control = the parameters the optimizer changes (paper §4.2): the pattern's rest coordinates
// x̄ (#V×2, m), stretch compliances per material group (#G×3: warp, weft, shear; m/N), bending
// stiffness per group (#G, N·m) and the body's vertex positions (#Vb×3, m). RestCache holds
// what the forward pass derives from it (D̄⁻¹, Ā per triangle, hinge weights, the body's vertex
// normals).
#pragma once
#include <vector>

#include "common/types.hpp"
#include "sim/cloth_model.hpp"
#include "sim/stretch_kernel.hpp"

namespace diffavatar {

struct ClothControl {
  RowMatX2d rest;
  RowMatX3d stretch_compliance;
  VecXd bend_stiffness;
  RowMatX3d body_vertices;
};

struct RestCache {
  std::vector<StretchRest> tri;
  VecXd hinge_weight;
  RowMatX3d body_normals;  // unit vertex normals of body_vertices (geometry/vertex_normals.hpp)
};

/// Validates the control against the model and derives the rest cache. Throws
/// std::invalid_argument naming the problem (inverted rest triangle, non-positive material...).
RestCache prepare_control(const ClothModel& m, const ClothControl& c);

}  // namespace diffavatar
