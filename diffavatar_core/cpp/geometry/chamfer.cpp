#include "geometry/chamfer.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "geometry/aabb_tree.hpp"
#include "geometry/surface_sampling.hpp"
#include "geometry/triangle_mesh_bvh.hpp"

namespace diffavatar {
namespace {

constexpr Eigen::Index kChunk = 4096;  // queries between cancel checks / progress reports

// Runs query(i) for i in [0, n) in parallel chunks, polling cancel between chunks.
template <class Query>
void chunked_parallel(Eigen::Index n, const char* stage, RunControl& rc, Query&& query) {
  for (Eigen::Index begin = 0; begin < n; begin += kChunk) {
    rc.check(stage);
    const Eigen::Index end = std::min(n, begin + kChunk);
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = begin; i < end; ++i) query(i);
    rc.report({stage, static_cast<long>(end), static_cast<long>(n), std::nan("")}, end == n);
  }
}

}  // namespace

VecXd nearest_point_distances(const RefX3d& A, const RefX3d& B, RunControl& rc) {
  if (B.rows() == 0) throw std::invalid_argument("nearest_point_distances: empty target set");
  std::vector<AabbTree::Box> boxes(B.rows());
  for (Eigen::Index i = 0; i < B.rows(); ++i) boxes[i] = AabbTree::Box(B.row(i).transpose(), B.row(i).transpose());
  AabbTree tree;
  tree.build(boxes);
  VecXd d(A.rows());
  chunked_parallel(A.rows(), "nearest points", rc, [&](Eigen::Index i) {
    const Vec3 p = A.row(i);
    double best_sq;
    tree.closest(p, [&](int j) { return (B.row(j).transpose() - p).squaredNorm(); },
                 std::numeric_limits<double>::infinity(), best_sq);
    d[i] = std::sqrt(best_sq);
  });
  return d;
}

VecXd surface_distances(const RefX3d& P, const RefX3d& V, const RefX3i& F, RunControl& rc) {
  if (F.rows() == 0) throw std::invalid_argument("surface_distances: the surface has no triangles");
  TriangleMeshBvh bvh(V, F);
  VecXd d(P.rows());
  chunked_parallel(P.rows(), "surface distances", rc,
                   [&](Eigen::Index i) { d[i] = std::sqrt(bvh.closest(P.row(i).transpose()).dist_sq); });
  return d;
}

double chamfer_points(const RefX3d& A, const RefX3d& B, RunControl& rc) {
  if (A.rows() == 0 || B.rows() == 0) throw std::invalid_argument("chamfer_points: empty point set");
  return 0.5 * (nearest_point_distances(A, B, rc).mean() + nearest_point_distances(B, A, rc).mean());
}

double chamfer_meshes(const RefX3d& VA, const RefX3i& FA, const RefX3d& VB, const RefX3i& FB,
                      int samples, uint64_t seed, RunControl& rc) {
  if (samples <= 0) throw std::invalid_argument("chamfer_meshes: samples must be positive");
  const RowMatX3d SA = sample_surface(VA, FA, samples, seed);
  const RowMatX3d SB = sample_surface(VB, FB, samples, seed + 1);
  return 0.5 * (surface_distances(SA, VB, FB, rc).mean() + surface_distances(SB, VA, FA, rc).mean());
}

}  // namespace diffavatar
