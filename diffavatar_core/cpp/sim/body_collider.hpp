// Cloth–body contact detection against a triangle-mesh body (tens of thousands of triangles)
// through the core's BVH (geometry/triangle_mesh_bvh.hpp). The body may move between steps:
// set_vertices refits the tree in O(#Fb).
#pragma once
#include <cmath>
#include <memory>
#include <vector>

#include "common/types.hpp"
#include "geometry/triangle_mesh_bvh.hpp"
#include "sim/contact_kernel.hpp"
#include "sim/contact_query_cache.hpp"

namespace diffavatar {

/// A cloth vertex in contact with the body at the point of triangle `tri` with barycentrics w:
/// the closest point of its position `at` (m) at detection, in the triangle's Voronoi region
/// `region` (closest_point_triangle.hpp: 0 face, 1–3 edges, 4–6 corners; contact_kernel.hpp).
struct Contact {
  int vertex;
  int tri;
  double w[3];
  int region;
  Vec3 at;
};

/// The contact's barycentrics on the body V (m), F: its detection point's closest point in its
/// region (contact_kernel.hpp region_barycentrics) — what they were at detection, and how they
/// follow the body when it moves under a held contact. A degenerate triangle (no finite
/// barycentrics) keeps the previous ones.
inline void update_barycentrics(Contact& c, const RowMatX3d& V, const RowMatX3i& F) {
  V3<double> b[3], at{c.at.x(), c.at.y(), c.at.z()};
  for (int k = 0; k < 3; ++k) b[k] = {V(F(c.tri, k), 0), V(F(c.tri, k), 1), V(F(c.tri, k), 2)};
  double w[3];
  region_barycentrics(at, b, c.region, w);
  if (std::isfinite(w[0]) && std::isfinite(w[1]) && std::isfinite(w[2]))
    for (int k = 0; k < 3; ++k) c.w[k] = w[k];
}

/// The contact's plane (smooth or face, contact_kernel.hpp) on body vertices V (m) with unit vertex
/// normals N and faces F.
inline ContactFrame contact_frame(bool smooth, const Contact& c, const RowMatX3d& V, const RowMatX3d& N,
                                 const RowMatX3i& F) {
  Vec3 b[3], n[3];
  for (int k = 0; k < 3; ++k) {
    b[k] = V.row(F(c.tri, k)).transpose();
    n[k] = N.row(F(c.tri, k)).transpose();
  }
  return contact_frame(smooth, b, n, c.w);
}

/// The contact plane (smooth or face, contact_kernel.hpp) at each point's closest point on the
/// body (V m, F): triangle (−1 for no body), the closest point q (on the plane either way) and the
/// plane's unit normal n (#P×3). What a contact detected at P would hold (cloth.py's friction-cone
/// check, refine.py's push_outside).
struct ContactPlanes {
  VecXi tri;
  RowMatX3d q, n;
};
ContactPlanes contact_planes(const RowMatX3d& V, const RowMatX3i& F, const RowMatX3d& P, bool smooth);

class BodyCollider {
 public:
  BodyCollider() = default;
  /// valleys: also the faces' edge adjacency, which detect(..., valleys = true) needs.
  BodyCollider(const RefX3d& V, const RefX3i& F, bool valleys = false);
  bool empty() const { return !bvh_; }
  void set_vertices(const RefX3d& V);
  /// An independent copy: the BVH copied as it is — built for the first pose, refit since — not
  /// rebuilt, so queries walk the same tree and break exact ties (a point nearest a body vertex is
  /// as near every triangle around it) alike; a rebuilt tree can pick another of the tied
  /// triangles, whose face plane then differs.
  BodyCollider clone() const;
  /// Contacts of the free vertices of x closer than `radius` (m) to the body surface,
  /// sorted by vertex (deterministic), one per vertex (its closest point; the sweeps and the
  /// trajectory adjoint project and reverse contacts in parallel on that basis) unless `valleys`
  /// (only for the quasi-static solves' sets, XpbdSolver::detect_contacts): then a vertex whose closest
  /// triangle T has an edge neighbour T' rising above T's plane (a concave body edge) holds T''s
  /// face plane too while its gap to it is within ±radius. Over a valley the free space is above
  /// both planes; one plane per vertex — whichever is closer — switches at the bisector, and a
  /// solve holding one set ends where the other is closer (a re-detected set never reaches
  /// equilibrium). T''s plane extends below T, so it adds nothing away from the crease.
  /// cache (or null): the queries' memory for this body pose (sim/contact_query_cache.hpp) — the
  /// same contacts, fewer tree searches.
  std::vector<Contact> detect(const RowMatX3d& x, const VecXd& inv_mass, double radius, bool valleys = false,
                              ContactQueryCache* cache = nullptr) const;
  /// Signed distance of p to the body (m): positive outside, by the closest triangle's normal.
  double signed_distance(const Vec3& p) const;
  /// Deepest penetration below the body surface over the vertices of x (m, ≥ 0).
  double max_penetration(const RowMatX3d& x) const;

 private:
  std::shared_ptr<TriangleMeshBvh> bvh_;
  std::shared_ptr<const RowMatX3i> edge_neighbours_;  // triangle across edge k (v_k v_k+1), −1 on a border;
                                                      // only when built with valleys
};

}  // namespace diffavatar
