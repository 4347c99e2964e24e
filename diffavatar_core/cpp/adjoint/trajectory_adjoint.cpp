#include "adjoint/trajectory_adjoint.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "adjoint/projection_vjp.hpp"
#include "autodiff/jet.hpp"
#include "sim/bending_kernel.hpp"
#include "sim/contact_kernel.hpp"
#include "sim/grain_frame.hpp"
#include "sim/stretch_kernel.hpp"

namespace diffavatar {
namespace {

// Below this many constraints in a colour the reverse pass runs serially, as the forward sweep
// does (xpbd_solver.cpp): on a shared, oversubscribed machine a fork/join per colour pass (tens
// of thousands per trajectory) costs far more than the work it splits (measured: 64 made the
// 532-vertex skirt's adjoint ~8× slower on 2 loaded cores).
constexpr int kReverseParallelMin = 1024;

template <class T>
V3<T> var3(const RowMatX3d& X, int i, int off) {
  return {T::var(X(i, 0), off), T::var(X(i, 1), off + 1), T::var(X(i, 2), off + 2)};
}
inline V3<double> val3(const RowMatX3d& X, int i) { return {X(i, 0), X(i, 1), X(i, 2)}; }
template <class T>
T comp(const V3<T>& v, int d) {
  return d == 0 ? v.x : (d == 1 ? v.y : v.z);
}

// ---- closed-form constraint values and x-gradients, generic in the scalar -------------------
// Differentiating these once with duals gives exactly the Hessian-vector products the reverse
// projection needs (projection_vjp.hpp).

/// Stretch block (stretch_kernel.hpp): C = Green strain [ε00, ε11, ε01] with B = D̄⁻¹ given as
/// (B00, B01, B10, B11), and g[a][k] = ∂C_a/∂x_k.
template <class T>
void stretch_cg(const V3<T> x[3], const T B[4], T C[3], V3<T> g[3][3]) {
  const T &B00 = B[0], &B01 = B[1], &B10 = B[2], &B11 = B[3];
  V3<T> d1 = x[1] - x[0], d2 = x[2] - x[0];
  V3<T> f0 = d1 * B00 + d2 * B10, f1 = d1 * B01 + d2 * B11;
  C[0] = 0.5 * (dot(f0, f0) - 1.0);
  C[1] = 0.5 * (dot(f1, f1) - 1.0);
  C[2] = 0.5 * dot(f0, f1);
  const T c0[3] = {-(B00 + B10), B00, B10};
  const T c1[3] = {-(B01 + B11), B01, B11};
  for (int k = 0; k < 3; ++k) {
    g[0][k] = f0 * c0[k];
    g[1][k] = f1 * c1[k];
    g[2][k] = (f1 * c0[k] + f0 * c1[k]) * T(0.5);
  }
}

/// B = D̄⁻¹ from the rest corners u (stretch_kernel.hpp, green_strain), as (B00, B01, B10, B11).
template <class T>
void rest_inverse(const T u[3][2], T B[4]) {
  T a = u[1][0] - u[0][0], b = u[2][0] - u[0][0];
  T c = u[1][1] - u[0][1], d = u[2][1] - u[0][1];
  T det = a * d - b * c;
  B[0] = d / det;
  B[1] = -b / det;
  B[2] = -c / det;
  B[3] = a / det;
}

/// Hinge (bending_kernel.hpp, dihedral_gradient): θ and ∇θ; false if degenerate.
template <class T>
bool dihedral_cg(const V3<T>& a, const V3<T>& b, const V3<T>& c, const V3<T>& d, T* theta, V3<T> g[4]) {
  V3<T> e = b - a;
  T el = norm(e);
  V3<T> n1 = cross(e, c - a), n2 = cross(d - a, e);
  T q1 = dot(n1, n1), q2 = dot(n2, n2);
  if (value_of(el) < 1e-12 || value_of(q1) < 1e-30 || value_of(q2) < 1e-30) return false;
  T iel = T(1.0) / el;
  V3<T> eh = e * iel;
  *theta = atan2(dot(cross(n1, n2), eh), dot(n1, n2));
  V3<T> m1 = n1 * (T(1.0) / q1), m2 = n2 * (T(1.0) / q2);
  g[2] = m1 * (-el);
  g[3] = m2 * (-el);
  g[0] = m1 * (-dot(c - b, eh)) - m2 * dot(d - b, eh);
  g[1] = m1 * dot(c - a, eh) + m2 * dot(d - a, eh);
  return true;
}

/// Contact (contact_kernel.hpp): C = n̂·(p − b0) − h, ∇_p C = n̂, n = (b1−b0)×(b2−b0).
template <class T>
T contact_cg(const V3<T>& p, const V3<T>& b0, const V3<T>& b1, const V3<T>& b2, double h, V3<T>* gp) {
  V3<T> n = cross(b1 - b0, b2 - b0);
  *gp = n * (T(1.0) / norm(n));
  return dot(*gp, p - b0) - h;
}

/// Derivatives of the rest-shape quantities w.r.t. the rest coordinates u; constant during one
/// adjoint call (the control is fixed), so computed once instead of once per projection.
struct RestDerivs {
  std::vector<Eigen::Matrix<double, 4, 6>> dB;  // ∂(B00, B01, B10, B11)/∂(u0, u1, u2) per triangle, B in the grain frame
  std::vector<Eigen::Matrix<double, 6, 1>> dA;  // ∂Ā/∂u per triangle
  std::vector<Eigen::Matrix<double, 8, 1>> dw;  // ∂w/∂u per hinge
  VecXd w;                                      // hinge weight (as from hinge_weight)

  explicit RestDerivs(const XpbdSolver& S) {
    const ClothModel& m = S.model();
    const RowMatX2d& rest = S.control().rest;
    const int nf = static_cast<int>(m.faces.rows()), nh = static_cast<int>(m.hinges.rows());
    dB.resize(nf);
    dA.resize(nf);
    for (int t = 0; t < nf; ++t) {
      Dual<6> u[3][2], ug[3][2], B[4];
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 2; ++d) u[k][d] = Dual<6>::var(rest(m.faces(t, k), d), 2 * k + d);
      to_grain_frame(m.tri_frame[t], u, ug);  // B is formed in the grain frame (cloth_control.cpp)
      rest_inverse(ug, B);
      for (int q = 0; q < 4; ++q) dB[t].row(q) = B[q].g.transpose();
      dA[t] = rest_area(ug).g;
    }
    dw.resize(nh);
    w.resize(nh);
    for (int h = 0; h < nh; ++h) {
      Dual<8> u[4][2];
      for (int q = 0; q < 4; ++q)
        for (int d = 0; d < 2; ++d) u[q][d] = Dual<8>::var(rest(m.hinges(h, q), d), 2 * q + d);
      Dual<8> wj = hinge_weight(u[0], u[1], u[2], u[3]);
      w[h] = wj.v;
      dw[h] = wj.g;
    }
  }
};

struct Adjoints {
  const RestDerivs* rd = nullptr;
  RowMatX3d x;        // adjoint of positions
  RowMatX3d lam_tri;  // adjoints of the multipliers of the current step
  VecXd lam_hinge;
  RowMatX3d lam_seam;
  VecXd lam_contact;
  ControlGradient g;  // accumulated control gradient
  RowMatX3d tri_sc;   // per-triangle contribution to dφ/dα (summed per group in colour order)
  VecXd hinge_k;      // per-hinge contribution to dφ/dk
};

/// Multipliers at the start of a sweep, all constraint kinds.
struct SweepLambda {
  RowMatX3d tri;
  VecXd hinge;
  RowMatX3d seam;
  VecXd contact;
};

// z̄ = ∇_z ψ (projection_vjp.hpp) in closed form. The rest-coordinate rows: ψ depends on u only
// through B = D̄⁻¹ (4 numbers), so ∂ψ/∂B times the cached ∂B/∂u.
void reverse_tri(const XpbdSolver& S, const RowMatX3d& x, const RowMatX3d& lam, int t, double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  const ClothControl& c = S.control();
  const RestCache& rc = S.cache();
  int vi[3];
  V3<double> xd[3];
  Eigen::Matrix<double, 9, 1> w, xb;
  for (int k = 0; k < 3; ++k) {
    int i = vi[k] = m.faces(t, k);
    xd[k] = val3(x, i);
    w.segment<3>(3 * k).setConstant(m.inv_mass[i]);
    xb.segment<3>(3 * k) = a.x.row(i).transpose();
  }
  const Eigen::Matrix2d& Bm = rc.tri[t].B;
  const double Bd[4] = {Bm(0, 0), Bm(0, 1), Bm(1, 0), Bm(1, 1)};
  double Cd[3];
  V3<double> gd[3][3];
  stretch_cg(xd, Bd, Cd, gd);
  Eigen::Vector3d C(Cd[0], Cd[1], Cd[2]);
  Eigen::Matrix<double, 3, 9> G;
  for (int q = 0; q < 3; ++q)
    for (int k = 0; k < 3; ++k) G.block<1, 3>(q, 3 * k) << gd[q][k].x, gd[q][k].y, gd[q][k].z;
  const double area = rc.tri[t].area;
  Eigen::Vector3d al = c.stretch_compliance.row(m.tri_group[t]).transpose();
  Eigen::Vector3d at = al / (area * dt2);
  Eigen::Vector3d lm = lam.row(t).transpose();
  Eigen::Vector3d lb = a.lam_tri.row(t).transpose();
  auto r = block_adjoint<3, 9>(C, G, w, at, lm, false, xb, lb);
  // ψ = C̄·C + f0·(P0 + ½Q1) + f1·(P1 + ½Q0) with P0 = Σ_k c0_k Ḡ_0k, P1 = Σ_k c1_k Ḡ_1k,
  // Q0 = Σ_k c0_k Ḡ_2k, Q1 = Σ_k c1_k Ḡ_2k (Ḡ_ak the 3-block of row a for corner k), since
  // ∇_k C_0 = c0_k f0, ∇_k C_1 = c1_k f1, ∇_k C_2 = ½(c0_k f1 + c1_k f0). f0, f1 and c0, c1 are
  // linear in x and in B respectively, so its gradients are closed-form:
  //   ∂ψ/∂x_k = (Gᵀ C̄)_k + c0_k (P0 + ½Q1) + c1_k (P1 + ½Q0),
  //   ∂ψ/∂B via ∂f0 = d1 ∂B00 + d2 ∂B10, ∂f1 = d1 ∂B01 + d2 ∂B11 and ∂(Σ_k c_k V_k)/∂B = V_1 − V_0
  //   or V_2 − V_0 (E_a1, E_a2 below).
  const double c0[3] = {-(Bd[0] + Bd[2]), Bd[0], Bd[2]};
  const double c1[3] = {-(Bd[1] + Bd[3]), Bd[1], Bd[3]};
  auto blk = [&](int q, int k) -> Eigen::Vector3d { return r.Gbar.block<1, 3>(q, 3 * k).transpose(); };
  Eigen::Vector3d P0 = Eigen::Vector3d::Zero(), P1 = P0, Q0 = P0, Q1 = P0;
  for (int k = 0; k < 3; ++k) {
    P0 += c0[k] * blk(0, k);
    P1 += c1[k] * blk(1, k);
    Q0 += c0[k] * blk(2, k);
    Q1 += c1[k] * blk(2, k);
  }
  const Eigen::Vector3d R0 = P0 + 0.5 * Q1, R1 = P1 + 0.5 * Q0;
  Eigen::Matrix<double, 9, 1> zx = G.transpose() * r.Cbar;
  for (int k = 0; k < 3; ++k) zx.segment<3>(3 * k) += c0[k] * R0 + c1[k] * R1;
  const Eigen::Vector3d x0(xd[0].x, xd[0].y, xd[0].z);
  const Eigen::Vector3d d1 = Eigen::Vector3d(xd[1].x, xd[1].y, xd[1].z) - x0;
  const Eigen::Vector3d d2 = Eigen::Vector3d(xd[2].x, xd[2].y, xd[2].z) - x0;
  const Eigen::Vector3d f0 = d1 * Bd[0] + d2 * Bd[2], f1 = d1 * Bd[1] + d2 * Bd[3];
  const Eigen::Vector3d E01 = blk(0, 1) - blk(0, 0), E02 = blk(0, 2) - blk(0, 0);
  const Eigen::Vector3d E11 = blk(1, 1) - blk(1, 0), E12 = blk(1, 2) - blk(1, 0);
  const Eigen::Vector3d E21 = blk(2, 1) - blk(2, 0), E22 = blk(2, 2) - blk(2, 0);
  // vectors multiplying d1/d2 in ∂ψ/∂B: C̄0 f0 + ½C̄2 f1 + R0 (B00, B10) and C̄1 f1 + ½C̄2 f0 + R1 (B01, B11)
  const Eigen::Vector3d S0 = r.Cbar[0] * f0 + 0.5 * r.Cbar[2] * f1 + R0;
  const Eigen::Vector3d S1 = r.Cbar[1] * f1 + 0.5 * r.Cbar[2] * f0 + R1;
  Eigen::Matrix<double, 4, 1> psiB;
  psiB[0] = d1.dot(S0) + f0.dot(E01) + 0.5 * f1.dot(E21);  // B00
  psiB[1] = d1.dot(S1) + f1.dot(E11) + 0.5 * f0.dot(E21);  // B01
  psiB[2] = d2.dot(S0) + f0.dot(E02) + 0.5 * f1.dot(E22);  // B10
  psiB[3] = d2.dot(S1) + f1.dot(E12) + 0.5 * f0.dot(E22);  // B11
  // α̃_a = α_a / (Ā dt²): the compliance part is summed per group later (deterministic order);
  // the area part goes to the rest coordinates through ∂Ā/∂u.
  double Abar = 0.0;
  for (int q = 0; q < 3; ++q) {
    a.tri_sc(t, q) = r.atbar[q] / (area * dt2);
    Abar -= r.atbar[q] * al[q] / (area * area * dt2);
  }
  const Eigen::Matrix<double, 6, 1> zu = a.rd->dB[t].transpose() * psiB + Abar * a.rd->dA[t];
  for (int k = 0; k < 3; ++k) {
    int i = vi[k];
    a.x.row(i) += zx.segment<3>(3 * k).transpose();
    a.g.rest.row(i) += zu.segment<2>(2 * k).transpose();
  }
  a.lam_tri.row(t) = r.lbar.transpose();
}

// The hinge angle depends on x only (the rest shape enters through the weight w in α̃), so
// z̄ = Gᵀ C̄ + D(∇θ)[Ḡ]: one tangent through the closed-form ∇θ.
void reverse_hinge(const XpbdSolver& S, const RowMatX3d& x, const VecXd& lam, int h, double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  const ClothControl& c = S.control();
  const RestCache& rc = S.cache();
  a.hinge_k[h] = 0.0;
  double k = c.bend_stiffness[m.hinge_group[h]];
  double kw = k * rc.hinge_weight[h];
  if (!(kw > 0.0)) return;
  int vi[4];
  V3<double> xd[4];
  Eigen::Matrix<double, 12, 1> w, xb;
  for (int q = 0; q < 4; ++q) {
    int i = vi[q] = m.hinges(h, q);
    xd[q] = val3(x, i);
    w.segment<3>(3 * q).setConstant(m.inv_mass[i]);
    xb.segment<3>(3 * q) = a.x.row(i).transpose();
  }
  double th;
  V3<double> gd[4];
  if (!dihedral_cg(xd[0], xd[1], xd[2], xd[3], &th, gd)) return;
  Eigen::Matrix<double, 1, 1> C, at, lm, lb;
  C[0] = th - m.hinge_rest_angle[h];
  Eigen::Matrix<double, 1, 12> G;
  for (int q = 0; q < 4; ++q) G.segment<3>(3 * q) << gd[q].x, gd[q].y, gd[q].z;
  at[0] = 1.0 / (kw * dt2);
  lm[0] = lam[h];
  lb[0] = a.lam_hinge[h];
  auto r = block_adjoint<1, 12>(C, G, w, at, lm, false, xb, lb);
  using D = Dual<1>;
  V3<D> xs[4];
  for (int q = 0; q < 4; ++q) {
    xs[q] = {D(xd[q].x), D(xd[q].y), D(xd[q].z)};
    xs[q].x.g[0] = r.Gbar(0, 3 * q);
    xs[q].y.g[0] = r.Gbar(0, 3 * q + 1);
    xs[q].z.g[0] = r.Gbar(0, 3 * q + 2);
  }
  D thj;
  V3<D> gj[4];
  dihedral_cg(xs[0], xs[1], xs[2], xs[3], &thj, gj);
  // α̃ = 1/(k w dt²): ∂α̃/∂k = −α̃/k, ∂α̃/∂w = −α̃/w
  a.hinge_k[h] = -r.atbar[0] * at[0] / k;
  double wbar = -r.atbar[0] * at[0] / a.rd->w[h];
  for (int q = 0; q < 4; ++q) {
    int i = vi[q];
    a.x.row(i) += (r.Cbar[0] * G.segment<3>(3 * q) + Eigen::RowVector3d(gj[q].x.g[0], gj[q].y.g[0], gj[q].z.g[0]));
    a.g.rest.row(i) += wbar * a.rd->dw[h].segment<2>(2 * q).transpose();
  }
  a.lam_hinge[h] = r.lbar[0];
}

// Seams: C = x_i − x_j is linear (no Hessian term): z̄ = Jᵀ C̄.
void reverse_seam(const XpbdSolver& S, const RowMatX3d& x, const RowMatX3d& lam, int sidx, double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  int i = m.seams(sidx, 0), j = m.seams(sidx, 1);
  Eigen::Vector3d C = (x.row(i) - x.row(j)).transpose();
  Eigen::Matrix<double, 3, 6> G;
  G.leftCols<3>().setIdentity();
  G.rightCols<3>() = -Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 6, 1> w, xb;
  w.head<3>().setConstant(m.inv_mass[i]);
  w.tail<3>().setConstant(m.inv_mass[j]);
  xb.head<3>() = a.x.row(i).transpose();
  xb.tail<3>() = a.x.row(j).transpose();
  Eigen::Vector3d at = Eigen::Vector3d::Constant(m.seam_compliance / dt2);
  Eigen::Vector3d lm = lam.row(sidx).transpose();
  Eigen::Vector3d lb = a.lam_seam.row(sidx).transpose();
  auto r = block_adjoint<3, 6>(C, G, w, at, lm, false, xb, lb);
  a.x.row(i) += r.Cbar.transpose();
  a.x.row(j) -= r.Cbar.transpose();
  a.lam_seam.row(sidx) = r.lbar.transpose();
}

void reverse_contact(const XpbdSolver& S, const RowMatX3d& x, const VecXd& lam, const Contact& ct, int ci,
                     double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  const ClothControl& c = S.control();
  const RowMatX3d& B = c.body_vertices;
  int bi[3];
  for (int q = 0; q < 3; ++q) bi[q] = m.body_faces(ct.tri, q);
  V3<double> nd;
  double Cd = contact_cg(val3(x, ct.vertex), val3(B, bi[0]), val3(B, bi[1]), val3(B, bi[2]), m.thickness, &nd);
  Eigen::Matrix<double, 1, 1> C, at, lm, lb;
  C[0] = Cd;
  Eigen::Matrix<double, 1, 3> G(nd.x, nd.y, nd.z);
  Eigen::Vector3d w = Eigen::Vector3d::Constant(m.inv_mass[ct.vertex]);
  Eigen::Vector3d xb = a.x.row(ct.vertex).transpose();
  at[0] = 1.0 / (m.contact_stiffness * dt2);
  lm[0] = lam[ci];
  lb[0] = a.lam_contact[ci];
  auto r = block_adjoint<1, 3>(C, G, w, at, lm, true, xb, lb);
  // ψ = C̄ C + Ḡ·n̂ = n̂·v − C̄ h with v = C̄ (p − b0) + Ḡ: ∂ψ/∂p = C̄ n̂ (∇_p C = n̂ is constant in
  // p); through n = e1 × e2 (e1 = b1 − b0, e2 = b2 − b0): y = ∂(n̂·v)/∂n = (v − n̂ (n̂·v))/|n|,
  // ∂/∂b1 = e2 × y, ∂/∂b2 = y × e1, ∂/∂b0 = −(∂/∂b1 + ∂/∂b2) − C̄ n̂.
  const Eigen::Vector3d pv = x.row(ct.vertex).transpose();
  const Eigen::Vector3d b0 = B.row(bi[0]).transpose(), e1 = B.row(bi[1]).transpose() - b0,
                        e2 = B.row(bi[2]).transpose() - b0;
  const Eigen::Vector3d n = e1.cross(e2);
  const double nl = n.norm();
  const Eigen::Vector3d nh = n / nl;
  const double cb = r.Cbar[0];
  const Eigen::Vector3d v = cb * (pv - b0) + r.Gbar.row(0).transpose();
  const Eigen::Vector3d y = (v - nh * nh.dot(v)) / nl;
  const Eigen::Vector3d g1 = e2.cross(y), g2 = y.cross(e1);
  a.x.row(ct.vertex) += cb * nh.transpose();
  a.g.body_vertices.row(bi[0]) -= (g1 + g2 + cb * nh).transpose();
  a.g.body_vertices.row(bi[1]) += g1.transpose();
  a.g.body_vertices.row(bi[2]) += g2.transpose();
  a.lam_contact[ci] = r.lbar[0];
}

/// Reverses the projections of one block (constraints of one kind sharing no vertex), in
/// parallel when `parallel` and the block is large. Writes only the block's vertices' rows and
/// its own per-constraint entries; the per-group material sums are formed by accumulate().
void reverse_block(const XpbdSolver& S, const RowMatX3d& x, const SweepLambda& lam, const SweepBlock& b, double dt2,
                   Adjoints& a, bool parallel) {
  const int n = static_cast<int>(b.idx.size());
  const bool par = parallel && n >= kReverseParallelMin;
  if (b.kind == ConstraintKind::kStretch) {
#pragma omp parallel for schedule(static) if (par)
    for (int j = 0; j < n; ++j) reverse_tri(S, x, lam.tri, b.idx[j], dt2, a);
  } else if (b.kind == ConstraintKind::kBending) {
#pragma omp parallel for schedule(static) if (par)
    for (int j = 0; j < n; ++j) reverse_hinge(S, x, lam.hinge, b.idx[j], dt2, a);
  } else {
#pragma omp parallel for schedule(static) if (par)
    for (int j = 0; j < n; ++j) reverse_seam(S, x, lam.seam, b.idx[j], dt2, a);
  }
}

/// Adds a reversed block's per-constraint material adjoints to the per-group sums, in block
/// order, so the result does not depend on the thread count.
void accumulate(const ClothModel& m, const SweepBlock& b, Adjoints& a) {
  if (b.kind == ConstraintKind::kStretch) {
    for (int t : b.idx)
      for (int q = 0; q < 3; ++q) a.g.stretch_compliance(m.tri_group[t], q) += a.tri_sc(t, q);
  } else if (b.kind == ConstraintKind::kBending) {
    for (int h : b.idx) a.g.bend_stiffness[m.hinge_group[h]] += a.hinge_k[h];
  }
}

/// Reverses one sweep from the positions before each of its blocks (`sw`, by plan slot): the
/// contacts (serial: they share body vertices), the interface, then the lanes — concurrently in
/// the lane plan, each lane's blocks in reverse order, their material sums afterwards in a fixed
/// order.
void reverse_sweep(const XpbdSolver& S, const SweepTape& sw, const SweepLambda& lam,
                   const std::vector<Contact>& contacts, double dt, Adjoints& a) {
  const ClothModel& m = S.model();
  const SweepPlan& plan = S.sweep_plan();
  const double dt2 = dt * dt;
  const int nslots = plan.num_slots(), base = plan.max_lane_blocks();
  const RowMatX3d& xc = sw.x_before[nslots - 1];
  for (int ci = 0; ci < static_cast<int>(contacts.size()); ++ci)  // independent: any order
    reverse_contact(S, xc, lam.contact, contacts[ci], ci, dt2, a);
  for (int k = static_cast<int>(plan.interface.size()) - 1; k >= 0; --k) {
    reverse_block(S, sw.x_before[base + k], lam, plan.interface[k], dt2, a, true);
    accumulate(m, plan.interface[k], a);
  }
  if (!plan.lane_parallel()) {
    const auto& blocks = plan.lanes[0];
    for (int k = static_cast<int>(blocks.size()) - 1; k >= 0; --k) {
      reverse_block(S, sw.x_before[k], lam, blocks[k], dt2, a, true);
      accumulate(m, blocks[k], a);
    }
    return;
  }
  const int nl = static_cast<int>(plan.lanes.size());
#pragma omp parallel for schedule(static)
  for (int l = 0; l < nl; ++l) {
    const auto& blocks = plan.lanes[l];
    for (int k = static_cast<int>(blocks.size()) - 1; k >= 0; --k)
      reverse_block(S, sw.x_before[k], lam, blocks[k], dt2, a, false);
  }
  for (int l = 0; l < nl; ++l)
    for (int k = static_cast<int>(plan.lanes[l].size()) - 1; k >= 0; --k) accumulate(m, plan.lanes[l][k], a);
}

// Reverses one recorded step: on entry a.x holds dφ/dx after the step and vbar dφ/dv after it;
// on exit a.x and vbar hold the adjoints at the step's start. Each sweep is first replayed from
// its recorded start (positions and multipliers) to recover the positions before every colour
// pass (one sweep's worth, in `sw`), then reversed pass by pass. The replay uses the solver's
// contacts, which are those of the step just recorded.
void reverse_step(XpbdSolver& S, const StepTape& tape, const SimParams& p, Adjoints& a, RowMatX3d& vbar,
                  SweepTape& sw) {
  const ClothModel& m = S.model();
  const int nv = m.num_vertices;
  const double dt = p.dt, decay = std::exp(-p.damping * p.dt);
  RowMatX3d xprev_bar = RowMatX3d::Zero(nv, 3);
  for (int i = 0; i < nv; ++i) {
    if (m.inv_mass[i] == 0.0) continue;  // pinned: v = 0, no dependence
    a.x.row(i) += vbar.row(i) / dt;
    xprev_bar.row(i) -= vbar.row(i) / dt;
  }
  const Eigen::Index nf = m.faces.rows(), nh = m.hinges.rows(), ns = m.seams.rows();
  const Eigen::Index nc = static_cast<Eigen::Index>(tape.contacts.size());
  a.lam_tri = RowMatX3d::Zero(nf, 3);
  a.lam_hinge = VecXd::Zero(nh);
  a.lam_seam = RowMatX3d::Zero(ns, 3);
  a.lam_contact = VecXd::Zero(nc);
  const int nslots = S.sweep_plan().num_slots();
  if (static_cast<int>(tape.x_sweep.size()) != p.iterations || tape.lambda_sweep.size() != tape.x_sweep.size() ||
      S.contacts().size() != tape.contacts.size())
    throw std::logic_error("trajectory adjoint: tape does not match the sweep structure");
  ClothState q;
  SweepLambda lam;
  for (int it = p.iterations - 1; it >= 0; --it) {
    // Every constraint is projected once per sweep, so the multipliers before its pass are
    // those at the sweep start.
    const VecXd& L = tape.lambda_sweep[it];
    if (L.size() != 3 * nf + nh + 3 * ns + nc) throw std::logic_error("trajectory adjoint: multiplier tape size");
    lam.tri = Eigen::Map<const RowMatX3d>(L.data(), nf, 3);
    lam.hinge = L.segment(3 * nf, nh);
    lam.seam = Eigen::Map<const RowMatX3d>(L.data() + 3 * nf + nh, ns, 3);
    lam.contact = L.tail(nc);
    q.x = tape.x_sweep[it];
    q.lambda_tri = lam.tri;
    q.lambda_hinge = lam.hinge;
    q.lambda_seam = lam.seam;
    q.lambda_contact = lam.contact;
    S.sweep(q, dt, &sw);
    if (static_cast<int>(sw.x_before.size()) != nslots)
      throw std::logic_error("trajectory adjoint: sweep replay does not match the sweep plan");
    reverse_sweep(S, sw, lam, tape.contacts, dt, a);
  }
  // Prediction: x̃ = x + dt (decay v + dt g) for free vertices; pinned stay.
  RowMatX3d vb = RowMatX3d::Zero(nv, 3);
  for (int i = 0; i < nv; ++i)
    if (m.inv_mass[i] != 0.0) vb.row(i) = decay * dt * a.x.row(i);
  a.x += xprev_bar;
  vbar = vb;
}

// Checkpoints and segment starts keep positions and velocities only: a step zeroes its
// multipliers before the first sweep, so they carry no information across steps.
struct PosVel {
  RowMatX3d x, v;
};
ClothState restore(const XpbdSolver& S, const PosVel& c) {
  ClothState s = S.make_state(c.x);
  s.v = c.v;
  return s;
}

template <class M>
double mb(const M& a) {
  return a.size() * 8.0 / 1048576.0;
}

}  // namespace

TrajectoryGradient trajectory_adjoint(XpbdSolver& S, const ClothState& start, const SimParams& p, int steps,
                                      const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int k, RunControl& rc) {
  auto t0 = std::chrono::steady_clock::now();
  const ClothModel& m = S.model();
  if (steps < 1 || k < 1) throw std::invalid_argument("trajectory adjoint: steps and checkpoint_every must be >= 1");
  if (dphi_dx.rows() != m.num_vertices || dphi_dv.rows() != m.num_vertices)
    throw std::invalid_argument("trajectory adjoint: dphi_dx and dphi_dv must be #V×3");
  // Forward with checkpoints.
  std::vector<PosVel> ckpt;
  ClothState s = start;
  for (int t = 0; t < steps; ++t) {
    rc.check("trajectory adjoint (forward)");
    if (t % k == 0) ckpt.push_back({s.x, s.v});
    S.step(s, p);
    rc.report({"trajectory forward", t + 1, 2L * steps, 0.0});
  }
  TrajectoryGradient out;
  out.x_final = s.x;
  Adjoints a;
  a.x = dphi_dx;
  RowMatX3d vbar = dphi_dv;
  a.g.rest = RowMatX2d::Zero(m.num_vertices, 2);
  a.g.stretch_compliance = RowMatX3d::Zero(m.num_groups, 3);
  a.g.bend_stiffness = VecXd::Zero(m.num_groups);
  a.g.body_vertices = RowMatX3d::Zero(S.control().body_vertices.rows(), 3);
  a.tri_sc = RowMatX3d::Zero(m.faces.rows(), 3);
  const RestDerivs rd(S);
  a.rd = &rd;
  a.hinge_k = VecXd::Zero(m.hinges.rows());
  double peak = 0.0, base = ckpt.size() * 2 * mb(start.x);
  SweepTape sw;
  for (int seg = static_cast<int>(ckpt.size()) - 1; seg >= 0; --seg) {
    int t_begin = seg * k, t_end = std::min(steps, t_begin + k);
    std::vector<PosVel> starts;
    ClothState r = restore(S, ckpt[seg]);
    for (int t = t_begin; t < t_end; ++t) {
      starts.push_back({r.x, r.v});
      if (t + 1 < t_end) S.step(r, p);
    }
    for (int t = t_end - 1; t >= t_begin; --t) {
      rc.check("trajectory adjoint (backward)");
      StepTape tape;
      ClothState q = restore(S, starts[t - t_begin]);
      S.step(q, p, &tape);
      reverse_step(S, tape, p, a, vbar, sw);
      double tape_mb = 0.0;
      for (const auto& xs : tape.x_sweep) tape_mb += mb(xs);
      for (const auto& ls : tape.lambda_sweep) tape_mb += mb(ls);
      for (const auto& xb : sw.x_before) tape_mb += mb(xb);
      out.step_tape_mb = std::max(out.step_tape_mb, tape_mb);
      peak = std::max(peak, base + starts.size() * 2 * mb(start.x) + tape_mb);
      rc.report({"trajectory backward", 2L * steps - t, 2L * steps, 0.0});
    }
  }
  out.control = a.g;
  out.x0 = a.x;
  out.v0 = vbar;
  out.peak_tape_mb = peak;
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace diffavatar
