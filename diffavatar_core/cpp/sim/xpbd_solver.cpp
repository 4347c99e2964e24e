#include "sim/xpbd_solver.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

#include "common/stream_store.hpp"
#include "sim/bending_kernel.hpp"
#include "sim/cloth_energy.hpp"
#include "sim/contact_kernel.hpp"
#include "sim/friction_kernel.hpp"
#include "sim/seam_kernel.hpp"
#include "sim/stretch_kernel.hpp"

namespace diffavatar {

// Below this many constraints in a colour the sweep runs serially: an OpenMP fork/join costs
// more than the work, and far more on an oversubscribed machine.
constexpr int kParallelMin = 1024;

XpbdSolver::XpbdSolver(ClothModel model, ClothControl control) : model_(std::move(model)) {
  plan_ = build_sweep_plan(model_, SweepPlanParams());
  layout_ = sweep_tape_layout(plan_);
  collider_ = BodyCollider(control.body_vertices, model_.body_faces, model_.valley_contact);
  set_control(std::move(control));
}

XpbdSolver XpbdSolver::clone() const {
  XpbdSolver c(model_, control_);
  c.collider_ = collider_.clone();
  c.use_query_cache_ = use_query_cache_;
  c.newton_.set_supernodal(newton_.supernodal());
  c.hinge_clamp_ = hinge_clamp_;
  return c;
}

void XpbdSolver::set_control(ClothControl control) {
  cache_ = prepare_control(model_, control);  // validates the rest shape before any mass uses it
  if (model_.masses_follow_rest) set_lumped_masses(model_, control.rest);
  control_ = std::move(control);
  collider_.set_vertices(control_.body_vertices);
  query_cache_.clear();  // its distance bounds were for the previous pose
  // Held contacts follow the body: a smooth contact's barycentrics (its detection point's closest
  // point in its region) and every contact's plane.
  if (model_.smooth_contact)
    for (Contact& c : contacts_) update_barycentrics(c, control_.body_vertices, model_.body_faces);
  set_contacts(std::move(contacts_));
  bump_revision();
}

void XpbdSolver::bump_revision() {
  static std::atomic<std::uint64_t> next{1};
  revision_ = next.fetch_add(1);
}

ClothState XpbdSolver::make_state(const RowMatX3d& x) const {
  if (x.rows() != model_.num_vertices) throw std::invalid_argument("state: x must be #V×3");
  ClothState s;
  s.x = x;
  s.v = RowMatX3d::Zero(x.rows(), 3);
  s.lambda_tri = RowMatX3d::Zero(model_.faces.rows(), 3);
  s.lambda_hinge = VecXd::Zero(model_.hinges.rows());
  s.lambda_seam = RowMatX3d::Zero(model_.seams.rows(), 3);
  s.lambda_contact = VecXd::Zero(0);
  return s;
}

void XpbdSolver::set_contacts(std::vector<Contact> contacts) {
  contacts_ = std::move(contacts);
  frames_.resize(contacts_.size());
  for (std::size_t j = 0; j < contacts_.size(); ++j)
    frames_[j] = contact_frame(model_.smooth_contact, contacts_[j], control_.body_vertices, cache_.body_normals,
                               model_.body_faces);
}

void XpbdSolver::detect_contacts(const RowMatX3d& x, const SimParams& p) {
  // with valley_contact the quasi-static solves hold both planes over a concave body edge (BodyCollider::detect)
  set_contacts(collider_.detect(x, model_.inv_mass, model_.thickness + p.contact_radius, model_.valley_contact));
}

void XpbdSolver::set_sweep_plan(const SweepPlanParams& p) {
  if (p.min_constraints < 0) throw std::invalid_argument("sweep plan: min_constraints must be >= 0");
  plan_ = build_sweep_plan(model_, p);
  layout_ = sweep_tape_layout(plan_);
  bump_revision();
}

// Projects constraint c of `kind` (Eq. 1–2): reads and writes only its own vertices' rows of x
// and its own multipliers.
void XpbdSolver::project(ConstraintKind kind, int c, RowMatX3d& x, ClothState& s, double dt2, double* rec) const {
  const ClothModel& m = model_;
  if (kind == ConstraintKind::kStretch) {
    Vec3 p[3];
    Vec3* pp[3];
    double w[3];
    for (int k = 0; k < 3; ++k) {
      int i = m.faces(c, k);
      p[k] = x.row(i).transpose();
      pp[k] = &p[k];
      w[k] = m.inv_mass[i];
    }
    if (rec) {
      double r[12];
      for (int k = 0; k < 3; ++k) Eigen::Map<Vec3>(r + 3 * k) = p[k];
      for (int a = 0; a < 3; ++a) r[9 + a] = s.lambda_tri(c, a);
      stream_store(rec, r, 12);
    }
    Vec3 at = control_.stretch_compliance.row(m.tri_group[c]).transpose() / (cache_.tri[c].area * dt2);
    project_stretch(pp, w, cache_.tri[c], at, &s.lambda_tri(c, 0));
    for (int k = 0; k < 3; ++k) x.row(m.faces(c, k)) = p[k].transpose();
  } else if (kind == ConstraintKind::kBending) {
    double kw = control_.bend_stiffness[m.hinge_group[c]] * cache_.hinge_weight[c];
    if (!(kw > 0.0)) return;
    Vec3 p[4];
    Vec3* pp[4];
    double w[4];
    for (int q = 0; q < 4; ++q) {
      int i = m.hinges(c, q);
      p[q] = x.row(i).transpose();
      pp[q] = &p[q];
      w[q] = m.inv_mass[i];
    }
    double r[14];
    if (rec) {
      for (int q = 0; q < 4; ++q) Eigen::Map<Vec3>(r + 3 * q) = p[q];
      r[12] = 0.0;  // θ, set by the projection unless the hinge is degenerate (then the reverse skips it)
      r[13] = s.lambda_hinge[c];
    }
    project_bending(pp, w, m.hinge_rest_angle[c], 1.0 / (kw * dt2), &s.lambda_hinge[c], rec ? r + 12 : nullptr);
    if (rec) stream_store(rec, r, 14);
    for (int q = 0; q < 4; ++q) x.row(m.hinges(c, q)) = p[q].transpose();
  } else {
    int a = m.seams(c, 0), b = m.seams(c, 1);
    Vec3 xa = x.row(a).transpose(), xb = x.row(b).transpose();
    if (rec) {
      double r[9];
      Eigen::Map<Vec3>{r} = xa;
      Eigen::Map<Vec3>(r + 3) = xb;
      for (int a3 = 0; a3 < 3; ++a3) r[6 + a3] = s.lambda_seam(c, a3);
      stream_store(rec, r, 9);
    }
    project_seam(xa, xb, m.inv_mass[a], m.inv_mass[b], m.seam_compliance / dt2, &s.lambda_seam(c, 0));
    x.row(a) = xa.transpose();
    x.row(b) = xb.transpose();
  }
}

void XpbdSolver::sweep(ClothState& s, double dt, SweepTape* tape) {
  const ClothModel& m = model_;
  const double dt2 = dt * dt;
  RowMatX3d& x = s.x;
  const int nc = static_cast<int>(contacts_.size());
  if (tape) {
    tape->rec.resize(layout_.size);  // reused across sweeps and steps: no reallocation
    tape->contact.resize(kContactRecord * static_cast<std::size_t>(nc));
  }
  // Record pointer of a block's j-th projection, or null without a tape.
  auto rec = [&](std::size_t off, const SweepBlock& b, int j) -> double* {
    return tape ? tape->rec.data() + off + static_cast<std::size_t>(j) * record_stride(b.kind) : nullptr;
  };
  if (s.lambda_contact.size() != nc) s.lambda_contact = VecXd::Zero(nc);
  const double ac = 1.0 / (m.contact_stiffness * dt2);
  auto contact = [&](int j) {
    const Contact& ct = contacts_[j];
    Vec3 pi = x.row(ct.vertex).transpose();
    if (tape) {
      Eigen::Map<Vec3>(tape->contact.data() + kContactRecord * j) = pi;
      tape->contact[kContactRecord * j + 3] = s.lambda_contact[j];
    }
    project_contact(pi, m.inv_mass[ct.vertex], frames_[j].n, frames_[j].q, m.thickness, ac, &s.lambda_contact[j]);
    x.row(ct.vertex) = pi.transpose();
  };
  if (!plan_.lane_parallel()) {
    // Colour plan: one fork/join per colour large enough to pay for it.
    const auto& blocks = plan_.lanes[0];
    for (std::size_t k = 0; k < blocks.size(); ++k) {
      const SweepBlock& b = blocks[k];
      const std::size_t off = layout_.lane[0][k];
      const int n = static_cast<int>(b.idx.size());
#pragma omp parallel if (n >= kParallelMin)
      {
#pragma omp for schedule(static)
        for (int j = 0; j < n; ++j) project(b.kind, b.idx[j], x, s, dt2, rec(off, b, j));
        if (tape) stream_fence();  // the records' streaming stores, before the region's barrier
      }
    }
#pragma omp parallel for schedule(static) if (nc >= kParallelMin)
    for (int j = 0; j < nc; ++j) contact(j);
    return;
  }
  // Lane plan: one parallel region per sweep and a barrier after each of its three phases.
  const int nl = static_cast<int>(plan_.lanes.size());
#pragma omp parallel
  {
#pragma omp for schedule(static)
    for (int l = 0; l < nl; ++l) {
      const auto& blocks = plan_.lanes[l];
      for (std::size_t k = 0; k < blocks.size(); ++k) {
        const SweepBlock& b = blocks[k];
        const std::size_t off = layout_.lane[l][k];
        const int n = static_cast<int>(b.idx.size());
        for (int j = 0; j < n; ++j) project(b.kind, b.idx[j], x, s, dt2, rec(off, b, j));
      }
    }
#pragma omp single
    {
      for (std::size_t k = 0; k < plan_.interface.size(); ++k) {
        const SweepBlock& b = plan_.interface[k];
        const std::size_t off = layout_.interface[k];
        const int n = static_cast<int>(b.idx.size());
        for (int j = 0; j < n; ++j) project(b.kind, b.idx[j], x, s, dt2, rec(off, b, j));
      }
    }
#pragma omp for schedule(static)
    for (int j = 0; j < nc; ++j) contact(j);
    if (tape) stream_fence();  // the records' streaming stores, before the region's barrier
  }
}

double StepTape::mb() const {
  double d = 0.0;
  for (const auto& sw : sweeps) d += sw.mb();
  return d;
}

double XpbdSolver::step(ClothState& s, const SimParams& p, StepTape* tape, const std::vector<Contact>* contacts) {
  const ClothModel& m = model_;
  const int nv = m.num_vertices;
  if (tape && p.friction != 0.0)
    throw std::invalid_argument("XPBD step: friction is not differentiated; record a trajectory with friction = 0");
  if (!(p.friction >= 0.0) || !std::isfinite(p.friction))
    throw std::invalid_argument("XPBD step: friction must be a finite coefficient >= 0");
  RowMatX3d x_prev = s.x;
  const double decay = std::exp(-p.damping * p.dt);
  double vpred = 0.0;
  for (int i = 0; i < nv; ++i) {
    if (m.inv_mass[i] == 0.0) continue;
    s.v.row(i) = s.v.row(i) * decay + p.dt * p.gravity.transpose();
    s.x.row(i) += p.dt * s.v.row(i);
    vpred = std::max(vpred, s.v.row(i).norm());
  }
  // Contacts of the predicted positions; the search radius grows with the step's travel so a
  // fast vertex cannot tunnel through the collision layer between detections.
  if (contacts)
    set_contacts(*contacts);
  else
    set_contacts(collider_.detect(s.x, m.inv_mass, m.thickness + p.contact_radius + std::min(vpred * p.dt, 0.1),
                                  false, use_query_cache_ ? &query_cache_ : nullptr));
  s.lambda_tri.setZero();
  s.lambda_hinge.setZero();
  s.lambda_seam.setZero();
  s.lambda_contact = VecXd::Zero(contacts_.size());
  if (tape) tape->contacts = contacts_;
  if (tape) tape->sweeps.resize(p.iterations);
  if (p.fast && !tape) {
    if (fast_.revision != revision_) {
      fast_.build(model_, control_, cache_, plan_);
      fast_.revision = revision_;
    }
    fast_.run(s.x, p.iterations, p.dt, contacts_, frames_, m.thickness, m.contact_stiffness, m.seam_compliance);
  } else {
    for (int it = 0; it < p.iterations; ++it) sweep(s, p.dt, tape ? &tape->sweeps[it] : nullptr);
  }
  if (p.friction > 0.0) {
    const int nc = static_cast<int>(contacts_.size());
    const bool fl = p.fast && !tape;
    for (int j = 0; j < nc; ++j) {
      const int i = contacts_[j].vertex;
      const double lam = fl ? static_cast<double>(fast_.contact_lambda()[j]) : s.lambda_contact[j];
      Vec3 xi = s.x.row(i).transpose();
      apply_friction(xi, x_prev.row(i).transpose(), frames_[j].n, m.inv_mass[i] * lam, p.friction);
      s.x.row(i) = xi.transpose();
    }
  }
  double vmax = 0.0;
  for (int i = 0; i < nv; ++i) {
    if (m.inv_mass[i] == 0.0) {
      s.v.row(i).setZero();
      continue;
    }
    s.v.row(i) = (s.x.row(i) - x_prev.row(i)) / p.dt;
    double sp = s.v.row(i).norm();
    if (!(sp <= vmax)) vmax = std::isfinite(sp) ? std::max(vmax, sp) : INFINITY;
  }
  return vmax;
}

std::vector<int> XpbdSolver::free_dofs() const {
  std::vector<int> dof(model_.num_vertices, -1);
  int n = 0;
  for (int i = 0; i < model_.num_vertices; ++i)
    if (model_.inv_mass[i] > 0.0) {
      dof[i] = n;
      n += 3;
    }
  return dof;
}

EnergyContext XpbdSolver::energy_context(const Vec3& gravity) const {
  EnergyContext ctx{model_, control_, cache_, contacts_, frames_, gravity};
  if (anchor_.rows() == model_.num_vertices && anchor_k_ > 0) {
    ctx.anchor = &anchor_;
    ctx.anchor_stiffness = anchor_k_;
  }
  ctx.hinge_clamp = hinge_clamp_;
  return ctx;
}

double XpbdSolver::residual(const RowMatX3d& x, const Vec3& gravity) const {
  return force_residual(energy_gradient(energy_context(gravity), x), gravity);
}

double XpbdSolver::force_residual(const RowMatX3d& G, const Vec3& gravity) const {
  double worst = 0.0, wsum = 0.0;
  int nfree = 0;
  for (int i = 0; i < model_.num_vertices; ++i) {
    if (model_.inv_mass[i] == 0.0) continue;
    worst = std::max(worst, G.row(i).norm());
    wsum += model_.mass[i];
    ++nfree;
  }
  double ref = nfree ? wsum / nfree * std::max(gravity.norm(), 1e-12) : 1.0;
  return worst / ref;
}

void XpbdSolver::set_anchor(const RowMatX3d& a) {
  if (a.rows() != model_.num_vertices) throw std::invalid_argument("anchor: must be #V×3");
  if (!a.allFinite()) throw std::invalid_argument("anchor: non-finite position");
  anchor_ = a;
}

Eigen::SparseMatrix<double> XpbdSolver::newton_hessian(const RowMatX3d& x, const Vec3& gravity, bool project_psd) {
  if (x.rows() != model_.num_vertices) throw std::invalid_argument("newton_hessian: x must be #V×3");
  return newton_.assemble(energy_context(gravity), x, free_dofs(), project_psd);
}

int XpbdSolver::refine(ClothState& s, const SimParams& p, const DrapeParams& d, RunControl& rc, double* res_out,
                       bool keep_anchor, bool keep_contacts) {
  if (!keep_anchor || anchor_.rows() != model_.num_vertices) anchor_ = s.x;
  anchor_k_ = d.anchor_stiffness;
  const std::vector<int> dof = free_dofs();
  int n = 0;
  for (int v : dof) n = std::max(n, v + 3);
  int it = 0;
  double res = INFINITY;
  bool res_stale = true;  // res not yet evaluated at the current s.x
  // Levenberg–Marquardt damping λ·M (λ in 1/s², M the lumped masses): 0 unless a step fails.
  double reg = 0.0;
  // E at s.x once evaluated: the contact set and anchors stay fixed within the call, so the
  // accepted trial's energy is the next iteration's E0 (NaN: not yet known).
  double E_at_x = NAN;
  for (; it < d.refine_iterations; ++it) {
    rc.check("equilibrium refinement");
    // The contact set is detected once and then held fixed, so every line search minimises
    // one energy (re-detection between Newton steps makes the iteration cycle).
    if (it == 0 && !keep_contacts) detect_contacts(s.x, p);
    EnergyContext ctx = energy_context(p.gravity);
    RowMatX3d G = energy_gradient(ctx, s.x);
    res = force_residual(G, p.gravity);
    res_stale = false;
    rc.report({"refine", it, d.refine_iterations, res});
    if (res <= d.residual_tol || n == 0) break;
    VecXd g(n);
    for (int i = 0; i < model_.num_vertices; ++i)
      if (dof[i] >= 0) g.segment<3>(dof[i]) = G.row(i).transpose();
    // Far from equilibrium the element Hessians are made positive semi-definite (triangles
    // clamped, hinges Gauss–Newton: cloth_energy.hpp); close to it the exact Hessian is used
    // (quadratic convergence; compressed triangles and bent hinges make the projected one
    // differ) as long as it yields a descent direction.
    const bool exact = res < 1.0 && reg == 0.0;
    // ∇²E on the mesh's fixed pattern, its symbolic factorization kept across iterations and
    // calls (sim/newton_system.hpp; the same matrix and iterates as energy_hessian's).
    const Eigen::SparseMatrix<double>& H = newton_.assemble(ctx, s.x, dof, !exact);
    VecXd step;
    for (int attempt = 0; attempt < 8; ++attempt) {
      Eigen::SparseMatrix<double> Hr;
      if (reg > 0) {
        Hr = H;
        for (int i = 0; i < model_.num_vertices; ++i)
          if (dof[i] >= 0)
            for (int k = 0; k < 3; ++k) Hr.coeffRef(dof[i] + k, dof[i] + k) += reg * model_.mass[i];
      }
      if (newton_.factorize(reg > 0 ? Hr : H)) {
        step = newton_.solve(-g);
        if (step.allFinite()) break;
      }
      reg = std::max(1e-2, reg * 10.0);
    }
    if (step.size() != n) break;
    if (exact && !(g.dot(step) < 0.0)) {
      reg = 1e-2;  // not a descent direction: fall back to the projected Hessian
      continue;
    }
    // Backtracking line search on E (Armijo) with the contact set held fixed.
    if (std::isnan(E_at_x)) E_at_x = total_energy(ctx, s.x);
    double E0 = E_at_x, E1 = NAN, slope = g.dot(step), a = 1.0;
    RowMatX3d xt = s.x;
    bool ok = false;
    for (int ls = 0; ls < 30; ++ls) {
      for (int i = 0; i < model_.num_vertices; ++i)
        if (dof[i] >= 0) xt.row(i) = s.x.row(i) + a * step.segment<3>(dof[i]).transpose();
      E1 = total_energy(ctx, xt);
      if (std::isfinite(E1) && E1 <= E0 + 1e-4 * a * slope) {
        ok = true;
        break;
      }
      // Near the solution the energy decrease falls below its round-off; then accept the full
      // Newton step when it halves the force residual instead.
      if (ls == 0 && std::isfinite(E1) && std::abs(E1 - E0) <= 1e-12 * (std::abs(E0) + 1e-12) &&
          residual(xt, p.gravity) < 0.5 * res) {
        ok = true;
        break;
      }
      a *= 0.5;
    }
    if (!ok) {
      reg = std::max(reg * 10.0, 1e-2);
      if (reg > 1e8) break;
      continue;
    }
    s.x = xt;
    E_at_x = E1;
    res_stale = true;
    reg = reg * 0.1 < 1e-6 ? 0.0 : reg * 0.1;
  }
  if (res_stale) res = residual(s.x, p.gravity);  // only when the last iteration moved x
  if (res_out) *res_out = res;
  s.v.setZero();
  return it;
}

DrapeReport XpbdSolver::drape(ClothState& s, const SimParams& p, const DrapeParams& d, RunControl& rc) {
  auto t0 = std::chrono::steady_clock::now();
  DrapeReport r;
  RowMatX3d x_good = s.x, v_good = s.v;
  // Small steps (Macklin et al. 2019): `substeps` XPBD steps of dt/substeps with
  // iterations/substeps sweeps each make as many sweeps as one step of dt (plus a contact
  // detection per substep), but the constraint error Gauss–Seidel leaves shrinks with the step,
  // so a fine mesh keeps the material's stiffness (test/sim/test_drape_substeps.py).
  const int sub = std::max(1, d.substeps);
  SimParams ps = p;
  ps.dt = p.dt / sub;
  ps.iterations = std::max(1, (p.iterations + sub - 1) / sub);
  for (r.steps = 0; r.steps < d.max_steps; ++r.steps) {
    rc.check("drape");
    double vmax = 0.0;
    for (int k = 0; k < sub; ++k) {
      vmax = step(s, ps);
      if (!std::isfinite(vmax) || vmax > p.max_speed || !s.x.allFinite()) break;
    }
    if (!std::isfinite(vmax) || vmax > p.max_speed || !s.x.allFinite()) {
      s.x = x_good;
      s.v = v_good;
      r.diverged = true;
      r.message = "diverged at step " + std::to_string(r.steps) + " (max speed " + std::to_string(vmax) +
                  " m/s > " + std::to_string(p.max_speed) + "): time step too large or material too stiff; "
                  "state restored to the last finite step";
      break;
    }
    x_good = s.x;
    v_good = s.v;
    r.max_speed = vmax;
    rc.report({"drape", r.steps, d.max_steps, vmax});
    if (r.steps + 1 >= d.min_steps && vmax < d.speed_tol) {
      r.settled = true;
      ++r.steps;
      break;
    }
  }
  if (!r.diverged && d.refine) {
    RowMatX3d x_before = s.x;
    r.refine_iterations = refine(s, p, d, rc, &r.residual);
    if (!s.x.allFinite()) {
      s.x = x_before;
      detect_contacts(s.x, p);
      r.residual = residual(s.x, p.gravity);
      r.message = "equilibrium refinement produced non-finite positions; XPBD state kept";
    }
  } else {
    detect_contacts(s.x, p);
    r.residual = residual(s.x, p.gravity);
  }
  r.converged = !r.diverged && r.residual <= d.residual_tol;
  if (r.message.empty())
    r.message = r.converged ? "converged" : (r.settled ? "settled but residual above tolerance" : "step budget exhausted");
  r.max_penetration = max_penetration(s.x);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  rc.report({"drape", r.steps, d.max_steps, r.residual}, true);
  return r;
}

}  // namespace diffavatar
