// Closest-point queries on a triangle mesh (body colliders, scan surfaces) through an AabbTree.
// Units: those of the vertices (metres inside the core).
#pragma once
#include <limits>
#include <vector>

#include "geometry/aabb_tree.hpp"
#include "geometry/closest_point_triangle.hpp"

namespace diffavatar {

/// Result of a closest-point query: triangle index (-1 if none within range), the point,
/// its barycentric coordinates in that triangle, squared distance and Voronoi region
/// (see closest_point_triangle).
struct SurfaceHit {
  int tri = -1;
  Vec3 point = Vec3::Zero();
  Vec3 bary = Vec3::Zero();
  double dist_sq = std::numeric_limits<double>::infinity();
  int region = -1;
};

class TriangleMeshBvh {
 public:
  /// V: #V×3 vertex positions, F: #F×3 vertex indices (validated by the caller). Copies both.
  TriangleMeshBvh(const RefX3d& V, const RefX3i& F);
  /// Moves the vertices (same topology) and refits the tree: O(#F).
  void set_vertices(const RefX3d& V);
  /// Closest surface point to p within max_dist (default: unbounded).
  SurfaceHit closest(const Vec3& p, double max_dist = std::numeric_limits<double>::infinity()) const;
  /// The same search with the squared bound given: the closest triangle with squared distance
  /// below bound_sq. For any bound above the minimum it returns the same triangle (the first of
  /// equally close ones in the tree's fixed visiting order: a bound prunes only nodes that
  /// cannot hold a closer one), so a caller that knows a near triangle can tighten the search.
  SurfaceHit closest_below(const Vec3& p, double bound_sq) const;
  /// Squared distance from p to triangle t (the value the searches compare).
  double dist_sq(int t, const Vec3& p) const;
  /// Calls visit(tri) for each triangle whose box, grown by `radius`, contains p.
  template <class Visit>
  void triangles_near(const Vec3& p, double radius, Visit&& visit) const {
    AabbTree::Box q(p - Vec3::Constant(radius), p + Vec3::Constant(radius));
    tree_.overlapping(q, visit);
  }
  const RowMatX3d& vertices() const { return V_; }
  const RowMatX3i& faces() const { return F_; }
  /// Unit normal of triangle t (right-hand rule on its vertex order).
  Vec3 face_normal(int t) const;

 private:
  std::vector<AabbTree::Box> boxes() const;
  RowMatX3d V_;
  RowMatX3i F_;
  AabbTree tree_;
};

}  // namespace diffavatar
