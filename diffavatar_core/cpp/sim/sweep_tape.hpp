// The record of one XPBD sweep that its reverse needs (trajectory adjoint, issue 4; DiffXPBD,
// supplement Eq. 1–4): for every projection, in the sweep plan's order, the inputs it read —
// the positions of its vertices just before it (m) and, for a hinge, the angle θ it measured
// (rad). The backward pass then reverses a sweep without replaying it, reading its records
// sequentially. Each block of the plan owns a contiguous range (SweepTapeLayout), so the lanes
// of the lane plan write disjoint parts concurrently. Multipliers are not recorded here: every
// constraint is projected once per sweep, so they are those at the sweep's start (StepTape).
#pragma once
#include <cstddef>
#include <vector>

#include "sim/sweep_plan.hpp"

namespace diffavatar {

/// Doubles per projection record: stretch 3 corners × 3; hinge 4 vertices × 3 + θ; seam 2 × 3.
inline int record_stride(ConstraintKind k) {
  return k == ConstraintKind::kStretch ? 9 : (k == ConstraintKind::kBending ? 13 : 6);
}

/// Where each block's records start in SweepTape::rec.
struct SweepTapeLayout {
  std::vector<std::vector<std::size_t>> lane;  // [lane][block]
  std::vector<std::size_t> interface;          // [block]
  std::size_t size = 0;                        // doubles per sweep
};

inline SweepTapeLayout sweep_tape_layout(const SweepPlan& plan) {
  SweepTapeLayout L;
  auto place = [&](const SweepBlock& b) {
    std::size_t at = L.size;
    L.size += b.idx.size() * static_cast<std::size_t>(record_stride(b.kind));
    return at;
  };
  L.lane.resize(plan.lanes.size());
  for (std::size_t l = 0; l < plan.lanes.size(); ++l)
    for (const SweepBlock& b : plan.lanes[l]) L.lane[l].push_back(place(b));
  for (const SweepBlock& b : plan.interface) L.interface.push_back(place(b));
  return L;
}

struct SweepTape {
  std::vector<double> rec;      // SweepTapeLayout::size doubles; a skipped hinge (k w ≤ 0) leaves its record unused
  std::vector<double> contact;  // per contact, the vertex position before its projection (m), 3 doubles
  double mb() const { return (rec.size() + contact.size()) * 8.0 / 1048576.0; }
};

}  // namespace diffavatar
