// One-sided cloth–body contact (paper Eq. 6) of a cloth vertex p against a plane of its closest
// body triangle (b0, b1, b2): C = n̂·(p − q) − h ≥ 0, h the collision thickness (m). Two planes
// (ClothModel::smooth_contact):
//  - face (the default): the triangle's own plane, q = b0, n̂ = (b1 − b0) × (b2 − b0) normalised;
//  - smooth: the tangent plane at the closest point with the interpolated (Phong) normal,
//    q = Σ_k w_k b_k, n̂ = s/|s|, s = Σ_k w_k N_k, N_k the unit area-weighted vertex normals
//    (geometry/vertex_normals.hpp), w the closest point's barycentrics; it turns continuously as
//    the closest point crosses a body edge, where the face plane jumps (docs/simulation.md).
// While the contact is held (its triangle, and for the smooth plane the Voronoi region and the
// detection point `at` whose closest point gives w) C is linear in p and smooth in the body.
// Compliant penalty form U = ½ k_c min(0, C)², k_c in N/m; the XPBD projection clamps λ ≥ 0.
#pragma once
#include <Eigen/Geometry>

#include "autodiff/jet.hpp"
#include "common/types.hpp"

namespace diffavatar {

/// The contact's plane: point q (m), unit normal n, and |s| (for derivatives).
struct ContactFrame {
  Vec3 q = Vec3::Zero();
  Vec3 n = Vec3::Zero();
  double s_norm = 0.0;
};

inline ContactFrame contact_frame(bool smooth, const Vec3 b[3], const Vec3 N[3], const double w[3]) {
  ContactFrame f;
  if (!smooth) {
    const Vec3 n = (b[1] - b[0]).cross(b[2] - b[0]);
    f.q = b[0];
    f.s_norm = n.norm();
    if (f.s_norm > 0) f.n = n / f.s_norm;
    return f;
  }
  Vec3 s = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    f.q += w[k] * b[k];
    s += w[k] * N[k];
  }
  f.s_norm = s.norm();
  if (f.s_norm > 0) f.n = s / f.s_norm;
  return f;
}

inline double contact_gap(const Vec3& p, const ContactFrame& f, double h) { return f.n.dot(p - f.q) - h; }

/// Barycentrics w of the closest point of `at` on triangle (b0, b1, b2) within the Voronoi region
/// it was detected in (closest_point_triangle.hpp: 0 face — the orthogonal projection; 1–3 edges
/// b0b1, b1b2, b2b0 — the projection on the edge's line; 4–6 corners — constant), as a smooth
/// function of `at` and the triangle for any scalar T (the trajectory adjoint differentiates the
/// XPBD step's detection through it).
template <class T>
void region_barycentrics(const V3<T>& at, const V3<T> b[3], int region, T w[3]) {
  auto edge = [&](int i, int j) {
    const V3<T> e = b[j] - b[i];
    const T t = dot(at - b[i], e) / dot(e, e);
    for (int k = 0; k < 3; ++k) w[k] = T(0.0);
    w[i] = 1.0 - t;
    w[j] = t;
  };
  if (region == 0) {
    const V3<T> e1 = b[1] - b[0], e2 = b[2] - b[0], d = at - b[0];
    const T a11 = dot(e1, e1), a12 = dot(e1, e2), a22 = dot(e2, e2), r1 = dot(d, e1), r2 = dot(d, e2);
    const T det = a11 * a22 - a12 * a12;
    w[1] = (a22 * r1 - a12 * r2) / det;
    w[2] = (a11 * r2 - a12 * r1) / det;
    w[0] = 1.0 - w[1] - w[2];
  } else if (region <= 3) {
    edge(region - 1, region % 3);
  } else {
    for (int k = 0; k < 3; ++k) w[k] = T(k == region - 4 ? 1.0 : 0.0);
  }
}

/// Vector–Jacobian product of region_barycentrics: Σ_k wbar_k ∂w_k/∂(at, b0, b1, b2), added to
/// *g_at and gb[k] (a corner's w is constant: nothing added).
inline void region_barycentrics_vjp(const Vec3& at, const Vec3 b[3], int region, const double wbar[3], Vec3* g_at,
                                    Vec3 gb[3]) {
  if (region >= 4) return;
  using D = Dual<12>;
  V3<D> a{D::var(at.x(), 0), D::var(at.y(), 1), D::var(at.z(), 2)}, bd[3];
  for (int k = 0; k < 3; ++k)
    bd[k] = {D::var(b[k].x(), 3 + 3 * k), D::var(b[k].y(), 4 + 3 * k), D::var(b[k].z(), 5 + 3 * k)};
  D w[3];
  region_barycentrics(a, bd, region, w);
  Eigen::Matrix<double, 12, 1> g = Eigen::Matrix<double, 12, 1>::Zero();
  for (int k = 0; k < 3; ++k) g += wbar[k] * w[k].g;
  *g_at += g.head<3>();
  for (int k = 0; k < 3; ++k) gb[k] += g.segment<3>(3 + 3 * k);
}

/// Vector–Jacobian product of ψ = c̄ C + ḡ·∇ₚC (∇ₚC = n̂; the forms the energy's mixed product and
/// the XPBD projection's adjoint need), with v = c̄ (p − q) + ḡ: ∂ψ/∂p = c̄ n̂, and
///  - face: with n = e1 × e2 (e1 = b1 − b0, e2 = b2 − b0), y = (I − n̂ n̂ᵀ) v/|n|: ∂ψ/∂b1 = e2 × y,
///    ∂ψ/∂b2 = y × e1, ∂ψ/∂b0 = −(∂ψ/∂b1 + ∂ψ/∂b2) − c̄ n̂;
///  - smooth: ∂ψ/∂b_k = −c̄ w_k n̂, and with y = (I − n̂ n̂ᵀ) v/|s|: ∂ψ/∂N_k = w_k y,
///    ∂ψ/∂w_k = −c̄ n̂·b_k + y·N_k.
/// Added to gp, gb[k], gN[k] and (if not null) gw[k].
inline void contact_vjp(bool smooth, const Vec3& p, const ContactFrame& f, const Vec3 b[3], const Vec3 N[3],
                        const double w[3], double cbar, const Vec3& gbar, Vec3* gp, Vec3 gb[3], Vec3 gN[3],
                        double* gw = nullptr) {
  *gp += cbar * f.n;
  if (!(f.s_norm > 0)) return;
  const Vec3 v = cbar * (p - f.q) + gbar;
  const Vec3 y = (v - f.n * f.n.dot(v)) / f.s_norm;
  if (!smooth) {
    const Vec3 e1 = b[1] - b[0], e2 = b[2] - b[0];
    const Vec3 g1 = e2.cross(y), g2 = y.cross(e1);
    gb[0] -= g1 + g2 + cbar * f.n;
    gb[1] += g1;
    gb[2] += g2;
    return;
  }
  for (int k = 0; k < 3; ++k) {
    gb[k] -= cbar * w[k] * f.n;
    gN[k] += w[k] * y;
    if (gw) gw[k] += -cbar * f.n.dot(b[k]) + y.dot(N[k]);
  }
}

/// XPBD projection with fixed plane (n, q): Δλ = −(C + α̃λ)/(w + α̃), λ clamped ≥ 0.
inline void project_contact(Vec3& p, double w, const Vec3& n, const Vec3& q, double h, double alpha_tilde,
                            double* lambda) {
  double C = n.dot(p - q) - h;
  double dl = -(C + alpha_tilde * (*lambda)) / (w + alpha_tilde);
  double nl = *lambda + dl;
  if (nl < 0.0) nl = 0.0;
  dl = nl - *lambda;
  *lambda = nl;
  p += w * dl * n;
}

}  // namespace diffavatar
