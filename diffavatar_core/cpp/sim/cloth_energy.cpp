#include "sim/cloth_energy.hpp"

#include <Eigen/Eigenvalues>

#include "autodiff/jet.hpp"
#include "geometry/vertex_normals.hpp"
#include "sim/bending_kernel.hpp"
#include "sim/contact_kernel.hpp"
#include "sim/grain_frame.hpp"
#include "sim/seam_kernel.hpp"
#include "sim/stretch_kernel.hpp"

namespace diffavatar {
namespace {

template <class T>
V3<T> var3(const RowMatX3d& X, int i, int off) {
  return {T::var(X(i, 0), off), T::var(X(i, 1), off + 1), T::var(X(i, 2), off + 2)};
}

// Triangle: Q_a = ½ Ā ε_a² (ε in the grain frame) as jets over z = [x0 x1 x2 (9) | ū0 ū1 ū2 (6)] for
// the mixed derivatives ∂²E/∂x∂ū; E = Σ_a Q_a / α_a. (∇ₓE and ∇ₓ²E: stretch_derivatives.)
std::array<Jet<15>, 3> tri_terms(const EnergyContext& c, const RowMatX3d& x, int t) {
  using J = Jet<15>;
  V3<J> xs[3];
  J u[3][2];
  for (int k = 0; k < 3; ++k) {
    int i = c.model.faces(t, k);
    xs[k] = var3<J>(x, i, 3 * k);
    for (int d = 0; d < 2; ++d)
      u[k][d] = J::var(c.control.rest(i, d), 9 + 2 * k + d);
  }
  J ug[3][2];  // rest corners in the grain frame (grain_frame.hpp); ∂/∂ū chains through R(−g)
  to_grain_frame(c.model.tri_frame[t], u, ug);
  auto e = green_strain(xs, ug);
  J A = rest_area(ug);
  return {0.5 * A * e[0] * e[0], 0.5 * A * e[1] * e[1], 0.5 * A * e[2] * e[2]};
}

void corners(const ClothModel& m, const RowMatX3d& x, int t, Vec3 xs[3]) {
  for (int k = 0; k < 3; ++k) xs[k] = x.row(m.faces(t, k)).transpose();
}

// Hinge h: its corners (12, m), θ − θ0 (rad) and ∇θ (12, 1/m) by dihedral_gradient; false if degenerate.
bool hinge_angle(const ClothModel& m, const RowMatX3d& x, int h, double xs[12], double* theta,
                 Eigen::Matrix<double, 12, 1>* g) {
  for (int k = 0; k < 4; ++k)
    for (int d = 0; d < 3; ++d) xs[3 * k + d] = x(m.hinges(h, k), d);
  Vec3 g4[4];
  const Eigen::Map<const Vec3> a(xs), b(xs + 3), cc(xs + 6), dd(xs + 9);
  if (!dihedral_gradient(a, b, cc, dd, theta, g4)) return false;
  *theta -= m.hinge_rest_angle[h];
  for (int k = 0; k < 4; ++k) g->segment<3>(3 * k) = g4[k];
  return true;
}

// W = V ⊗ I₃ (3NV × 3(NV−1)) with V the Helmert basis of the vectors of R^NV orthogonal to
// (1, …, 1): orthonormal columns spanning everything but the element's rigid translations.
template <int NV>
Eigen::Matrix<double, 3 * NV, 3 * (NV - 1)> translation_free_basis() {
  Eigen::Matrix<double, 3 * NV, 3 * (NV - 1)> W = Eigen::Matrix<double, 3 * NV, 3 * (NV - 1)>::Zero();
  for (int j = 1; j < NV; ++j) {
    const double s = 1.0 / std::sqrt(static_cast<double>(j * (j + 1)));
    for (int k = 0; k <= j; ++k)
      W.template block<3, 3>(3 * k, 3 * (j - 1)) = (k < j ? s : -j * s) * Eigen::Matrix3d::Identity();
  }
  return W;
}

// H clamped to its non-negative eigenvalues, for an element Hessian over NV vertices of a
// translation-invariant energy: H annihilates the translations, so H = W M Wᵀ with M = WᵀHW and
// the projection is W proj(M) Wᵀ — the same matrix from an eigenproblem of 3(NV−1) instead of 3NV
// (6 instead of 9 for a triangle, 9 instead of 12 for a hinge).
template <int NV>
Eigen::Matrix<double, 3 * NV, 3 * NV> project_psd(const Eigen::Matrix<double, 3 * NV, 3 * NV>& H) {
  constexpr int R = 3 * (NV - 1);
  static const Eigen::Matrix<double, 3 * NV, R> W = translation_free_basis<NV>();
  const Eigen::Matrix<double, R, R> M = W.transpose() * H * W;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, R, R>> es(M);
  const Eigen::Matrix<double, 3 * NV, R> Q = W * es.eigenvectors();
  return Q * es.eigenvalues().cwiseMax(0.0).asDiagonal() * Q.transpose();
}

}  // namespace

double total_energy(const EnergyContext& c, const RowMatX3d& x) {
  const ClothModel& m = c.model;
  double E = 0.0;
#pragma omp parallel for reduction(+ : E) schedule(static) if (m.faces.rows() >= 512)
  for (int t = 0; t < m.faces.rows(); ++t) {
    V3<double> xs[3];
    double u[3][2], al[3];
    for (int k = 0; k < 3; ++k) {
      int i = m.faces(t, k);
      xs[k] = {x(i, 0), x(i, 1), x(i, 2)};
      u[k][0] = c.control.rest(i, 0);
      u[k][1] = c.control.rest(i, 1);
      al[k] = c.control.stretch_compliance(m.tri_group[t], k);
    }
    double ug[3][2];
    to_grain_frame(m.tri_frame[t], u, ug);
    E += stretch_energy(xs, ug, al);
  }
#pragma omp parallel for reduction(+ : E) schedule(static) if (m.hinges.rows() >= 512)
  for (int h = 0; h < m.hinges.rows(); ++h) {
    double k = c.control.bend_stiffness[m.hinge_group[h]];
    if (k == 0.0) continue;
    V3<double> xs[4];
    for (int j = 0; j < 4; ++j) {
      int i = m.hinges(h, j);
      xs[j] = {x(i, 0), x(i, 1), x(i, 2)};
    }
    double th = dihedral_angle(xs[0], xs[1], xs[2], xs[3]) - m.hinge_rest_angle[h];
    if (std::isfinite(th)) E += 0.5 * k * c.cache.hinge_weight[h] * th * th;
  }
  for (int s = 0; s < m.seams.rows(); ++s)
    E += (x.row(m.seams(s, 0)) - x.row(m.seams(s, 1))).squaredNorm() * 0.5 / m.seam_compliance;
  for (std::size_t j = 0; j < c.contacts.size(); ++j) {
    double C = contact_gap(x.row(c.contacts[j].vertex).transpose(), c.frames[j], m.thickness);
    if (C < 0.0) E += 0.5 * m.contact_stiffness * C * C;
  }
  for (int i = 0; i < x.rows(); ++i) E -= m.mass[i] * c.gravity.dot(x.row(i).transpose());
  if (c.anchor && c.anchor_stiffness > 0)
    for (int i = 0; i < x.rows(); ++i)
      E += 0.5 * c.anchor_stiffness * m.mass[i] * (x.row(i) - c.anchor->row(i)).squaredNorm();
  return E;
}

RowMatX3d energy_gradient(const EnergyContext& c, const RowMatX3d& x) {
  const ClothModel& m = c.model;
  const int nv = static_cast<int>(x.rows());
  RowMatX3d G(nv, 3);
  for (int i = 0; i < nv; ++i) G.row(i) = -m.mass[i] * c.gravity.transpose();
  if (c.anchor && c.anchor_stiffness > 0)
    for (int i = 0; i < nv; ++i) G.row(i) += c.anchor_stiffness * m.mass[i] * (x.row(i) - c.anchor->row(i));
  // Element gradients in parallel, scattered serially (deterministic).
  std::vector<Eigen::Matrix<double, 9, 1>> gt(m.faces.rows());
#pragma omp parallel for schedule(static) if (m.faces.rows() >= 256)
  for (int t = 0; t < m.faces.rows(); ++t) {
    Vec3 xs[3];
    corners(m, x, t, xs);
    stretch_derivatives(xs, c.cache.tri[t], c.control.stretch_compliance.row(m.tri_group[t]).transpose(), &gt[t],
                        nullptr);
  }
  std::vector<Eigen::Matrix<double, 12, 1>> gh(m.hinges.rows());
#pragma omp parallel for schedule(static) if (m.hinges.rows() >= 256)
  for (int h = 0; h < m.hinges.rows(); ++h) {
    gh[h].setZero();
    double k = c.control.bend_stiffness[m.hinge_group[h]];
    if (k == 0.0) continue;
    double xs[12], th;
    Eigen::Matrix<double, 12, 1> g;
    if (!hinge_angle(m, x, h, xs, &th, &g)) continue;
    gh[h] = k * c.cache.hinge_weight[h] * th * g;
  }
  for (int t = 0; t < m.faces.rows(); ++t)
    for (int k = 0; k < 3; ++k) G.row(m.faces(t, k)) += gt[t].segment<3>(3 * k).transpose();
  for (int h = 0; h < m.hinges.rows(); ++h)
    for (int k = 0; k < 4; ++k) G.row(m.hinges(h, k)) += gh[h].segment<3>(3 * k).transpose();
  for (int s = 0; s < m.seams.rows(); ++s) {
    Eigen::RowVector3d d = (x.row(m.seams(s, 0)) - x.row(m.seams(s, 1))) / m.seam_compliance;
    G.row(m.seams(s, 0)) += d;
    G.row(m.seams(s, 1)) -= d;
  }
  for (std::size_t j = 0; j < c.contacts.size(); ++j) {
    const int i = c.contacts[j].vertex;
    const ContactFrame& f = c.frames[j];
    double C = contact_gap(x.row(i).transpose(), f, m.thickness);
    if (C < 0.0) G.row(i) += m.contact_stiffness * C * f.n.transpose();
  }
  return G;
}

ElementHessians element_hessians(const EnergyContext& c, const RowMatX3d& x, bool psd) {
  const ClothModel& m = c.model;
  ElementHessians eh;
  eh.tri.resize(m.faces.rows());
  eh.hinge.resize(m.hinges.rows());
#pragma omp parallel for schedule(static) if (m.faces.rows() >= 256)
  for (int t = 0; t < m.faces.rows(); ++t) {
    Vec3 xs[3];
    corners(m, x, t, xs);
    stretch_derivatives(xs, c.cache.tri[t], c.control.stretch_compliance.row(m.tri_group[t]).transpose(), nullptr,
                        &eh.tri[t]);
    if (psd) eh.tri[t] = project_psd<3>(eh.tri[t]);
  }
#pragma omp parallel for schedule(static) if (m.hinges.rows() >= 256)
  for (int h = 0; h < m.hinges.rows(); ++h) {
    eh.hinge[h].setZero();
    double k = c.control.bend_stiffness[m.hinge_group[h]];
    if (k == 0.0) continue;
    double xs[12], th;
    Eigen::Matrix<double, 12, 1> g;
    if (!hinge_angle(m, x, h, xs, &th, &g)) continue;
    // ∇²(½ k w θ²) = k w (∇θ ∇θᵀ + θ ∇²θ), ∇²θ by HingeGeom (bending_kernel.hpp). Far from
    // equilibrium (psd) its Gauss–Newton part k w ∇θ ∇θᵀ: PSD by construction, the exact block at
    // the rest angle, and no 9×9 eigenproblem — the clamp of the whole block cost twice the rest of
    // the assembly, and bench/newton.py's re-equilibration took 55 Newton iterations with it, 39
    // without (BENCHMARKS.md stop 59).
    if (psd && !c.hinge_clamp) {
      eh.hinge[h] = k * c.cache.hinge_weight[h] * (g * g.transpose());
      continue;
    }
    eh.hinge[h] = k * c.cache.hinge_weight[h] * (g * g.transpose() + th * HingeGeom(xs).hessian());
    if (psd) eh.hinge[h] = project_psd<4>(eh.hinge[h]);
  }
  return eh;
}

Eigen::SparseMatrix<double> energy_hessian(const EnergyContext& c, const RowMatX3d& x, const std::vector<int>& dof,
                                           bool psd) {
  const ClothModel& m = c.model;
  int n = 0;
  for (int d : dof) n = std::max(n, d + 3);
  const ElementHessians eh = element_hessians(c, x, psd);
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(m.faces.rows() * 81 + m.hinges.rows() * 144 + m.seams.rows() * 36 + c.contacts.size() * 9 +
               m.num_vertices * 3);
  scatter_hessian(
      c, x, dof, eh, [&](int r, int col, double v) { trip.emplace_back(r, col, v); },
      [&](int vtx, int i, int j, double v) { trip.emplace_back(dof[vtx] + i, dof[vtx] + j, v); });
  Eigen::SparseMatrix<double> S(n, n);
  S.setFromTriplets(trip.begin(), trip.end());
  return S;
}

ControlGradient mixed_product(const EnergyContext& c, const RowMatX3d& x, const RowMatX3d& mu) {
  const ClothModel& m = c.model;
  ControlGradient g;
  g.rest = RowMatX2d::Zero(c.control.rest.rows(), 2);
  g.stretch_compliance = RowMatX3d::Zero(m.num_groups, 3);
  g.bend_stiffness = VecXd::Zero(m.num_groups);
  g.body_vertices = RowMatX3d::Zero(c.control.body_vertices.rows(), 3);
  // Triangles: μ_localᵀ ∂²E/∂x∂ū and ∂/∂α_a (∇ₓE) = −∇ₓQ_a/α_a².
  std::vector<Eigen::Matrix<double, 6, 1>> gu(m.faces.rows());
  std::vector<Eigen::Vector3d> ga(m.faces.rows());
#pragma omp parallel for schedule(static) if (m.faces.rows() >= 256)
  for (int t = 0; t < m.faces.rows(); ++t) {
    auto q = tri_terms(c, x, t);
    Eigen::Matrix<double, 9, 1> ml;
    for (int k = 0; k < 3; ++k) ml.segment<3>(3 * k) = mu.row(m.faces(t, k)).transpose();
    gu[t].setZero();
    for (int a = 0; a < 3; ++a) {
      double al = c.control.stretch_compliance(m.tri_group[t], a);
      gu[t] += q[a].H.template block<6, 9>(9, 0) * ml / al;
      ga[t][a] = -ml.dot(q[a].g.template head<9>()) / (al * al);
    }
  }
  std::vector<Eigen::Matrix<double, 8, 1>> hu(m.hinges.rows());
  std::vector<double> hk(m.hinges.rows(), 0.0);
#pragma omp parallel for schedule(static) if (m.hinges.rows() >= 256)
  for (int h = 0; h < m.hinges.rows(); ++h) {
    hu[h].setZero();
    double xs[12], th;
    Eigen::Matrix<double, 12, 1> gth;
    if (!hinge_angle(m, x, h, xs, &th, &gth)) continue;
    Dual<8> u[4][2];  // w over ū (8)
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 2; ++d) u[k][d] = Dual<8>::var(c.control.rest(m.hinges(h, k), d), 2 * k + d);
    const Dual<8> w = hinge_weight(u[0], u[1], u[2], u[3]);
    double k = c.control.bend_stiffness[m.hinge_group[h]];
    Eigen::Matrix<double, 12, 1> ml;
    for (int j = 0; j < 4; ++j) ml.segment<3>(3 * j) = mu.row(m.hinges(h, j)).transpose();
    double s = ml.dot(gth) * th;  // μᵀ θ ∇θ
    hu[h] = k * s * w.g;          // ∂/∂ū of k w θ ∇θ
    hk[h] = w.v * s;              // ∂/∂k
  }
  for (int t = 0; t < m.faces.rows(); ++t) {
    for (int k = 0; k < 3; ++k) g.rest.row(m.faces(t, k)) += gu[t].segment<2>(2 * k).transpose();
    g.stretch_compliance.row(m.tri_group[t]) += ga[t].transpose();
  }
  for (int h = 0; h < m.hinges.rows(); ++h) {
    for (int k = 0; k < 4; ++k) g.rest.row(m.hinges(h, k)) += hu[h].segment<2>(2 * k).transpose();
    g.bend_stiffness[m.hinge_group[h]] += hk[h];
  }
  if (m.masses_follow_rest) {
    // ∇_{x_i}E ∋ m_i (−g + κ (x_i − a_i)) with m_i = ρ Σ_{t∋i} A_t(x̄)/3:
    // μᵀ ∂/∂x̄ = Σ_t (ρ/3) Σ_{i∈t} μ_i·(−g + κ (x_i − a_i)) ∂A_t/∂x̄.
    VecXd s(m.num_vertices);
    const bool anchored = c.anchor && c.anchor_stiffness > 0;
    for (int i = 0; i < m.num_vertices; ++i) {
      Vec3 f = -c.gravity;
      if (anchored) f += c.anchor_stiffness * (x.row(i) - c.anchor->row(i)).transpose();
      s[i] = mu.row(i).dot(f.transpose());
    }
    for (int t = 0; t < m.faces.rows(); ++t) {
      Dual<6> u[3][2];   // ∂Ā/∂ū in the pattern frame (an area does not depend on the grain)
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 2; ++d) u[k][d] = Dual<6>::var(c.control.rest(m.faces(t, k), d), 2 * k + d);
      const Eigen::Matrix<double, 6, 1> dA = rest_area(u).g;
      const double w = m.density / 3.0 * (s[m.faces(t, 0)] + s[m.faces(t, 1)] + s[m.faces(t, 2)]);
      for (int k = 0; k < 3; ++k) g.rest.row(m.faces(t, k)) += w * dA.segment<2>(2 * k).transpose();
    }
  }
  RowMatX3d gN;  // gradient w.r.t. the body's vertex normals, carried to its vertices at the end
  for (std::size_t j = 0; j < c.contacts.size(); ++j) {
    const Contact& ct = c.contacts[j];
    Vec3 b[3], N[3];
    for (int k = 0; k < 3; ++k) {
      b[k] = c.control.body_vertices.row(m.body_faces(ct.tri, k)).transpose();
      N[k] = c.cache.body_normals.row(m.body_faces(ct.tri, k)).transpose();
    }
    const ContactFrame& f = c.frames[j];
    const Vec3 p = x.row(ct.vertex).transpose();
    const double C = contact_gap(p, f, m.thickness);
    if (C >= 0.0) continue;
    // μₚ·∇ₚU = k C (n̂·μₚ): its body derivative is contact_vjp's ψ with c̄ = k n̂·μₚ, ḡ = k C μₚ.
    const Vec3 mp = mu.row(ct.vertex).transpose();
    Vec3 gp = Vec3::Zero(), gb[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()},
         gn[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    double gw[3] = {0.0, 0.0, 0.0};
    contact_vjp(m.smooth_contact, p, f, b, N, ct.w, m.contact_stiffness * f.n.dot(mp), m.contact_stiffness * C * mp,
                &gp, gb, gn, gw);
    Vec3 g_at = Vec3::Zero();  // the held detection point is not a variable here
    if (m.smooth_contact) region_barycentrics_vjp(ct.at, b, ct.region, gw, &g_at, gb);  // w follows the body
    if (gN.rows() == 0) gN = RowMatX3d::Zero(c.control.body_vertices.rows(), 3);
    for (int k = 0; k < 3; ++k) {
      g.body_vertices.row(m.body_faces(ct.tri, k)) += gb[k].transpose();
      gN.row(m.body_faces(ct.tri, k)) += gn[k].transpose();
    }
  }
  if (m.smooth_contact && gN.rows()) g.body_vertices += vertex_normals_vjp(c.control.body_vertices, m.body_faces, gN);
  return g;
}

}  // namespace diffavatar
