#include "geometry/triangle_mesh_bvh.hpp"

#include <stdexcept>

namespace diffavatar {

TriangleMeshBvh::TriangleMeshBvh(const RefX3d& V, const RefX3i& F) : V_(V), F_(F) {
  tree_.build(boxes());
}

void TriangleMeshBvh::set_vertices(const RefX3d& V) {
  if (V.rows() != V_.rows()) throw std::invalid_argument("TriangleMeshBvh: vertex count changed");
  V_ = V;
  tree_.refit(boxes());
}

std::vector<AabbTree::Box> TriangleMeshBvh::boxes() const {
  std::vector<AabbTree::Box> b(F_.rows());
  for (Eigen::Index t = 0; t < F_.rows(); ++t) {
    b[t].setEmpty();
    for (int k = 0; k < 3; ++k) b[t].extend(V_.row(F_(t, k)).transpose());
  }
  return b;
}

SurfaceHit TriangleMeshBvh::closest(const Vec3& p, double max_dist) const {
  return closest_below(p, std::isfinite(max_dist) ? max_dist * max_dist : std::numeric_limits<double>::infinity());
}

double TriangleMeshBvh::dist_sq(int t, const Vec3& p) const {
  Vec3 bary;
  int region;
  const Vec3 q = closest_point_triangle(p, V_.row(F_(t, 0)).transpose(), V_.row(F_(t, 1)).transpose(),
                                        V_.row(F_(t, 2)).transpose(), bary, region);
  return (q - p).squaredNorm();
}

SurfaceHit TriangleMeshBvh::closest_below(const Vec3& p, double bound_sq) const {
  SurfaceHit hit;
  double best_sq;
  const int t = tree_.closest(p, [&](int tri) { return dist_sq(tri, p); }, bound_sq, best_sq);
  if (t < 0) return hit;
  hit.tri = t;
  hit.point = closest_point_triangle(p, V_.row(F_(t, 0)).transpose(), V_.row(F_(t, 1)).transpose(),
                                     V_.row(F_(t, 2)).transpose(), hit.bary, hit.region);
  hit.dist_sq = best_sq;
  return hit;
}

Vec3 TriangleMeshBvh::face_normal(int t) const {
  const Vec3 a = V_.row(F_(t, 0)), b = V_.row(F_(t, 1)), c = V_.row(F_(t, 2));
  const Vec3 n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0 ? Vec3(n / len) : Vec3::Zero();
}

}  // namespace diffavatar
