// The triangles around each edge of a triangle mesh: what the cloth's hinges (cloth_model.cpp)
// and the body's valley contacts (body_collider.cpp) are built from.
#pragma once
#include <algorithm>
#include <map>
#include <utility>
#include <vector>

#include "common/types.hpp"

namespace diffavatar {

/// Edge (min vertex, max vertex) → its (triangle, local k) incidences, edge k of triangle t
/// being (F(t, k), F(t, k+1)); ordered by edge (deterministic). Two incidences: an interior
/// manifold edge; one: a border; more: non-manifold.
inline std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> edge_triangles(const RefX3i& F) {
  std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> edges;
  for (int t = 0; t < F.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = F(t, k), b = F(t, (k + 1) % 3);
      edges[{std::min(a, b), std::max(a, b)}].push_back({t, k});
    }
  return edges;
}

}  // namespace diffavatar
