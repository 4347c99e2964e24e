// Fabric grain frame (issue 3; paper §3.2 Eq. 1, supplement Eq. 9): the orthotropic StVK
// compliances are per warp / weft / shear, so the Green strain must be expressed in the
// fabric's frame. A triangle with grain angle g (rad, warp direction measured from the pattern
// x axis, counter-clockwise) has its rest corners rotated by −g, ū' = R(−g) ū, before D̄ and
// D̄⁻¹ are formed; then F = D D̄'⁻¹ has its first column along the warp. Rotation is rigid, so
// Ā and every rest length are unchanged, and ∂/∂ū chains through the constant R(−g).
#pragma once
#include <algorithm>
#include <cmath>

namespace diffavatar {

/// cos g, sin g; exact for multiples of π/2 (so quarter turns only permute/negate coordinates)
/// and `identity` for g == 0 (callers then copy, keeping grain 0 bit-identical to no grain).
struct GrainRotation {
  double c = 1.0, s = 0.0;
  bool identity = true;
};

inline GrainRotation grain_rotation(double g) {
  GrainRotation r;
  if (g == 0.0) return r;
  r.identity = false;
  const double q = g / M_PI_2, k = std::round(q);
  if (std::abs(g - k * M_PI_2) <= 8.0 * 2.220446049250313e-16 * std::max(1.0, std::abs(g))) {
    static const double C[4] = {1.0, 0.0, -1.0, 0.0}, S[4] = {0.0, 1.0, 0.0, -1.0};
    const int i = static_cast<int>(((static_cast<long long>(k) % 4) + 4) % 4);
    r.c = C[i];
    r.s = S[i];
  } else {
    r.c = std::cos(g);
    r.s = std::sin(g);
  }
  return r;
}

/// u' = R(−g) u for the three rest corners of a triangle (generic in the scalar so duals/jets
/// over u carry ∂u'/∂u = R(−g)).
template <class T>
void to_grain_frame(const GrainRotation& r, const T u[3][2], T out[3][2]) {
  for (int k = 0; k < 3; ++k) {
    if (r.identity) {
      out[k][0] = u[k][0];
      out[k][1] = u[k][1];
    } else {
      out[k][0] = u[k][0] * r.c + u[k][1] * r.s;
      out[k][1] = u[k][1] * r.c - u[k][0] * r.s;
    }
  }
}

}  // namespace diffavatar
