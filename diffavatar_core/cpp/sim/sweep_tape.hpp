// The record of one XPBD sweep that its reverse needs (trajectory adjoint, issue 4; DiffXPBD,
// supplement Eq. 1–4): for every projection, in the sweep plan's order, the inputs it read —
// the positions of its vertices just before it (m), for a hinge the angle θ it measured (rad),
// and its multipliers λ before it. The backward pass then reverses a sweep without replaying it,
// reading its records sequentially. Each block of the plan owns a contiguous range
// (SweepTapeLayout), so the lanes of the lane plan write disjoint parts concurrently. Every
// constraint is projected once per sweep, so its "position" (its rank among the constraints of
// its kind in plan order) is the same in every sweep; the adjoint keeps its per-constraint data
// by position too, which makes its memory access sequential.
#pragma once
#include <cstddef>
#include <vector>

#include "sim/sweep_plan.hpp"

namespace diffavatar {

/// Doubles per projection record: stretch 3 corners × 3 + λ (3); hinge 4 vertices × 3 + θ + λ;
/// seam 2 × 3 + λ (3). A contact's record is its vertex (3) + λ.
inline int record_stride(ConstraintKind k) {
  return k == ConstraintKind::kStretch ? 12 : (k == ConstraintKind::kBending ? 14 : 9);
}
constexpr int kContactRecord = 4;

/// Where each block's records start in SweepTape::rec, and its first position.
struct SweepTapeLayout {
  std::vector<std::vector<std::size_t>> lane;  // [lane][block]: offset in rec (doubles)
  std::vector<std::size_t> interface;          // [block]
  std::vector<std::vector<int>> lane_first;    // [lane][block]: position of its first constraint
  std::vector<int> interface_first;            // [block]
  int count[3] = {0, 0, 0};                    // positions per kind (= constraints of that kind)
  std::size_t size = 0;                        // doubles per sweep
};

inline SweepTapeLayout sweep_tape_layout(const SweepPlan& plan) {
  SweepTapeLayout L;
  auto place = [&](const SweepBlock& b, std::vector<std::size_t>& off, std::vector<int>& first) {
    off.push_back(L.size);
    first.push_back(L.count[static_cast<int>(b.kind)]);
    L.size += b.idx.size() * static_cast<std::size_t>(record_stride(b.kind));
    L.count[static_cast<int>(b.kind)] += static_cast<int>(b.idx.size());
  };
  L.lane.resize(plan.lanes.size());
  L.lane_first.resize(plan.lanes.size());
  for (std::size_t l = 0; l < plan.lanes.size(); ++l)
    for (const SweepBlock& b : plan.lanes[l]) place(b, L.lane[l], L.lane_first[l]);
  for (const SweepBlock& b : plan.interface) place(b, L.interface, L.interface_first);
  return L;
}

struct SweepTape {
  std::vector<double> rec;      // SweepTapeLayout::size doubles; a skipped hinge (k w ≤ 0) leaves its record unused
  std::vector<double> contact;  // kContactRecord doubles per contact
  double mb() const { return (rec.size() + contact.size()) * 8.0 / 1048576.0; }
};

}  // namespace diffavatar
