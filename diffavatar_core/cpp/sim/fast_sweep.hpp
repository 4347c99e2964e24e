// The drape's fast sweep: the XPBD projections of one step (paper §3.2, Eq. 1–2) in single
// precision, vectorised across the constraints of a colour. Same constraints, same order of
// colours and the same lane/interface/contact phases as XpbdSolver::sweep (sim/sweep_plan.hpp),
// but every block of a colour runs as one SIMD loop (its constraints share no vertex), on a
// float copy of the positions, with the rest data (D̄⁻¹, Ā, hinge weights, compliances) packed
// per block in structure-of-arrays form. Kernels are those of stretch_kernel.hpp (the 3×3 block
// from three weighted sums of the grain-frame coefficients), bending_kernel.hpp (a polynomial
// atan2, |error| ≤ 2e-8 rad before float round-off), seam_kernel.hpp and contact_kernel.hpp.
//
// Only for the drape's dynamic phase, never for what is differentiated: no tape, round-off of
// float (positions ~6e-8 m at 1 m), and the multipliers live here (the state's stay zero). The
// Newton refinement that follows works in double. The result does not depend on the thread count
// (lanes and contact chunks touch disjoint vertices); it may differ in the last bits between CPUs:
// the loops are compiled for AVX-512, AVX2 and baseline x86-64 and the CPU's features pick one.
#pragma once
#include <cstdint>
#include <vector>

#include "common/types.hpp"
#include "sim/body_collider.hpp"
#include "sim/cloth_control.hpp"
#include "sim/sweep_plan.hpp"

namespace diffavatar {

class FastSweep {
 public:
  /// Packs the plan's blocks with the control's rest data (nothing position-dependent).
  void build(const ClothModel& m, const ClothControl& c, const RestCache& cache, const SweepPlan& plan);
  /// `sweeps` sweeps of a step of length dt (s) on x (#V×3, m; written back at the end) with
  /// this step's contacts and their planes (contact_kernel.hpp). Multipliers start at zero, as
  /// every step's do.
  void run(RowMatX3d& x, int sweeps, double dt, const std::vector<Contact>& contacts,
           const std::vector<ContactFrame>& frames, double thickness, double contact_stiffness, double seam_compliance);
  /// The last run's contact multipliers λ (one per contact, in its order): the contact moved
  /// its vertex by w λ (m) along the normal.
  const std::vector<float>& contact_lambda() const { return cl_; }
  std::uint64_t revision = 0;  // the solver revision (control + plan) it was built for

  /// Packed constraints of one kind: vertex indices and float fields, one entry per constraint in
  /// plan order (a kind fills only the index columns and fields it has: 3/4/2 vertices).
  struct Pack {
    std::vector<std::int32_t> v[4];
    std::vector<float> f[13];
    std::vector<float> lambda[3];
    int size() const { return static_cast<int>(v[0].size()); }
  };
  struct Range {
    ConstraintKind kind;
    int begin, end;
  };

 private:
  void run_range(const Range& r, float inv_dt2, float seam_alpha);
  Pack stretch_, bend_, seam_;
  std::vector<std::vector<Range>> lanes_;
  std::vector<Range> interface_;
  std::vector<float> X_, X0_;          // positions (3 per vertex) and their value at the start
  std::vector<float> w_;               // inverse masses (1/kg)
  // this step's contacts: vertex, n (3), offset n·b0 + h, multiplier
  std::vector<std::int32_t> cv_;
  std::vector<float> cn_[3], cd_, cl_;
};

}  // namespace diffavatar
