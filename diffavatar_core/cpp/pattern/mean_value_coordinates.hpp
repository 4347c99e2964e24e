// Control cage of a pattern panel and mean value coordinates w.r.t. it (paper §4.2.2).
#pragma once
#include <vector>

#include "common/types.hpp"

namespace diffavatar {

/// Control-cage handle selection (paper §4.2.2): a vertex of a panel's boundary loop is a handle
/// if it is a corner of the loop's convex hull or if the loop turns by more than
/// `angle_threshold_deg` there (turning angle = angle between the incoming and outgoing edge).
/// loop: #B×2 boundary points in order (m). Returns the handle positions in the loop (ascending).
VecXi cage_handles(const RefX2d& loop, double angle_threshold_deg);

/// Mean value coordinates (Floater 2003; signed-angle form valid for non-convex polygons,
/// Hormann & Floater 2006) of points w.r.t. a closed polygon cage:
///   w_i(x) = (tan(α_{i−1}/2) + tan(α_i/2)) / ‖v_i − x‖,  λ_i = w_i / Σ_j w_j,
/// α_i the signed angle at x between v_i − x and v_{i+1} − x, tan(α/2) = A/(r r' + D).
/// Points on a cage vertex or edge get the exact (linear) boundary values.
/// They reproduce every affine function: Σ λ_i v_i = x, Σ λ_i = 1.
/// cage: #H×2 vertices in order (m); points: #N×2 (m). Returns #N×#H λ (dimensionless),
/// so that  x̄ = W ζ  with ζ = cage.
RowMatXd mean_value_coordinates(const RefX2d& cage, const RefX2d& points);

}  // namespace diffavatar
