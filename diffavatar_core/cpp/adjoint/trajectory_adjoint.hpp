// Trajectory adjoint (issue 4, mode 1; DiffXPBD, supplement Eq. 1–4): the exact reverse pass of
// `steps` XPBD steps. Each step is replayed forward from its start state while recording the
// positions and multipliers at the start of every sweep (StepTape); then, sweep by sweep from
// the last, the sweep is replayed to recover the positions before each colour pass (SweepTape)
// and every projection is reversed (adjoint/projection_vjp.hpp), colour by colour, the
// constraints of one colour in parallel. Memory is bounded
// by checkpointing: the forward pass keeps the state every `checkpoint_every` steps; the
// backward pass recomputes one segment at a time. Contacts are detected in each replayed step
// exactly as in the forward pass (their selection is not differentiated).
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
  double step_tape_mb = 0;  // the largest one step's tape (sweep starts + one sweep's passes)
  double wall_s = 0;
};

TrajectoryGradient trajectory_adjoint(XpbdSolver& solver, const ClothState& start, const SimParams& p, int steps,
                                      const RowMatX3d& dphi_dx, const RowMatX3d& dphi_dv, int checkpoint_every,
                                      RunControl& rc);

}  // namespace diffavatar
