// Coulomb friction of a cloth vertex against the body, applied once per XPBD step after the
// sweeps (Macklin et al. 2014, "Unified Particle Physics", §6.1; Müller et al. 2020, §3.5): the
// step's contact moved the vertex by d_n = w λ (m) along the body normal n, the normal impulse
// of the step in position units; the vertex's tangential travel over the step Δx_t (relative to
// the body, which is static within a step) is cancelled while |Δx_t| < μ d_n (static friction:
// the cone |f_t| ≤ μ f_n) and shortened by μ d_n otherwise (kinetic friction). μ is
// dimensionless. Forward only: the equilibrium adjoint differentiates the frictionless
// equilibrium with its anchor springs (cloth_energy.hpp), and the trajectory adjoint refuses
// friction (xpbd_solver.cpp).
#pragma once
#include <cmath>

#include "common/types.hpp"

namespace diffavatar {

/// p: the vertex after the step's sweeps (m), written; p_prev: at the step's start (m);
/// n: the contact's outward unit normal; normal_correction: d_n = w λ ≥ 0 (m); mu ≥ 0.
inline void apply_friction(Vec3& p, const Vec3& p_prev, const Vec3& n, double normal_correction, double mu) {
  if (!(normal_correction > 0.0) || !(mu > 0.0)) return;
  Vec3 d = p - p_prev;
  Vec3 dt = d - d.dot(n) * n;
  const double len = dt.norm();
  if (!(len > 0.0)) return;
  const double limit = mu * normal_correction;
  p -= len <= limit ? dt : (limit / len) * dt;
}

}  // namespace diffavatar
