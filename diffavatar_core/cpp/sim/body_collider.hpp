// Cloth–body contact detection against a triangle-mesh body (tens of thousands of triangles)
// through the core's BVH (geometry/triangle_mesh_bvh.hpp). The body may move between steps:
// set_vertices refits the tree in O(#Fb).
#pragma once
#include <memory>
#include <vector>

#include "common/types.hpp"
#include "geometry/triangle_mesh_bvh.hpp"

namespace diffavatar {

/// A cloth vertex in contact with the plane of body triangle `tri` (contact_kernel.hpp).
struct Contact {
  int vertex;
  int tri;
};

class BodyCollider {
 public:
  BodyCollider() = default;
  BodyCollider(const RefX3d& V, const RefX3i& F);
  bool empty() const { return !bvh_; }
  void set_vertices(const RefX3d& V);
  /// Contacts of the free vertices of x closer than `radius` (m) to the body surface,
  /// sorted by vertex (deterministic), at most one per vertex (its closest body triangle; the
  /// sweeps and the trajectory adjoint project and reverse contacts in parallel on that basis).
  std::vector<Contact> detect(const RowMatX3d& x, const VecXd& inv_mass, double radius) const;
  /// Signed distance of p to the body (m): positive outside, by the closest triangle's normal.
  double signed_distance(const Vec3& p) const;
  /// Deepest penetration below the body surface over the vertices of x (m, ≥ 0).
  double max_penetration(const RowMatX3d& x) const;
  Vec3 normal(int tri) const { return bvh_->face_normal(tri); }
  Vec3 vertex(int tri, int k) const { return bvh_->vertices().row(bvh_->faces()(tri, k)); }

 private:
  std::shared_ptr<TriangleMeshBvh> bvh_;
};

}  // namespace diffavatar
