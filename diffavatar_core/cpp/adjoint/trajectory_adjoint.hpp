// Trajectory adjoint (issue 4, mode 1; DiffXPBD, supplement Eq. 1–4): the exact reverse pass of
// `steps` XPBD steps. Each step is replayed forward from its start state while recording every
// projection's inputs (StepTape: per sweep, one record per projection in plan order — the
// positions it read, its multipliers and a hinge's angle; sim/sweep_tape.hpp); then the sweeps
// are reversed from the last, projection by projection (adjoint/projection_vjp.hpp), reading the
// records sequentially, in the sweep plan's blocks (parallel as in the forward sweep). Memory is
// bounded by checkpointing: the forward pass keeps the state every `checkpoint_every` steps; the
// backward pass recomputes one segment at a time and holds one step's tape. Every replayed step
// uses the contacts its first run detected (kept with the checkpoints and segment starts; which
// triangle and Voronoi region a vertex touches is not differentiated, the closest point's
// barycentrics within it are: they are a smooth function of the step's predicted position and the
// body, contact_kernel.hpp region_barycentrics).
//
// The two halves can be run apart (trajectory_forward, then trajectory_backward): a loss that is
// not linear in the final state (a Chamfer distance) needs x_T before its gradient ∂φ/∂x_T
// exists, and the recorded forward run is then reused instead of simulated twice.
#pragma once
#include <cstdint>
#include <optional>
#include <vector>

#include "common/run_control.hpp"
#include "sim/cloth_energy.hpp"
#include "sim/xpbd_solver.hpp"

namespace diffavatar {

struct TrajectoryGradient {
  ControlGradient control;  // dφ/d{rest, stretch_compliance, bend_stiffness, body_vertices}
  RowMatX3d x0;             // dφ/dx at the start (per m)
  RowMatX3d v0;             // dφ/dv at the start (per m/s)
  RowMatX3d x_final;        // positions after the steps (m)
  double peak_tape_mb = 0;  // checkpoints + one segment's step starts + one step's tape
  double step_tape_mb = 0;  // the largest one step's tape (multipliers + projection records)
  double wall_s = 0;
};

/// The forward half: every k-th state (positions m, velocities m/s; a step zeroes its
/// multipliers first, so they carry nothing across steps) with the contacts its step detected,
/// and the final state. Valid for the solver revision it was recorded with.
struct TrajectoryCheckpoints {
  struct Entry {
    RowMatX3d x, v;
    std::optional<std::vector<Contact>> contacts;  // those the step from this state detected, once known
  };
  std::vector<Entry> states;
  int steps = 0, every = 1;
  SimParams params;
  std::uint64_t solver_revision = 0;
  RowMatX3d x_final, v_final;
  double mb() const;  // memory of the stored states and contacts
  double wall_s = 0;
};

TrajectoryCheckpoints trajectory_forward(XpbdSolver& solver, const ClothState& start, const SimParams& p, int steps,
                                         int checkpoint_every, RunControl& rc);
/// The backward half over a recorded forward run; throws std::invalid_argument if the solver's
/// control or sweep plan changed since (the replays would then not be the recorded computation).
TrajectoryGradient trajectory_backward(XpbdSolver& solver, const TrajectoryCheckpoints& fw, const RowMatX3d& dphi_dx,
                                       const RowMatX3d& dphi_dv, RunControl& rc);
/// Both halves (the forward's progress counts the first `steps` of 2·steps units).
TrajectoryGradient trajectory_adjoint(XpbdSolver& solver, const ClothState& start, const SimParams& p, int steps,
                                      const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int checkpoint_every,
                                      RunControl& rc);

}  // namespace diffavatar
