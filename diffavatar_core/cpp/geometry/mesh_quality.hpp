// Triangle conditioning quality (Shewchuk 2002), the mesh-quality measure of the paper's Table 1.
#pragma once
#include "common/types.hpp"

namespace diffavatar {

/// q = 3A / (l1² + l2² + l3²) for each triangle: √3/4 ≈ 0.433 for an equilateral triangle,
/// 0 for a degenerate one; scale invariant.
/// V: #V×3 positions (any length unit; a 2D pattern is passed with z = 0), F: #F×3 indices.
/// Returns #F qualities (dimensionless).
VecXd triangle_quality(const RefX3d& V, const RefX3i& F);

}  // namespace diffavatar
