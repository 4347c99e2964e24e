// XPBD cloth solver (paper §3.2, Eq. 1–2; Macklin et al. 2016) over a Model, a Control and a
// State kept apart (cloth_model.hpp, cloth_control.hpp, cloth_state.hpp), plus the
// quasi-static drape of the paper: XPBD dynamics until the garment settles, then Newton
// refinement of the same energy (cloth_energy.hpp) to the exact equilibrium that the
// equilibrium adjoint differentiates. A sweep projects the constraints in the order of a
// SweepPlan (sweep_plan.hpp): colour by colour on small models, lane-parallel with three barriers
// per sweep on large ones; either way the result does not depend on the thread count.
// Units: m, kg, s.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "common/run_control.hpp"
#include "sim/body_collider.hpp"
#include "sim/cloth_energy.hpp"
#include "sim/cloth_control.hpp"
#include "sim/cloth_model.hpp"
#include "sim/cloth_state.hpp"
#include "sim/fast_sweep.hpp"
#include "sim/newton_system.hpp"
#include "sim/sweep_plan.hpp"
#include "sim/sweep_tape.hpp"

namespace diffavatar {

struct SimParams {
  double dt = 1.0 / 120.0;             // s
  int iterations = 100;                // constraint sweeps per step (Gauss–Seidel is soft below ~50)
  Vec3 gravity = Vec3(0.0, -9.81, 0.0);  // m/s²
  double damping = 4.0;                // 1/s, v ← v·exp(−damping·dt)
  double contact_radius = 0.01;        // m beyond the thickness within which contacts are detected
  double max_speed = 50.0;             // m/s; above (or non-finite) the step is declared diverged
  bool fast = false;  // single-precision SIMD sweeps (sim/fast_sweep.hpp): drapes only, never with a tape
  double friction = 0.0;  // Coulomb μ of cloth on body (sim/friction_kernel.hpp): forward only, never with a tape
};

struct DrapeParams {
  int max_steps = 2000;
  int min_steps = 20;
  int substeps = 1;            // XPBD steps of dt/substeps (iterations/substeps sweeps) per step of dt
  double speed_tol = 2e-3;     // m/s: XPBD phase has settled when every vertex is slower
  bool refine = true;          // Newton refinement to the exact equilibrium afterwards
  double residual_tol = 1e-5;  // max |net force| / mean vertex weight (dimensionless)
  double anchor_stiffness = 1.0;  // κ (1/s²) of the static-friction proxy (cloth_energy.hpp)
  int refine_iterations = 200;  // Newton steps at most (buckled drapes converge linearly for a while: the 2.5 cm t-shirt needed 65)
};

/// What the trajectory adjoint needs to reverse one step: every sweep's projection records
/// (sim/sweep_tape.hpp) and the step's contacts. O(iterations × projections)
/// doubles: about 100 MB per step on a 10k-vertex garment at 20 sweeps; one step's tape is alive
/// at a time, and step() reuses its buffers.
struct StepTape {
  std::vector<SweepTape> sweeps;
  std::vector<Contact> contacts;
  double mb() const;
};

struct DrapeReport {
  bool converged = false;   // residual ≤ residual_tol at the end (and not diverged)
  bool settled = false;     // XPBD phase reached speed_tol within the step budget
  bool diverged = false;    // a step produced non-finite or absurd velocities (state restored)
  int steps = 0;
  int refine_iterations = 0;
  double max_speed = 0.0;        // m/s at the end of the XPBD phase
  double residual = 0.0;         // dimensionless force residual at the end
  double max_penetration = 0.0;  // m below the body surface
  double wall_s = 0.0;
  std::string message;
};

class XpbdSolver {
 public:
  XpbdSolver(ClothModel model, ClothControl control);
  /// An independent solver of this one's model and control with a copy of its body collider
  /// (BodyCollider::clone: the same contacts as this one's from any state) and its query-cache
  /// setting; not copied: the sweep plan (the default's), the contact set and anchors held
  /// between calls, the caches (rebuilt on use).
  XpbdSolver clone() const;
  const ClothModel& model() const { return model_; }
  const ClothControl& control() const { return control_; }
  const RestCache& cache() const { return cache_; }
  /// Replaces the control (validated); refits the body collider to the new body vertices.
  void set_control(ClothControl control);
  /// A state at rest at positions x (m): v = 0, λ = 0.
  ClothState make_state(const RowMatX3d& x) const;
  /// One XPBD step of length p.dt. Returns the max vertex speed (m/s) after the step. With
  /// `contacts`, they are used instead of detecting them (the trajectory adjoint's replay passes
  /// those the same step detected in its first run: identical by construction).
  double step(ClothState& s, const SimParams& p, StepTape* tape = nullptr,
              const std::vector<Contact>* contacts = nullptr);
  /// One projection sweep over all constraints (the benchmark's unit of work), in plan order;
  /// with a tape, every projection's inputs are recorded in it (sim/sweep_tape.hpp).
  void sweep(ClothState& s, double dt, SweepTape* tape = nullptr);
  /// Rebuilds the sweep plan (the order of the projections, hence the trajectory's round-off).
  void set_sweep_plan(const SweepPlanParams& p);
  const SweepPlan& sweep_plan() const { return plan_; }
  const SweepTapeLayout& tape_layout() const { return layout_; }
  /// Changes whenever the control or the sweep plan does (unique across solvers): what a
  /// recorded trajectory (adjoint/trajectory_adjoint.hpp) was computed with.
  std::uint64_t revision() const { return revision_; }
  DrapeReport drape(ClothState& s, const SimParams& p, const DrapeParams& d, RunControl& rc);
  /// Newton refinement of s.x to ∇ₓE = 0; returns iterations used; sets residual. The anchors
  /// of the friction proxy are set to s.x unless keep_anchor (then the stored ones are reused).
  /// keep_contacts skips the contact detection (the last contact set is used).
  int refine(ClothState& s, const SimParams& p, const DrapeParams& d, RunControl& rc, double* residual,
             bool keep_anchor = false, bool keep_contacts = false);
  /// ∇ₓ²E (J/m²) at x (m) over the free DOFs with the held contacts and anchors, assembled as
  /// refine() assembles its Newton steps (NewtonSystem: in place on the cached pattern) — equal to
  /// energy_hessian(energy_context(gravity), x, free_dofs(), project_psd) bit for bit.
  Eigen::SparseMatrix<double> newton_hessian(const RowMatX3d& x, const Vec3& gravity, bool project_psd);
  const RowMatX3d& anchor() const { return anchor_; }
  /// Sets the anchors a (#V×3, m) that the next refine(keep_anchor = true) ties the cloth to —
  /// e.g. a target shape for a guided equilibrium (pipeline/guided_drape.py).
  void set_anchor(const RowMatX3d& a);
  double anchor_stiffness() const { return anchor_k_; }
  EnergyContext energy_context(const Vec3& gravity) const;
  /// Force residual max_i |∇ᵢE| / (mean m |g|) over free vertices, with current contacts.
  double residual(const RowMatX3d& x, const Vec3& gravity) const;
  /// The same from an energy gradient G (#V×3, N) already evaluated.
  double force_residual(const RowMatX3d& G, const Vec3& gravity) const;
  double max_penetration(const RowMatX3d& x) const { return collider_.max_penetration(x); }
  /// The contact set the quasi-static solves hold (refine, residual, the equilibrium adjoint):
  /// with ClothModel::valley_contact, both planes over a concave body edge (BodyCollider::detect valleys).
  void detect_contacts(const RowMatX3d& x, const SimParams& p);
  const std::vector<Contact>& contacts() const { return contacts_; }
  std::vector<int> free_dofs() const;
  /// Whether step() detects through its ContactQueryCache (default) — the same contacts either
  /// way (sim/contact_query_cache.hpp); off for the test and the benchmark's reference.
  void set_use_query_cache(bool on) { use_query_cache_ = on; }
  bool use_query_cache() const { return use_query_cache_; }
  /// refine()'s LDLᵀ: linalg/supernodal_ldlt.hpp when on, Eigen's SimplicialLDLT otherwise.
  void set_supernodal_newton(bool on) { newton_.set_supernodal(on); }
  bool supernodal_newton() const { return newton_.supernodal(); }
  /// The projected Hessian's hinge blocks clamped to their non-negative eigenvalues (the Newton
  /// of stops 31–58: bench/newton.py's reference) instead of their Gauss–Newton parts.
  void set_hinge_clamp(bool on) { hinge_clamp_ = on; }
  bool hinge_clamp() const { return hinge_clamp_; }
  const ContactQueryCache& query_cache() const { return query_cache_; }

 private:
  /// Projects constraint c; `rec` (or null) receives its record (sim/sweep_tape.hpp).
  void project(ConstraintKind kind, int c, RowMatX3d& x, ClothState& s, double dt2, double* rec) const;
  ClothModel model_;
  ClothControl control_;
  RestCache cache_;
  SweepPlan plan_;
  SweepTapeLayout layout_;
  BodyCollider collider_;
  ContactQueryCache query_cache_;  // step()'s detections on the current body pose
  bool use_query_cache_ = true;
  bool hinge_clamp_ = false;
  std::vector<Contact> contacts_;
  std::vector<ContactFrame> frames_;  // of contacts_, on control_'s body
  void set_contacts(std::vector<Contact> contacts);
  RowMatX3d anchor_;
  double anchor_k_ = 0.0;
  std::uint64_t revision_ = 0;
  FastSweep fast_;  // packed for revision fast_.revision
  NewtonSystem newton_;  // refine()'s Hessian pattern and symbolic factorization
  void bump_revision();
};

}  // namespace diffavatar
