// Unit vertex normals of a triangle mesh, area-weighted: N_i = S_i/|S_i| with
// S_i = Σ_{f∋i} (b_f − a_f) × (c_f − a_f) (twice the face's area times its unit normal), and their
// vector–Jacobian product. The body's smooth contact normal (sim/contact_kernel.hpp) interpolates
// them; the VJP carries contact gradients to the body vertices (adjoints, body fitting).
#pragma once
#include "common/types.hpp"

namespace diffavatar {

/// (#V×3) unit normals of V (#V×3, m) with faces F; a vertex in no face (or with S_i = 0) gets 0.
RowMatX3d vertex_normals(const RowMatX3d& V, const RowMatX3i& F);

/// Σ_i gN_i·∂N_i/∂V (#V×3): the gradient w.r.t. V of a function whose gradient w.r.t. the
/// normals is gN (#V×3).
RowMatX3d vertex_normals_vjp(const RowMatX3d& V, const RowMatX3i& F, const RowMatX3d& gN);

}  // namespace diffavatar
