#include "sim/body_collider.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "geometry/edge_triangles.hpp"
#include "geometry/vertex_normals.hpp"

namespace diffavatar {

namespace {

// Faces closer to coplanar than this (sine of their angle, 0.06°) hold one plane: over a 1 cm
// triangle their planes differ by < 10 µm, and a second plane would only double the stiffness.
constexpr double kValleyMinSine = 1e-3;

// The triangle across each edge k = (v_k, v_k+1) of F, −1 on a border or a non-manifold edge.
RowMatX3i edge_neighbours(const RefX3i& F) {
  const auto edges = edge_triangles(F);
  RowMatX3i out = RowMatX3i::Constant(F.rows(), 3, -1);
  for (const auto& [e, tk] : edges)
    if (tk.size() == 2) {
      out(tk[0].first, tk[0].second) = tk[1].first;
      out(tk[1].first, tk[1].second) = tk[0].first;
    }
  return out;
}

}  // namespace

BodyCollider::BodyCollider(const RefX3d& V, const RefX3i& F, bool valleys) {
  if (F.rows() > 0) {
    bvh_ = std::make_shared<TriangleMeshBvh>(V, F);
    if (valleys) edge_neighbours_ = std::make_shared<const RowMatX3i>(edge_neighbours(F));
  }
}

BodyCollider BodyCollider::clone() const {
  BodyCollider c;
  if (bvh_) c.bvh_ = std::make_shared<TriangleMeshBvh>(*bvh_);
  c.edge_neighbours_ = edge_neighbours_;  // immutable: shared
  return c;
}

void BodyCollider::set_vertices(const RefX3d& V) {
  if (bvh_) bvh_->set_vertices(V);
}

std::vector<Contact> BodyCollider::detect(const RowMatX3d& x, const VecXd& inv_mass, double radius,
                                          bool valleys, ContactQueryCache* cache) const {
  std::vector<Contact> out;
  if (!bvh_) return out;
  if (valleys && !edge_neighbours_) throw std::logic_error("BodyCollider::detect: built without valleys");
  const int n = static_cast<int>(x.rows());
  std::vector<SurfaceHit> hits(n);
  const double r_sq = radius * radius;  // an uncached search's bound: hits closer than this
  if (!cache) {
#pragma omp parallel for schedule(static) if (n >= 256)
    for (int i = 0; i < n; ++i) {
      if (inv_mass[i] == 0.0) continue;
      hits[i] = bvh_->closest_below(x.row(i).transpose(), r_sq);
    }
  } else {
    cache->fit(n);
    const double reach = 2.0 * radius;
    std::int64_t searched = 0, skipped = 0;
#pragma omp parallel for schedule(static) reduction(+ : searched, skipped) if (n >= 256)
    for (int i = 0; i < n; ++i) {
      if (inv_mass[i] == 0.0) continue;
      const Vec3 p = x.row(i).transpose();
      // farther than radius for sure (1 nm above the bound's round-off): no contact, no search
      if (cache->lower[i] - (p - cache->at[i]).norm() > radius + 1e-9) {
        ++skipped;
        continue;
      }
      ++searched;
      // bounded by the last closest triangle's distance when that is within reach, plus 1 nm: the
      // boxes above that triangle then pass the bound although their distances and the
      // triangle's are rounded differently (~1e-16 m), so it or a closer one is found
      double bound = reach * reach;
      if (cache->tri[i] >= 0) {
        const double d = std::sqrt(bvh_->dist_sq(cache->tri[i], p)) + 1e-9;
        bound = std::min(bound, d * d);
      }
      const SurfaceHit h = bvh_->closest_below(p, bound);
      cache->at[i] = p;
      cache->tri[i] = h.tri;
      cache->lower[i] = h.tri >= 0 ? std::sqrt(h.dist_sq) : reach;
      if (h.tri >= 0 && h.dist_sq < r_sq) hits[i] = h;
    }
    cache->queries += searched;
    cache->skipped += skipped;
  }
  const RowMatX3d& V = bvh_->vertices();
  const RowMatX3i& F = bvh_->faces();
  for (int i = 0; i < n; ++i) {
    const int t = hits[i].tri;
    if (t < 0) continue;
    const Vec3 p = x.row(i).transpose();
    out.push_back({i, t, {hits[i].bary[0], hits[i].bary[1], hits[i].bary[2]}, hits[i].region, p});
    if (!valleys) continue;
    const Vec3 n_t = bvh_->face_normal(t), b_t = V.row(F(t, 0)).transpose();
    for (int k = 0; k < 3; ++k) {
      const int u = (*edge_neighbours_)(t, k);
      if (u < 0) continue;
      int opposite = -1;  // T''s vertex off the shared edge
      for (int j = 0; j < 3; ++j)
        if (F(u, j) != F(t, k) && F(u, j) != F(t, (k + 1) % 3)) opposite = F(u, j);
      if (opposite < 0 || !(n_t.dot(V.row(opposite).transpose() - b_t) > 0.0)) continue;  // not a valley
      const Vec3 n_u = bvh_->face_normal(u), b_u = V.row(F(u, 0)).transpose();
      if (!(n_t.cross(n_u).norm() > kValleyMinSine)) continue;  // (nearly) coplanar: one plane
      if (!(std::abs(n_u.dot(p - b_u)) < radius)) continue;
      Eigen::Vector3d w;
      int region;
      closest_point_triangle(p, b_u, V.row(F(u, 1)).transpose(), V.row(F(u, 2)).transpose(), w, region);
      out.push_back({i, u, {w[0], w[1], w[2]}, region, p});
    }
  }
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
