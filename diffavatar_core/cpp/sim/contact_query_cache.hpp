// Per-vertex memory of a cloth's last closest-point queries against one body pose, for
// BodyCollider::detect. Units: m.
//
// A vertex whose last query proved the body at least `lower` away from `at` is farther than r
// from it while |x − at| < lower − r (triangle inequality): it is skipped. A vertex queried again
// starts the tree search bounded by its last closest triangle's distance, and searches `reach`
// (2r) rather than r so that the bound it leaves stays useful. Neither prunes a triangle that can
// win (TriangleMeshBvh::closest_below), so the contacts are an uncached detection's bit for bit
// (test/sim/test_contact_query_cache.py). Valid for one body pose: clear() when the body moves.
#pragma once
#include <cstdint>
#include <vector>

#include "common/types.hpp"

namespace diffavatar {

struct ContactQueryCache {
  std::vector<Vec3> at;       // where each vertex was last queried
  std::vector<double> lower;  // a lower bound on its distance to the body there (0: nothing known)
  std::vector<int> tri;       // the closest triangle found then (−1: none within that query's reach)
  std::int64_t queries = 0;   // tree searches made and vertices skipped, over the cache's life
  std::int64_t skipped = 0;

  void clear() {
    at.clear();
    lower.clear();
    tri.clear();
  }
  /// Sized for n vertices, emptied if it was not.
  void fit(int n) {
    if (static_cast<int>(lower.size()) == n) return;
    at.assign(n, Vec3::Zero());
    lower.assign(n, 0.0);
    tri.assign(n, -1);
  }
};

}  // namespace diffavatar
