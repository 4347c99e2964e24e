// Trajectory adjoint (issue 4, mode 1; DiffXPBD, supplement Eq. 1–4): the exact reverse pass of
// `steps` XPBD steps. Each step is replayed forward from its start state while recording every
// projection's inputs (StepTape: per sweep, one record per projection in plan order — the
// positions it read, its multipliers and a hinge's angle; sim/sweep_tape.hpp); then the sweeps
// are reversed from the last, projection by projection (adjoint/projection_vjp.hpp), reading the
// records sequentially, in the sweep plan's blocks (parallel as in the forward sweep). Memory is
// bounded by checkpointing: the forward pass keeps the state every `checkpoint_every` steps; the
// backward pass recomputes one segment at a time and holds one step's tape. Every replayed step
// uses the contacts its first run detected (kept with the checkpoints and segment starts; their
// selection is not differentiated).
#pragma once
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

TrajectoryGradient trajectory_adjoint(XpbdSolver& solver, const ClothState& start, const SimParams& p, int steps,
                                      const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int checkpoint_every,
                                      RunControl& rc);

}  // namespace diffavatar
