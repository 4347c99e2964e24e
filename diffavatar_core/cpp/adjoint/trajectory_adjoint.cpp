#include "adjoint/trajectory_adjoint.hpp"

#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "adjoint/projection_vjp.hpp"
#include "autodiff/jet.hpp"
#include "geometry/vertex_normals.hpp"
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

inline V3<double> val3(const RowMatX3d& X, int i) { return {X(i, 0), X(i, 1), X(i, 2)}; }
inline V3<double> val3(const double* r) { return {r[0], r[1], r[2]}; }

// ---- closed-form constraint geometry ---------------------------------------------------------

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

/// Derivatives of the rest-shape quantities w.r.t. the rest coordinates u; constant during one
/// adjoint call (the control is fixed), so computed once instead of once per projection.
struct RestDerivs {
  std::vector<Eigen::Matrix<double, 4, 6>> dB;  // ∂(B00, B01, B10, B11)/∂(u0, u1, u2) per triangle, B in the grain frame
  std::vector<Eigen::Matrix<double, 6, 1>> dA;  // ∂Ā/∂u per triangle
  std::vector<Eigen::Matrix<double, 8, 1>> dw;  // ∂w/∂u per hinge (w itself: RestCache::hinge_weight)

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
    for (int h = 0; h < nh; ++h) {
      Dual<8> u[4][2];
      for (int q = 0; q < 4; ++q)
        for (int d = 0; d < 2; ++d) u[q][d] = Dual<8>::var(rest(m.hinges(h, q), d), 2 * q + d);
      dw[h] = hinge_weight(u[0], u[1], u[2], u[3]).g;
    }
  }
};

/// Per-constraint constants of the reverse pass, stored by position (sim/sweep_tape.hpp: the
/// constraint's rank in plan order) so that a sweep's reverse reads them sequentially, like its
/// records. Measured on the 10k t-shirt: loading them by constraint index (scattered) was about
/// a third of the stretch reverse.
struct TriConst {
  int v[3];
  int tri;
  double w[3];    // inverse masses (1/kg)
  double B[4];    // B = D̄⁻¹ in the grain frame, as (B00, B01, B10, B11) (1/m)
  double at[3];   // α̃ = α/(Ā dt²)
  double ad;      // 1/(Ā dt²) = ∂α̃/∂α (1/(m² s²))
  double ia;      // 1/Ā (1/m²)
};
struct HingeConst {
  int v[4];
  int hinge;
  double w[4];
  double k;       // bending stiffness of its group (N·m)
  double kw;      // k times the rest weight; ≤ 0: the forward sweep skips the hinge
  double at;      // α̃ = 1/(k w dt²) when kw > 0
  double ik;      // 1/k
  double theta0;  // rest angle (rad)
};

struct Adjoints {
  RowMatX3d x;        // adjoint of positions
  RowMatX3d xprev, vnext;  // work buffers of reverse_step (reused: no allocation per step)
  RowMatX3d lam_tri;  // adjoints of the multipliers of the current step, by position
  VecXd lam_hinge;    // by position
  RowMatX3d lam_seam; // by seam index
  VecXd lam_contact;  // by contact index
  // Per contact of the current step, its plane's gradient summed over the step's sweeps (b0, b1,
  // b2, then their vertex normals N0, N1, N2, × 3; then the barycentrics w0, w1, w2); at the
  // step's end w's goes through the step's detection (region_barycentrics of the predicted
  // position) and the rest to the body vertices and normals, in contact order, so the contacts
  // (which share body vertices) are reversed in parallel. The normals' gradient reaches the body
  // vertices once, at the end (the body is fixed during the trajectory: the VJP is linear).
  Eigen::Matrix<double, Eigen::Dynamic, 21, Eigen::RowMajor> contact_body;
  RowMatX3d body_normals_bar;
  ControlGradient g;  // control gradient (body vertices directly; the rest in finish_control)
  // Per-position sums over every projection of the trajectory. The rest shape and the material
  // enter a projection only through these per-constraint quantities, and the control is fixed
  // during the call, so their chain rule to u, α and k is applied once at the end
  // (finish_control) instead of once per projection; each position is reversed by one thread per
  // sweep, so the sums do not depend on the thread count.
  Eigen::Matrix<double, Eigen::Dynamic, 8, Eigen::RowMajor> tri_acc;    // ∂φ/∂(B00, B01, B10, B11), ∂φ/∂Ā, ∂φ/∂α (3)
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> hinge_acc;  // ∂φ/∂k, w ∂φ/∂w (see reverse_hinge)
  std::vector<TriConst> tri;
  std::vector<HingeConst> hinge;
};

/// Calls f(block, position of its first constraint) for every block in plan order.
template <class F>
void for_each_block(const SweepPlan& plan, const SweepTapeLayout& L, F f) {
  for (std::size_t l = 0; l < plan.lanes.size(); ++l)
    for (std::size_t k = 0; k < plan.lanes[l].size(); ++k) f(plan.lanes[l][k], L.lane_first[l][k]);
  for (std::size_t k = 0; k < plan.interface.size(); ++k) f(plan.interface[k], L.interface_first[k]);
}

void build_constants(const XpbdSolver& S, double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  const ClothControl& c = S.control();
  const RestCache& rc = S.cache();
  const SweepTapeLayout& L = S.tape_layout();
  if (L.count[0] != m.faces.rows() || L.count[1] != m.hinges.rows() || L.count[2] != m.seams.rows())
    throw std::logic_error("trajectory adjoint: the sweep plan does not project every constraint once");
  a.tri.resize(L.count[0]);
  a.hinge.resize(L.count[1]);
  for_each_block(S.sweep_plan(), L, [&](const SweepBlock& b, int first) {
    for (std::size_t j = 0; j < b.idx.size(); ++j) {
      const int id = b.idx[j];
      if (b.kind == ConstraintKind::kStretch) {
        TriConst& K = a.tri[first + j];
        K.tri = id;
        for (int q = 0; q < 3; ++q) {
          K.v[q] = m.faces(id, q);
          K.w[q] = m.inv_mass[K.v[q]];
        }
        const Eigen::Matrix2d& B = rc.tri[id].B;
        K.B[0] = B(0, 0);
        K.B[1] = B(0, 1);
        K.B[2] = B(1, 0);
        K.B[3] = B(1, 1);
        const double area = rc.tri[id].area;
        for (int q = 0; q < 3; ++q) K.at[q] = c.stretch_compliance(m.tri_group[id], q) / (area * dt2);
        K.ad = 1.0 / (area * dt2);
        K.ia = 1.0 / area;
      } else if (b.kind == ConstraintKind::kBending) {
        HingeConst& K = a.hinge[first + j];
        K.hinge = id;
        for (int q = 0; q < 4; ++q) {
          K.v[q] = m.hinges(id, q);
          K.w[q] = m.inv_mass[K.v[q]];
        }
        K.k = c.bend_stiffness[m.hinge_group[id]];
        K.kw = K.k * rc.hinge_weight[id];
        K.at = K.kw > 0.0 ? 1.0 / (K.kw * dt2) : 0.0;
        K.ik = 1.0 / K.k;
        K.theta0 = m.hinge_rest_angle[id];
      }
    }
  });
}

// z̄ = ∇_z ψ (projection_vjp.hpp) in closed form, using the block's structure instead of its
// 3×9 matrices. With f0 = D B e0, f1 = D B e1 (B = D̄⁻¹) the rows of G = ∂C/∂x are, per corner k,
//   G_0k = c0_k f0,  G_1k = c1_k f1,  G_2k = ½(c0_k f1 + c1_k f0),
// c0 = (−B00−B10, B00, B10), c1 = (−B01−B11, B01, B11). Hence, with w_k the inverse masses,
// s_k = w_k x̄'_k, σ0 = Σ c0_k s_k, σ1 = Σ c1_k s_k and the scalars s00 = Σ w c0², s01 = Σ w c0 c1,
// s11 = Σ w c1²:  A = G W Gᵀ + diag(α̃) has A00 = s00|f0|², A11 = s11|f1|², A01 = s01 f0·f1, …;
// G s = (f0·σ0, f1·σ1, ½(f1·σ0 + f0·σ1)); and Ḡ = Δλ sᵀ + M G W (M = Ā + Āᵀ, Ā the adjoint of A)
// has blocks Ḡ_ak = Δλ_a s_k + w_k (c0_k U_a + c1_k V_a), U_a = M_a0 f0 + ½M_a2 f1,
// V_a = M_a1 f1 + ½M_a2 f0. ψ = C̄·C + Σ_a,k Ḡ_ak·G_ak is then differentiated in x and in B:
//   ∂ψ/∂x_k = c0_k S0 + c1_k S1, S0 = C̄0 f0 + ½C̄2 f1 + R0, S1 = C̄1 f1 + ½C̄2 f0 + R1,
//   R0 = P0 + ½Q1, R1 = P1 + ½Q0 with P0 = Σ c0_k Ḡ_0k, P1 = Σ c1_k Ḡ_1k, Q0 = Σ c0_k Ḡ_2k,
//   Q1 = Σ c1_k Ḡ_2k; ∂ψ/∂B through ∂f0 = d1 ∂B00 + d2 ∂B10, ∂f1 = d1 ∂B01 + d2 ∂B11 and
//   ∂(Σ_k c_k V_k)/∂B = V_1 − V_0 or V_2 − V_0 (E_a1, E_a2). The rest coordinates follow from
//   ∂ψ/∂B and ∂ψ/∂Ā in finish_control. `rec`: 3 corners, λ (sim/sweep_tape.hpp); `acc`, `lbar`:
//   this position's sums and multiplier adjoint.
void reverse_tri(const TriConst& K, const double* rec, double* acc, double* lbar, RowMatX3d& ax) {
  using V = Eigen::Vector3d;
  const double* w = K.w;
  V sv[3];
  for (int k = 0; k < 3; ++k) sv[k] = w[k] * ax.row(K.v[k]).transpose();
  const V x0 = Eigen::Map<const V>(rec);
  const V d1 = Eigen::Map<const V>(rec + 3) - x0, d2 = Eigen::Map<const V>(rec + 6) - x0;
  const V lm = Eigen::Map<const V>(rec + 9);
  const double B00 = K.B[0], B01 = K.B[1], B10 = K.B[2], B11 = K.B[3];
  const V f0 = d1 * B00 + d2 * B10, f1 = d1 * B01 + d2 * B11;
  const double c0[3] = {-(B00 + B10), B00, B10};
  const double c1[3] = {-(B01 + B11), B01, B11};
  const double ff00 = f0.squaredNorm(), ff11 = f1.squaredNorm(), ff01 = f0.dot(f1);
  const V C(0.5 * (ff00 - 1.0), 0.5 * (ff11 - 1.0), 0.5 * ff01);
  double s00 = 0.0, s01 = 0.0, s11 = 0.0;
  V sg0 = V::Zero(), sg1 = V::Zero();
  for (int k = 0; k < 3; ++k) {
    s00 += w[k] * c0[k] * c0[k];
    s01 += w[k] * c0[k] * c1[k];
    s11 += w[k] * c1[k] * c1[k];
    sg0 += c0[k] * sv[k];
    sg1 += c1[k] * sv[k];
  }
  const V at(K.at[0], K.at[1], K.at[2]);
  Eigen::Matrix3d A;
  A(0, 0) = s00 * ff00 + at[0];
  A(1, 1) = s11 * ff11 + at[1];
  A(2, 2) = 0.25 * (s00 * ff11 + 2.0 * s01 * ff01 + s11 * ff00) + at[2];
  A(0, 1) = A(1, 0) = s01 * ff01;
  A(0, 2) = A(2, 0) = 0.5 * (s00 * ff01 + s01 * ff00);
  A(1, 2) = A(2, 1) = 0.5 * (s01 * ff11 + s11 * ff01);
  // A is symmetric positive definite: its inverse from the six distinct cofactors.
  Eigen::Matrix3d Ainv;
  {
    const double c00 = A(1, 1) * A(2, 2) - A(1, 2) * A(1, 2), c01 = A(0, 2) * A(1, 2) - A(0, 1) * A(2, 2),
                 c02 = A(0, 1) * A(1, 2) - A(0, 2) * A(1, 1), c11 = A(0, 0) * A(2, 2) - A(0, 2) * A(0, 2),
                 c12 = A(0, 1) * A(0, 2) - A(0, 0) * A(1, 2), c22 = A(0, 0) * A(1, 1) - A(0, 1) * A(0, 1);
    const double id = 1.0 / (A(0, 0) * c00 + A(0, 1) * c01 + A(0, 2) * c02);
    Ainv << c00 * id, c01 * id, c02 * id, c01 * id, c11 * id, c12 * id, c02 * id, c12 * id, c22 * id;
  }
  const V dl = -(Ainv * (C + at.cwiseProduct(lm)));
  Eigen::Map<V> lb(lbar);
  const V dlbar = V(f0.dot(sg0), f1.dot(sg1), 0.5 * (f1.dot(sg0) + f0.dot(sg1))) + lb;
  const V u = Ainv * dlbar;
  const Eigen::Matrix3d M = -(u * dl.transpose() + dl * u.transpose());
  const V Cbar = -u;
  V U[3], W[3];
  for (int q = 0; q < 3; ++q) {
    U[q] = M(q, 0) * f0 + 0.5 * M(q, 2) * f1;
    W[q] = M(q, 1) * f1 + 0.5 * M(q, 2) * f0;
  }
  const V P0 = dl[0] * sg0 + s00 * U[0] + s01 * W[0], P1 = dl[1] * sg1 + s01 * U[1] + s11 * W[1];
  const V Q0 = dl[2] * sg0 + s00 * U[2] + s01 * W[2], Q1 = dl[2] * sg1 + s01 * U[2] + s11 * W[2];
  const V S0 = Cbar[0] * f0 + 0.5 * Cbar[2] * f1 + P0 + 0.5 * Q1;
  const V S1 = Cbar[1] * f1 + 0.5 * Cbar[2] * f0 + P1 + 0.5 * Q0;
  // E_aj = Ḡ_aj − Ḡ_a0 (j = 1, 2)
  const V ds[3] = {V::Zero(), sv[1] - sv[0], sv[2] - sv[0]};
  const double e0[3] = {0.0, w[1] * c0[1] - w[0] * c0[0], w[2] * c0[2] - w[0] * c0[0]};
  const double e1[3] = {0.0, w[1] * c1[1] - w[0] * c1[0], w[2] * c1[2] - w[0] * c1[0]};
  auto E = [&](int q, int j) -> V { return dl[q] * ds[j] + e0[j] * U[q] + e1[j] * W[q]; };
  const V E01 = E(0, 1), E02 = E(0, 2), E11 = E(1, 1), E12 = E(1, 2), E21 = E(2, 1), E22 = E(2, 2);
  acc[0] += d1.dot(S0) + f0.dot(E01) + 0.5 * f1.dot(E21);  // B00
  acc[1] += d1.dot(S1) + f1.dot(E11) + 0.5 * f0.dot(E21);  // B01
  acc[2] += d2.dot(S0) + f0.dot(E02) + 0.5 * f1.dot(E22);  // B10
  acc[3] += d2.dot(S1) + f1.dot(E12) + 0.5 * f0.dot(E22);  // B11
  // α̃_a = α_a / (Ā dt²): ∂α̃_a/∂α_a = α̃_a/α_a = 1/(Ā dt²), ∂α̃_a/∂Ā = −α̃_a/Ā. Ā's adjoint
  // (of A) has diagonal −u∘Δλ, so that of α̃ is −u∘(Δλ + λ).
  for (int q = 0; q < 3; ++q) {
    const double atbar = -u[q] * (dl[q] + lm[q]);
    acc[5 + q] += atbar * K.ad;
    acc[4] -= atbar * at[q] * K.ia;
  }
  for (int k = 0; k < 3; ++k) ax.row(K.v[k]) += (c0[k] * S0 + c1[k] * S1).transpose();
  lb -= at.cwiseProduct(u);  // λ̄ = λ̄' − α̃∘u
}

// The hinge angle depends on x only (the rest shape enters through the weight w in α̃), so
// z̄ = Gᵀ C̄ + D(∇θ)[Ḡ]. `rec`: 4 vertices, θ, λ. acc = (∂φ/∂k, ∂φ/∂w · w) with α̃ = 1/(k w dt²):
// ∂α̃/∂k = −α̃/k and ∂α̃/∂w = −α̃/w; the second is divided by w in finish_control.
void reverse_hinge(const HingeConst& K, const double* rec, double* acc, double* lbar, RowMatX3d& ax) {
  if (!(K.kw > 0.0)) return;
  const HingeGeom geo(rec);
  if (!geo.ok) return;
  // block_adjoint (projection_vjp.hpp) for one row: A = Σ w_q|g_q|² + α̃, Δλ = −(C + α̃λ)/A,
  // s_q = w_q x̄'_q, u = (Σ g_q·s_q + λ̄')/A, Ḡ_q = Δλ s_q − 2uΔλ w_q g_q, C̄ = −u,
  // α̃'s adjoint −u(Δλ + λ), λ̄ = λ̄' − α̃u.
  const double at = K.at, lm = rec[13];
  Eigen::Vector3d sv[4];
  double A = at, gs = 0.0;
  for (int q = 0; q < 4; ++q) {
    sv[q] = K.w[q] * ax.row(K.v[q]).transpose();
    A += K.w[q] * geo.g[q].squaredNorm();
    gs += geo.g[q].dot(sv[q]);
  }
  const double iA = 1.0 / A;
  const double dl = -(rec[12] - K.theta0 + at * lm) * iA;
  const double u = (gs + *lbar) * iA;
  double gbar[12];
  for (int q = 0; q < 4; ++q)
    Eigen::Map<Eigen::Vector3d>(gbar + 3 * q) = dl * sv[q] - (2.0 * u * dl * K.w[q]) * geo.g[q];
  Eigen::Vector3d gt[4];
  geo.tangent(gbar, gt);
  const double atbar = -u * (dl + lm);
  acc[0] -= atbar * at * K.ik;
  acc[1] -= atbar * at;
  for (int q = 0; q < 4; ++q) ax.row(K.v[q]) += (-u * geo.g[q] + gt[q]).transpose();
  *lbar -= at * u;
}

// Seams: C = x_i − x_j is linear (no Hessian term): z̄ = Jᵀ C̄. `rec`: 2 vertices, λ.
void reverse_seam(const XpbdSolver& S, const double* rec, int sidx, double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  int i = m.seams(sidx, 0), j = m.seams(sidx, 1);
  const Eigen::Vector3d C = Eigen::Map<const Eigen::Vector3d>(rec) - Eigen::Map<const Eigen::Vector3d>(rec + 3);
  Eigen::Matrix<double, 3, 6> G;
  G.leftCols<3>().setIdentity();
  G.rightCols<3>() = -Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 6, 1> w, xb;
  w.head<3>().setConstant(m.inv_mass[i]);
  w.tail<3>().setConstant(m.inv_mass[j]);
  xb.head<3>() = a.x.row(i).transpose();
  xb.tail<3>() = a.x.row(j).transpose();
  Eigen::Vector3d at = Eigen::Vector3d::Constant(m.seam_compliance / dt2);
  Eigen::Vector3d lm = Eigen::Map<const Eigen::Vector3d>(rec + 6);
  Eigen::Vector3d lb = a.lam_seam.row(sidx).transpose();
  auto r = block_adjoint<3, 6>(C, G, w, at, lm, false, xb, lb);
  a.x.row(i) += r.Cbar.transpose();
  a.x.row(j) -= r.Cbar.transpose();
  a.lam_seam.row(sidx) = r.lbar.transpose();
}

// `rec`: the vertex, λ.
void reverse_contact(const XpbdSolver& S, const double* rec, const Contact& ct, int ci, double dt2, Adjoints& a) {
  const ClothModel& m = S.model();
  Vec3 b[3], N[3];
  for (int k = 0; k < 3; ++k) {
    b[k] = S.control().body_vertices.row(m.body_faces(ct.tri, k)).transpose();
    N[k] = S.cache().body_normals.row(m.body_faces(ct.tri, k)).transpose();
  }
  const ContactFrame f = contact_frame(m.smooth_contact, b, N, ct.w);
  const Eigen::Vector3d pv = Eigen::Map<const Eigen::Vector3d>(rec);
  Eigen::Matrix<double, 1, 1> C, at, lm, lb;
  C[0] = contact_gap(pv, f, m.thickness);
  Eigen::Matrix<double, 1, 3> G = f.n.transpose();
  Eigen::Vector3d w = Eigen::Vector3d::Constant(m.inv_mass[ct.vertex]);
  Eigen::Vector3d xb = a.x.row(ct.vertex).transpose();
  at[0] = 1.0 / (m.contact_stiffness * dt2);
  lm[0] = rec[3];
  lb[0] = a.lam_contact[ci];
  auto r = block_adjoint<1, 3>(C, G, w, at, lm, true, xb, lb);
  // ψ = C̄ C + Ḡ·n̂ through the contact's plane (contact_kernel.hpp, contact_vjp).
  Vec3 gp = Vec3::Zero(), gb[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()},
       gn[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  double gw[3] = {0.0, 0.0, 0.0};
  contact_vjp(m.smooth_contact, pv, f, b, N, ct.w, r.Cbar[0], r.Gbar.row(0).transpose(), &gp, gb, gn, gw);
  a.x.row(ct.vertex) += gp.transpose();
  auto body = a.contact_body.row(ci);
  for (int k = 0; k < 3; ++k) {
    body.segment<3>(3 * k) += gb[k].transpose();
    body.segment<3>(9 + 3 * k) += gn[k].transpose();
    body[18 + k] += gw[k];
  }
  a.lam_contact[ci] = r.lbar[0];
}

/// Reverses the projections of one block (constraints of one kind sharing no vertex, positions
/// first…first+n−1) from its records (`rec`), in parallel when `parallel` and the block is large.
/// Writes only the block's vertices' rows and its own positions' entries.
void reverse_block(const XpbdSolver& S, const double* rec, const SweepBlock& b, int first, double dt2, Adjoints& a,
                   bool parallel) {
  const int n = static_cast<int>(b.idx.size());
  const bool par = parallel && n >= kReverseParallelMin;
  const int st = record_stride(b.kind);
  if (b.kind == ConstraintKind::kStretch) {
#pragma omp parallel for schedule(static) if (par)
    for (int j = 0; j < n; ++j)
      reverse_tri(a.tri[first + j], rec + j * st, a.tri_acc.row(first + j).data(), a.lam_tri.row(first + j).data(),
                  a.x);
  } else if (b.kind == ConstraintKind::kBending) {
#pragma omp parallel for schedule(static) if (par)
    for (int j = 0; j < n; ++j)
      reverse_hinge(a.hinge[first + j], rec + j * st, a.hinge_acc.row(first + j).data(), &a.lam_hinge[first + j],
                    a.x);
  } else {
#pragma omp parallel for schedule(static) if (par)
    for (int j = 0; j < n; ++j) reverse_seam(S, rec + j * st, b.idx[j], dt2, a);
  }
}

/// Reverses one sweep from its records (`sw`): the contacts (in parallel: a vertex has at most
/// one contact, BodyCollider::detect, and their body gradients go to per-contact rows), the
/// interface, then the lanes — concurrently in the lane plan, each lane's blocks in reverse
/// order.
void reverse_sweep(const XpbdSolver& S, const SweepTape& sw, const std::vector<Contact>& contacts, double dt,
                   Adjoints& a) {
  const SweepPlan& plan = S.sweep_plan();
  const SweepTapeLayout& L = S.tape_layout();
  const double dt2 = dt * dt;
  const double* rec = sw.rec.data();
  const int nc = static_cast<int>(contacts.size());
#pragma omp parallel for schedule(static) if (nc >= kReverseParallelMin)
  for (int ci = 0; ci < nc; ++ci)  // independent: any order
    reverse_contact(S, sw.contact.data() + kContactRecord * ci, contacts[ci], ci, dt2, a);
  for (int k = static_cast<int>(plan.interface.size()) - 1; k >= 0; --k)
    reverse_block(S, rec + L.interface[k], plan.interface[k], L.interface_first[k], dt2, a, true);
  if (!plan.lane_parallel()) {
    const auto& blocks = plan.lanes[0];
    for (int k = static_cast<int>(blocks.size()) - 1; k >= 0; --k)
      reverse_block(S, rec + L.lane[0][k], blocks[k], L.lane_first[0][k], dt2, a, true);
    return;
  }
  const int nl = static_cast<int>(plan.lanes.size());
#pragma omp parallel for schedule(static)
  for (int l = 0; l < nl; ++l) {
    const auto& blocks = plan.lanes[l];
    for (int k = static_cast<int>(blocks.size()) - 1; k >= 0; --k)
      reverse_block(S, rec + L.lane[l][k], blocks[k], L.lane_first[l][k], dt2, a, false);
  }
}

// Reverses one recorded step: on entry a.x holds dφ/dx after the step and vbar dφ/dv after it;
// on exit a.x and vbar hold the adjoints at the step's start. The sweeps are reversed from the
// last, each from its projection records.
void reverse_step(const XpbdSolver& S, const StepTape& tape, const SimParams& p, Adjoints& a, RowMatX3d& vbar) {
  const ClothModel& m = S.model();
  const int nv = m.num_vertices;
  const double dt = p.dt, decay = std::exp(-p.damping * p.dt);
  RowMatX3d& xprev_bar = a.xprev;
  xprev_bar.setZero(nv, 3);
  for (int i = 0; i < nv; ++i) {
    if (m.inv_mass[i] == 0.0) continue;  // pinned: v = 0, no dependence
    a.x.row(i) += vbar.row(i) / dt;
    xprev_bar.row(i) -= vbar.row(i) / dt;
  }
  const Eigen::Index nc = static_cast<Eigen::Index>(tape.contacts.size());
  a.lam_tri.setZero(a.tri.size(), 3);  // a step starts with λ = 0: no adjoint flows across steps
  a.lam_hinge.setZero(a.hinge.size());
  a.lam_seam.setZero(m.seams.rows(), 3);
  a.lam_contact.setZero(nc);
  a.contact_body.setZero(nc, 21);
  if (static_cast<int>(tape.sweeps.size()) < p.iterations)
    throw std::logic_error("trajectory adjoint: tape does not match the sweep structure");
  for (int it = p.iterations - 1; it >= 0; --it) {
    const SweepTape& sw = tape.sweeps[it];
    if (sw.rec.size() != S.tape_layout().size || sw.contact.size() != static_cast<std::size_t>(kContactRecord * nc))
      throw std::logic_error("trajectory adjoint: tape size does not match the model");
    reverse_sweep(S, sw, tape.contacts, dt, a);
  }
  for (Eigen::Index ci = 0; ci < nc; ++ci) {
    const Contact& ct = tape.contacts[ci];
    const auto row = a.contact_body.row(ci);
    for (int q = 0; q < 3; ++q) {
      const int b = m.body_faces(ct.tri, q);
      a.g.body_vertices.row(b) += row.segment<3>(3 * q);
      a.body_normals_bar.row(b) += row.segment<3>(9 + 3 * q);
    }
    // w = region_barycentrics(at, b): `at` is the vertex's predicted position, where a.x now is.
    if (!m.smooth_contact) continue;  // the face plane has no w
    Vec3 b[3], gb[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()}, g_at = Vec3::Zero();
    for (int q = 0; q < 3; ++q) b[q] = S.control().body_vertices.row(m.body_faces(ct.tri, q)).transpose();
    const double wbar[3] = {row[18], row[19], row[20]};
    region_barycentrics_vjp(ct.at, b, ct.region, wbar, &g_at, gb);
    a.x.row(ct.vertex) += g_at.transpose();
    for (int q = 0; q < 3; ++q) a.g.body_vertices.row(m.body_faces(ct.tri, q)) += gb[q].transpose();
  }
  // Prediction: x̃ = x + dt (decay v + dt g) for free vertices; pinned stay.
  RowMatX3d& vb = a.vnext;
  vb.setZero(nv, 3);
  for (int i = 0; i < nv; ++i)
    if (m.inv_mass[i] != 0.0) vb.row(i) = decay * dt * a.x.row(i);
  a.x += xprev_bar;
  vbar.swap(vb);
}

/// The chain rule from the per-position sums to the control: rest coordinates through ∂B/∂u,
/// ∂Ā/∂u and ∂w/∂u; compliances and stiffnesses summed per group, in plan order.
void finish_control(const XpbdSolver& S, const RestDerivs& rd, const Adjoints& a, ControlGradient& g) {
  const ClothModel& m = S.model();
  for (std::size_t pos = 0; pos < a.tri.size(); ++pos) {
    const int t = a.tri[pos].tri;
    const auto acc = a.tri_acc.row(pos);
    const Eigen::Matrix<double, 6, 1> zu = rd.dB[t].transpose() * acc.head<4>().transpose() + acc[4] * rd.dA[t];
    for (int k = 0; k < 3; ++k) g.rest.row(m.faces(t, k)) += zu.segment<2>(2 * k).transpose();
    g.stretch_compliance.row(m.tri_group[t]) += acc.tail<3>();
  }
  for (std::size_t pos = 0; pos < a.hinge.size(); ++pos) {
    const int h = a.hinge[pos].hinge;
    const double wbar = a.hinge_acc(pos, 1) / S.cache().hinge_weight[h];
    for (int q = 0; q < 4; ++q) g.rest.row(m.hinges(h, q)) += wbar * rd.dw[h].segment<2>(2 * q).transpose();
    g.bend_stiffness[m.hinge_group[h]] += a.hinge_acc(pos, 0);
  }
}

// Checkpoints and segment starts keep positions and velocities and, once known, the contacts
// their step detected, so a replay does not search the body again.
using PosVel = TrajectoryCheckpoints::Entry;
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

double TrajectoryCheckpoints::mb() const {
  double d = 0.0;
  for (const Entry& e : states)
    d += (e.x.size() + e.v.size()) * 8.0 / 1048576.0 +
         (e.contacts ? e.contacts->size() * sizeof(Contact) / 1048576.0 : 0.0);
  return d;
}

namespace {

TrajectoryCheckpoints forward_pass(XpbdSolver& S, const ClothState& start, const SimParams& p, int steps, int k,
                                   RunControl& rc, long total) {
  auto t0 = std::chrono::steady_clock::now();
  if (steps < 1 || k < 1) throw std::invalid_argument("trajectory adjoint: steps and checkpoint_every must be >= 1");
  // the replay records float64 projections: a float forward (sim/fast_sweep.hpp) would not match it
  if (p.fast) throw std::invalid_argument("trajectory adjoint: SimParams.fast (single-precision sweeps) is not differentiable");
  if (p.friction != 0.0)
    throw std::invalid_argument("trajectory adjoint: SimParams.friction is not differentiated; record with friction = 0");
  TrajectoryCheckpoints fw;
  fw.steps = steps;
  fw.every = k;
  fw.params = p;
  fw.solver_revision = S.revision();
  ClothState s = start;
  for (int t = 0; t < steps; ++t) {
    rc.check("trajectory adjoint (forward)");
    if (t % k == 0) fw.states.push_back({s.x, s.v, std::nullopt});
    S.step(s, p);
    if (t % k == 0) fw.states.back().contacts = S.contacts();
    rc.report({"trajectory forward", t + 1, total, 0.0});
  }
  fw.x_final = s.x;
  fw.v_final = s.v;
  fw.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return fw;
}

TrajectoryGradient backward_pass(XpbdSolver& S, const TrajectoryCheckpoints& fw, const RowMatX3d& dphi_dx,
                                 const RowMatX3d& dphi_dv, RunControl& rc, long done0, long total) {
  auto t0 = std::chrono::steady_clock::now();
  const ClothModel& m = S.model();
  if (fw.solver_revision != S.revision())
    throw std::invalid_argument(
        "trajectory adjoint: the solver's control or sweep plan was set since the forward run (or the run was "
        "recorded with another solver); record the trajectory again");
  if (dphi_dx.rows() != m.num_vertices || dphi_dv.rows() != m.num_vertices)
    throw std::invalid_argument("trajectory adjoint: dphi_dx and dphi_dv must be #V×3");
  const SimParams& p = fw.params;
  const int steps = fw.steps, k = fw.every;
  const std::vector<PosVel>& ckpt = fw.states;
  TrajectoryGradient out;
  out.x_final = fw.x_final;
  Adjoints a;
  a.x = dphi_dx;
  RowMatX3d vbar = dphi_dv;
  a.g.rest = RowMatX2d::Zero(m.num_vertices, 2);
  a.g.stretch_compliance = RowMatX3d::Zero(m.num_groups, 3);
  a.g.bend_stiffness = VecXd::Zero(m.num_groups);
  a.g.body_vertices = RowMatX3d::Zero(S.control().body_vertices.rows(), 3);
  a.body_normals_bar = RowMatX3d::Zero(S.control().body_vertices.rows(), 3);
  build_constants(S, p.dt * p.dt, a);
  a.tri_acc.setZero(a.tri.size(), 8);
  a.hinge_acc.setZero(a.hinge.size(), 2);
  const RestDerivs rd(S);
  double peak = 0.0;
  const double base = fw.mb(), state_mb = 2 * mb(fw.x_final);
  StepTape tape;  // one step's tape, its buffers reused from step to step
  for (int seg = static_cast<int>(ckpt.size()) - 1; seg >= 0; --seg) {
    int t_begin = seg * k, t_end = std::min(steps, t_begin + k);
    std::vector<PosVel> starts;
    ClothState r = restore(S, ckpt[seg]);
    for (int t = t_begin; t < t_end; ++t) {
      starts.push_back({r.x, r.v, t == t_begin ? ckpt[seg].contacts : std::nullopt});
      if (t + 1 < t_end) {
        PosVel& st = starts.back();
        S.step(r, p, nullptr, st.contacts ? &*st.contacts : nullptr);
        if (!st.contacts) st.contacts = S.contacts();
      }
    }
    for (int t = t_end - 1; t >= t_begin; --t) {
      rc.check("trajectory adjoint (backward)");
      const PosVel& st = starts[t - t_begin];
      ClothState q = restore(S, st);
      S.step(q, p, &tape, st.contacts ? &*st.contacts : nullptr);
      reverse_step(S, tape, p, a, vbar);
      const double tape_mb = tape.mb();
      out.step_tape_mb = std::max(out.step_tape_mb, tape_mb);
      peak = std::max(peak, base + starts.size() * state_mb + tape_mb);
      rc.report({"trajectory backward", done0 + steps - t, total, 0.0});
    }
  }
  if (!a.body_normals_bar.isZero(0.0))
    a.g.body_vertices += vertex_normals_vjp(S.control().body_vertices, m.body_faces, a.body_normals_bar);
  finish_control(S, rd, a, a.g);
  out.control = a.g;
  out.x0 = a.x;
  out.v0 = vbar;
  out.peak_tape_mb = peak;
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace

TrajectoryCheckpoints trajectory_forward(XpbdSolver& S, const ClothState& start, const SimParams& p, int steps, int k,
                                         RunControl& rc) {
  return forward_pass(S, start, p, steps, k, rc, steps);
}

// The replay differentiates the projections with the masses held fixed: a model whose masses
// follow its rest shape would get a rest gradient without the ∂m/∂x̄ terms, so it is refused.
static void require_fixed_masses(const ClothModel& m) {
  if (m.masses_follow_rest)
    throw std::invalid_argument("trajectory adjoint: this cloth's masses follow its rest shape "
                                "(masses_follow_rest); the trajectory adjoint holds masses fixed — "
                                "use the equilibrium adjoint, or a Cloth with masses_follow_rest=False");
}

TrajectoryGradient trajectory_backward(XpbdSolver& S, const TrajectoryCheckpoints& fw, const RowMatX3d& dphi_dx,
                                       const RowMatX3d& dphi_dv, RunControl& rc) {
  require_fixed_masses(S.model());
  return backward_pass(S, fw, dphi_dx, dphi_dv, rc, 0, fw.steps);
}

TrajectoryGradient trajectory_adjoint(XpbdSolver& S, const ClothState& start, const SimParams& p, int steps,
                                      const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int k, RunControl& rc) {
  auto t0 = std::chrono::steady_clock::now();
  const ClothModel& m = S.model();
  require_fixed_masses(m);
  // checked before the forward pass too, so a wrong argument fails before any simulation
  if (dphi_dx.rows() != m.num_vertices || dphi_dv.rows() != m.num_vertices)
    throw std::invalid_argument("trajectory adjoint: dphi_dx and dphi_dv must be #V×3");
  const TrajectoryCheckpoints fw = forward_pass(S, start, p, steps, k, rc, 2L * steps);
  TrajectoryGradient out = backward_pass(S, fw, dphi_dx, dphi_dv, rc, steps, 2L * steps);
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace diffavatar
