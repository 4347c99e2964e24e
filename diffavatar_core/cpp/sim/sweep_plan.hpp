// The order in which one XPBD sweep projects its constraints, shared by the forward sweep
// (xpbd_solver.cpp) and the trajectory adjoint's reverse (trajectory_adjoint.cpp), which must
// walk exactly the same passes backwards.
//
// Colour plan (small models): every colour is one pass; constraints of a colour share no vertex
// and run in parallel, so a sweep costs one fork/join per colour (~30 on a garment).
// Lane plan (large models): the vertices are cut into `lanes` contiguous pieces of their
// numbering (each lane owns a block of rows of the state: no false sharing) or, when that cut is
// much longer, of a breadth-first order of the mesh (one BFS front per cut). A constraint
// whose vertices all lie in one lane belongs to that lane; the few that straddle a cut form the
// interface. A sweep is then three phases with a barrier after each: (1) every lane projects its
// constraints, one thread per lane, colour by colour (its own restriction of the global
// colouring); (2) one thread projects the interface, colour by colour; (3) the contacts, in
// parallel. Lanes touch disjoint vertices, so the result does not depend on the thread count.
// Both plans visit the constraints kind by kind (stretch, bending, seams) within a lane and the
// contacts last; each constraint is projected once per sweep.
#pragma once
#include <string>
#include <vector>

#include "sim/cloth_model.hpp"

namespace diffavatar {

enum class ConstraintKind { kStretch = 0, kBending = 1, kSeam = 2 };

/// One colour's worth of constraints of one kind (no two share a vertex).
struct SweepBlock {
  ConstraintKind kind;
  std::vector<int> idx;
};

struct SweepPlan {
  /// Colour plan: a single lane, blocks = the global colours, interface empty.
  /// Lane plan: ≥ 2 lanes run concurrently, then the interface.
  std::vector<std::vector<SweepBlock>> lanes;
  std::vector<std::vector<int>> lane_vertices;  // vertices each lane moves (disjoint across lanes)
  std::vector<SweepBlock> interface;
  std::vector<int> interface_vertices;
  std::string partition = "colours";  // "colours" (colour plan), "index" or "bfs" (lane plan)
  int interface_constraints = 0;
  int total_constraints = 0;

  bool lane_parallel() const { return lanes.size() > 1; }
};

struct SweepPlanParams {
  int lanes = 2;                   // pieces of the lane plan (≤ 1: always the colour plan)
  int min_constraints = 16384;     // fewer constraints (triangles + hinges + seams): colour plan
};

/// Builds the plan for `m`; deterministic (depends only on the model and the parameters, never
/// on the thread count).
SweepPlan build_sweep_plan(const ClothModel& m, const SweepPlanParams& p);

}  // namespace diffavatar
