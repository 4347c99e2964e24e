// Area-uniform random sampling of a triangle mesh surface (for Chamfer metrics and losses).
#pragma once
#include <cstdint>

#include "common/types.hpp"

namespace diffavatar {

/// n points uniformly distributed over the surface area of (V: #V×3, F: #F×3); deterministic
/// for a given seed. Outputs: the #n×3 points (units of V) and, if non-null, the #n source
/// triangle of each point. Throws std::invalid_argument if the surface has zero area.
RowMatX3d sample_surface(const RefX3d& V, const RefX3i& F, int n, uint64_t seed,
                         VecXi* triangle_of_sample = nullptr);

}  // namespace diffavatar
