// Symmetric Chamfer distances (paper §5 "CD"; Table 1 reports it in cm).
#pragma once
#include <cstdint>

#include "common/run_control.hpp"
#include "common/types.hpp"

namespace diffavatar {

/// Distance from each row of A (#A×3) to its nearest row of B (#B×3). Units of the inputs.
VecXd nearest_point_distances(const RefX3d& A, const RefX3d& B, RunControl& rc);

/// Distance from each row of P (#P×3) to the nearest point of the surface (V: #V×3, F: #F×3).
VecXd surface_distances(const RefX3d& P, const RefX3d& V, const RefX3i& F, RunControl& rc);

/// ½ (mean_a min_b |a−b| + mean_b min_a |a−b|) between two point sets; units of the inputs.
double chamfer_points(const RefX3d& A, const RefX3d& B, RunControl& rc);

/// Symmetric Chamfer distance between two surfaces: `samples` area-uniform points on each
/// surface (seeded), each measured to the nearest point of the *other surface* (exact
/// closest point on its triangles, not on its samples), the two means averaged.
/// Identical meshes give 0 exactly; units of the inputs.
double chamfer_meshes(const RefX3d& VA, const RefX3i& FA, const RefX3d& VB, const RefX3i& FB,
                      int samples, uint64_t seed, RunControl& rc);

}  // namespace diffavatar
