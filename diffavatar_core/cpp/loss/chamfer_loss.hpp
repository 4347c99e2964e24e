// Interior feature-matching term of the DiffAvatar loss (paper §4.2.5, "Interior Point Feature
// Matching"): a symmetric squared Chamfer distance between the simulated garment surface and the
// scan's garment points, with its exact gradient w.r.t. the garment vertex positions.
#pragma once
#include "common/run_control.hpp"
#include "common/types.hpp"
#include "geometry/triangle_mesh_bvh.hpp"

namespace diffavatar {

/// Fixed sample points on the garment surface, as barycentric combinations of its vertices:
/// point_i = Σ_k bary(i,k) · X(F(tri(i), k)). Fixed within one loss evaluation, so the loss is
/// a smooth function of X between changes of nearest-neighbour assignments.
struct SurfaceSamples {
  VecXi tri;        ///< #S triangle indices
  RowMatX3d bary;   ///< #S×3 barycentric weights (rows sum to 1)
};

/// Value and gradient of the interior Chamfer loss.
struct ChamferLossResult {
  double value = 0.0;          ///< L (m²)
  double garment_to_scan = 0.0;  ///< mean squared distance, garment samples → scan (points or surface) (m²)
  double scan_to_garment = 0.0;  ///< mean squared distance, scan points → garment surface (m²)
  int garment_trimmed = 0;     ///< garment samples ignored (the scan, points or surface, beyond trim distance)
  int scan_trimmed = 0;        ///< scan points ignored (garment surface beyond trim distance)
  RowMatX3d grad;              ///< dL/dX, #V×3 (m)
};

/// L = ½ [ mean_i |g_i − t(g_i)|² + mean_j |s_j − c_j|² ]
///   g_i: garment samples (from `samples` on X, F); t(g): the closest point of `scan_surface`
///   (the scan's garment mesh, m) when given, else the nearest scan point — with a few thousand
///   scan points 1–2 cm apart that nearest point is ~0.8 cm away on average even where the two
///   surfaces coincide, a floor larger than the folds' misfit;
///   s_j: scan points (#T×3, m); c_j: closest point of the garment surface to s_j.
/// Pairs farther apart than `trim_distance` (m; ≤ 0 disables) are left out of both the value
/// and the gradient: scan holes and floating fragments must not drag the garment.
/// Gradient: dL/dx_v = Σ_i (1/N_g) b_iv (g_i − t_i) + Σ_j (1/N_s) b_jv (c_j − s_j) — exact
/// (envelope theorem: the closest-point parameters are optimal over the fixed triangle domain;
/// the scan is fixed, so t_i does not depend on X to first order either way).
/// X: #V×3 garment positions (m), F: #F×3, scan: #T×3 (m). Deterministic for a thread count.
ChamferLossResult chamfer_loss(const RefX3d& X, const RefX3i& F, const SurfaceSamples& samples,
                               const RefX3d& scan, double trim_distance, RunControl& rc,
                               const TriangleMeshBvh* scan_surface = nullptr);

}  // namespace diffavatar
