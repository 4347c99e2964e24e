#include "sim/body_collider.hpp"

#include <algorithm>

#include "geometry/vertex_normals.hpp"

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
  std::vector<SurfaceHit> hits(n);
#pragma omp parallel for schedule(static) if (n >= 256)
  for (int i = 0; i < n; ++i) {
    if (inv_mass[i] == 0.0) continue;
    hits[i] = bvh_->closest(x.row(i).transpose(), radius);
  }
  for (int i = 0; i < n; ++i)
    if (hits[i].tri >= 0)
      out.push_back({i, hits[i].tri, {hits[i].bary[0], hits[i].bary[1], hits[i].bary[2]}, hits[i].region,
                     x.row(i).transpose()});
  return out;
}

ContactPlanes contact_planes(const RowMatX3d& V, const RowMatX3i& F, const RowMatX3d& P, bool smooth) {
  const long n = P.rows();
  ContactPlanes out{VecXi::Constant(n, -1), RowMatX3d::Zero(n, 3), RowMatX3d::Zero(n, 3)};
  if (F.rows() == 0) return out;
  const TriangleMeshBvh bvh(V, F);
  const RowMatX3d N = vertex_normals(V, F);
#pragma omp parallel for schedule(dynamic, 256)
  for (long i = 0; i < n; ++i) {
    const SurfaceHit h = bvh.closest(P.row(i).transpose());
    const Contact c{static_cast<int>(i), h.tri, {h.bary[0], h.bary[1], h.bary[2]}, h.region, P.row(i).transpose()};
    out.tri[i] = h.tri;
    out.q.row(i) = h.point.transpose();  // on either plane
    out.n.row(i) = contact_frame(smooth, c, V, N, F).n.transpose();
  }
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
