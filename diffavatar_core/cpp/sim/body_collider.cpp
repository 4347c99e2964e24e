#include "sim/body_collider.hpp"

#include <algorithm>

namespace diffavatar {

BodyCollider::BodyCollider(const RefX3d& V, const RefX3i& F) {
  if (F.rows() > 0) bvh_ = std::make_shared<TriangleMeshBvh>(V, F);
}

void BodyCollider::set_vertices(const RefX3d& V) {
  if (bvh_) bvh_->set_vertices(V);
}

std::vector<Contact> BodyCollider::detect(const RowMatX3d& x, const VecXd& inv_mass, double radius) const {
  std::vector<Contact> out;
  if (!bvh_) return out;
  const int n = static_cast<int>(x.rows());
  std::vector<int> tri(n, -1);
#pragma omp parallel for schedule(static) if (n >= 256)
  for (int i = 0; i < n; ++i) {
    if (inv_mass[i] == 0.0) continue;
    SurfaceHit hit = bvh_->closest(x.row(i).transpose(), radius);
    if (hit.tri >= 0) tri[i] = hit.tri;
  }
  for (int i = 0; i < n; ++i)
    if (tri[i] >= 0) out.push_back({i, tri[i]});
  return out;
}

double BodyCollider::signed_distance(const Vec3& p) const {
  SurfaceHit hit = bvh_->closest(p);
  double d = std::sqrt(hit.dist_sq);
  return bvh_->face_normal(hit.tri).dot(p - hit.point) >= 0 ? d : -d;
}

double BodyCollider::max_penetration(const RowMatX3d& x) const {
  if (!bvh_) return 0.0;
  double worst = 0.0;
  const int n = static_cast<int>(x.rows());
#pragma omp parallel for reduction(max : worst) schedule(static) if (n >= 256)
  for (int i = 0; i < n; ++i) worst = std::max(worst, -signed_distance(x.row(i).transpose()));
  return worst;
}

}  // namespace diffavatar
