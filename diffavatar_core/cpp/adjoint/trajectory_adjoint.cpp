#include "adjoint/trajectory_adjoint.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "adjoint/projection_vjp.hpp"
#include "autodiff/jet.hpp"
#include "sim/bending_kernel.hpp"
#include "sim/contact_kernel.hpp"
#include "sim/stretch_kernel.hpp"

namespace diffavatar {
namespace {

using MatXd = Eigen::MatrixXd;

template <class T>
V3<T> var3(const RowMatX3d& X, int i, int off) {
  return {T::var(X(i, 0), off), T::var(X(i, 1), off + 1), T::var(X(i, 2), off + 2)};
}

template <int N>
void unpack(const std::vector<Jet<N>>& c, VecXd& C, MatXd& J, std::vector<MatXd>& H) {
  const int m = static_cast<int>(c.size());
  C.resize(m);
  J.resize(m, N);
  H.assign(m, MatXd());
  for (int a = 0; a < m; ++a) {
    C[a] = c[a].v;
    J.row(a) = c[a].g.transpose();
    H[a] = c[a].H;
  }
}

struct Adjoints {
  RowMatX3d x;        // adjoint of positions
  RowMatX3d lam_tri;  // adjoints of the multipliers of the current step
  VecXd lam_hinge;
  RowMatX3d lam_seam;
  VecXd lam_contact;
  ControlGradient g;  // accumulated control gradient
};

void reverse_pass(const XpbdSolver& S, const StepTape& tape, int pass, int kind, const std::vector<int>& color,
                  double dt, Adjoints& a) {
  const ClothModel& m = S.model();
  const ClothControl& c = S.control();
  const RestCache& rc = S.cache();
  const RowMatX3d& x = tape.x_before[pass];
  const VecXd& lam = tape.lambda_before[pass];
  const double dt2 = dt * dt;
  VecXd C;
  MatXd J;
  std::vector<MatXd> H;
  if (kind == 0) {  // stretch triangles
    for (int t : color) {
      using Jt = Jet<15>;
      V3<Jt> xs[3];
      Jt u[3][2];
      VecXd w(9), xb(9);
      for (int k = 0; k < 3; ++k) {
        int i = m.faces(t, k);
        xs[k] = var3<Jt>(x, i, 3 * k);
        for (int d = 0; d < 2; ++d) u[k][d] = Jt::var(c.rest(i, d), 9 + 2 * k + d);
        w.segment<3>(3 * k).setConstant(m.inv_mass[i]);
        xb.segment<3>(3 * k) = a.x.row(i).transpose();
      }
      auto e = green_strain(xs, u);
      Jt Ar = rest_area(u);
      unpack<15>({e[0], e[1], e[2]}, C, J, H);
      Eigen::Vector3d al = c.stretch_compliance.row(m.tri_group[t]).transpose();
      VecXd at = al / (rc.tri[t].area * dt2);
      VecXd lm = lam.segment<3>(3 * t);
      VecXd lb = a.lam_tri.row(t).transpose();
      BlockVjp r = block_vjp(9, C, J, H, w, at, lm, false, xb, lb);
      // α̃_a = α_a / (Ā dt²)
      double Abar = 0.0;
      for (int q = 0; q < 3; ++q) {
        a.g.stretch_compliance(m.tri_group[t], q) += r.atbar[q] / (rc.tri[t].area * dt2);
        Abar -= r.atbar[q] * al[q] / (rc.tri[t].area * rc.tri[t].area * dt2);
      }
      VecXd zb = r.zbar + Abar * Ar.g;
      for (int k = 0; k < 3; ++k) {
        int i = m.faces(t, k);
        a.x.row(i) += zb.segment<3>(3 * k).transpose();
        a.g.rest.row(i) += zb.segment<2>(9 + 2 * k).transpose();
      }
      a.lam_tri.row(t) = r.lbar.transpose();
    }
  } else if (kind == 1) {  // bending hinges
    for (int h : color) {
      double k = c.bend_stiffness[m.hinge_group[h]];
      double kw = k * rc.hinge_weight[h];
      if (!(kw > 0.0)) continue;
      Vec3 P[4];
      for (int q = 0; q < 4; ++q) P[q] = x.row(m.hinges(h, q)).transpose();
      double th;
      Vec3 g4[4];
      if (!dihedral_gradient(P[0], P[1], P[2], P[3], &th, g4)) continue;
      using Jh = Jet<12>;
      V3<Jh> xs[4];
      Dual<8> u[4][2];
      VecXd w(12), xb(12);
      for (int q = 0; q < 4; ++q) {
        int i = m.hinges(h, q);
        xs[q] = var3<Jh>(x, i, 3 * q);
        for (int d = 0; d < 2; ++d) u[q][d] = Dual<8>::var(c.rest(i, d), 2 * q + d);
        w.segment<3>(3 * q).setConstant(m.inv_mass[i]);
        xb.segment<3>(3 * q) = a.x.row(i).transpose();
      }
      Jh thj = dihedral_angle(xs[0], xs[1], xs[2], xs[3]) - m.hinge_rest_angle[h];
      Dual<8> wj = hinge_weight(u[0], u[1], u[2], u[3]);
      unpack<12>({thj}, C, J, H);
      VecXd at(1), lm(1), lb(1);
      at[0] = 1.0 / (kw * dt2);
      lm[0] = lam[h];
      lb[0] = a.lam_hinge[h];
      BlockVjp r = block_vjp(12, C, J, H, w, at, lm, false, xb, lb);
      // α̃ = 1/(k w dt²): ∂α̃/∂k = −α̃/k, ∂α̃/∂w = −α̃/w
      a.g.bend_stiffness[m.hinge_group[h]] -= r.atbar[0] * at[0] / k;
      double wbar = -r.atbar[0] * at[0] / wj.v;
      for (int q = 0; q < 4; ++q) {
        int i = m.hinges(h, q);
        a.x.row(i) += r.zbar.segment<3>(3 * q).transpose();
        a.g.rest.row(i) += wbar * wj.g.segment<2>(2 * q).transpose();
      }
      a.lam_hinge[h] = r.lbar[0];
    }
  } else if (kind == 2) {  // seams: C = x_i − x_j
    for (int sidx : color) {
      int i = m.seams(sidx, 0), j = m.seams(sidx, 1);
      C = (x.row(i) - x.row(j)).transpose();
      J = MatXd::Zero(3, 6);
      J.leftCols(3).setIdentity();
      J.rightCols(3) = -Eigen::Matrix3d::Identity();
      H.assign(3, MatXd::Zero(6, 6));
      VecXd w(6), xb(6);
      w.head<3>().setConstant(m.inv_mass[i]);
      w.tail<3>().setConstant(m.inv_mass[j]);
      xb.head<3>() = a.x.row(i).transpose();
      xb.tail<3>() = a.x.row(j).transpose();
      VecXd at = VecXd::Constant(3, m.seam_compliance / dt2);
      VecXd lm = lam.segment<3>(3 * sidx);
      VecXd lb = a.lam_seam.row(sidx).transpose();
      BlockVjp r = block_vjp(6, C, J, H, w, at, lm, false, xb, lb);
      a.x.row(i) += r.zbar.head<3>().transpose();
      a.x.row(j) += r.zbar.tail<3>().transpose();
      a.lam_seam.row(sidx) = r.lbar.transpose();
    }
  } else {  // contacts
    for (int ci = 0; ci < static_cast<int>(tape.contacts.size()); ++ci) {
      const Contact& ct = tape.contacts[ci];
      using Jc = Jet<12>;
      V3<Jc> pj = var3<Jc>(x, ct.vertex, 0);
      V3<Jc> b[3];
      for (int q = 0; q < 3; ++q) b[q] = var3<Jc>(c.body_vertices, m.body_faces(ct.tri, q), 3 + 3 * q);
      Jc Cj = contact_gap(pj, b[0], b[1], b[2], m.thickness);
      unpack<12>({Cj}, C, J, H);
      VecXd w = VecXd::Constant(3, m.inv_mass[ct.vertex]);
      VecXd xb = a.x.row(ct.vertex).transpose();
      VecXd at(1), lm(1), lb(1);
      at[0] = 1.0 / (m.contact_stiffness * dt2);
      lm[0] = lam[ci];
      lb[0] = a.lam_contact[ci];
      BlockVjp r = block_vjp(3, C, J, H, w, at, lm, true, xb, lb);
      a.x.row(ct.vertex) += r.zbar.head<3>().transpose();
      for (int q = 0; q < 3; ++q)
        a.g.body_vertices.row(m.body_faces(ct.tri, q)) += r.zbar.segment<3>(3 + 3 * q).transpose();
      a.lam_contact[ci] = r.lbar[0];
    }
  }
}

// Reverses one recorded step: on entry a.x holds dφ/dx after the step and vbar dφ/dv after it;
// on exit a.x and vbar hold the adjoints at the step's start.
void reverse_step(const XpbdSolver& S, const StepTape& tape, const SimParams& p, Adjoints& a, RowMatX3d& vbar) {
  const ClothModel& m = S.model();
  const int nv = m.num_vertices;
  const double dt = p.dt, decay = std::exp(-p.damping * p.dt);
  RowMatX3d xprev_bar = RowMatX3d::Zero(nv, 3);
  for (int i = 0; i < nv; ++i) {
    if (m.inv_mass[i] == 0.0) continue;  // pinned: v = 0, no dependence
    a.x.row(i) += vbar.row(i) / dt;
    xprev_bar.row(i) -= vbar.row(i) / dt;
  }
  a.lam_tri = RowMatX3d::Zero(m.faces.rows(), 3);
  a.lam_hinge = VecXd::Zero(m.hinges.rows());
  a.lam_seam = RowMatX3d::Zero(m.seams.rows(), 3);
  a.lam_contact = VecXd::Zero(tape.contacts.size());
  const int per_sweep = static_cast<int>(m.tri_colors.size() + m.hinge_colors.size() + m.seam_colors.size()) + 1;
  if (static_cast<int>(tape.x_before.size()) != per_sweep * p.iterations)
    throw std::logic_error("trajectory adjoint: tape does not match the sweep structure");
  const std::vector<int> none;
  for (int it = p.iterations - 1; it >= 0; --it) {
    int pass = (it + 1) * per_sweep - 1;
    reverse_pass(S, tape, pass--, 3, none, dt, a);
    for (int k = static_cast<int>(m.seam_colors.size()) - 1; k >= 0; --k)
      reverse_pass(S, tape, pass--, 2, m.seam_colors[k], dt, a);
    for (int k = static_cast<int>(m.hinge_colors.size()) - 1; k >= 0; --k)
      reverse_pass(S, tape, pass--, 1, m.hinge_colors[k], dt, a);
    for (int k = static_cast<int>(m.tri_colors.size()) - 1; k >= 0; --k)
      reverse_pass(S, tape, pass--, 0, m.tri_colors[k], dt, a);
  }
  // Prediction: x̃ = x + dt (decay v + dt g) for free vertices; pinned stay.
  RowMatX3d vb = RowMatX3d::Zero(nv, 3);
  for (int i = 0; i < nv; ++i)
    if (m.inv_mass[i] != 0.0) vb.row(i) = decay * dt * a.x.row(i);
  a.x += xprev_bar;
  vbar = vb;
}

double mb(const RowMatX3d& a) { return a.size() * 8.0 / 1048576.0; }

}  // namespace

TrajectoryGradient trajectory_adjoint(XpbdSolver& S, const ClothState& start, const SimParams& p, int steps,
                                      const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int k, RunControl& rc) {
  auto t0 = std::chrono::steady_clock::now();
  const ClothModel& m = S.model();
  if (steps < 1 || k < 1) throw std::invalid_argument("trajectory adjoint: steps and checkpoint_every must be >= 1");
  if (dphi_dx.rows() != m.num_vertices || dphi_dv.rows() != m.num_vertices)
    throw std::invalid_argument("trajectory adjoint: dphi_dx and dphi_dv must be #V×3");
  // Forward with checkpoints.
  std::vector<ClothState> ckpt;
  ClothState s = start;
  for (int t = 0; t < steps; ++t) {
    rc.check("trajectory adjoint (forward)");
    if (t % k == 0) ckpt.push_back(s);
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
  double peak = 0.0, base = ckpt.size() * 2 * mb(start.x);
  for (int seg = static_cast<int>(ckpt.size()) - 1; seg >= 0; --seg) {
    int t_begin = seg * k, t_end = std::min(steps, t_begin + k);
    std::vector<ClothState> starts;
    ClothState r = ckpt[seg];
    for (int t = t_begin; t < t_end; ++t) {
      starts.push_back(r);
      if (t + 1 < t_end) S.step(r, p);
    }
    for (int t = t_end - 1; t >= t_begin; --t) {
      rc.check("trajectory adjoint (backward)");
      StepTape tape;
      ClothState q = starts[t - t_begin];
      S.step(q, p, &tape);
      double tape_mb = 0.0;
      for (const auto& xb : tape.x_before) tape_mb += mb(xb);
      peak = std::max(peak, base + starts.size() * 2 * mb(start.x) + tape_mb);
      reverse_step(S, tape, p, a, vbar);
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
