// State = what a step advances: positions x (#V×3, m), velocities v (#V×3, m/s) and the
// XPBD multipliers λ of the last step (tri #F×3, hinge #H, seam #S×3, contact per vertex).
#pragma once
#include "common/types.hpp"

namespace diffavatar {

struct ClothState {
  RowMatX3d x;
  RowMatX3d v;
  RowMatX3d lambda_tri;
  VecXd lambda_hinge;
  RowMatX3d lambda_seam;
  VecXd lambda_contact;
};

}  // namespace diffavatar
