// atan2 for the hot loops (the dihedral angle of every hinge in every XPBD sweep, where glibc's
// correctly rounded atan2 took ~23% of a sweep). Rational approximation #5077 of Hart & Cheney,
// "Computer Approximations" (1968), 19.56 digits on |z| ≤ tan(π/8), after the classical range
// reduction atan a = π/4 + atan((a−1)/(a+1)) and atan a = π/2 − atan(1/a). Within a few ulp of
// std::atan2 (test/core/test_fast_atan2.py); finite inputs, not both zero.
#pragma once
#include <cmath>

namespace diffavatar {

namespace fast_atan_detail {
constexpr double kPi = 3.14159265358979323846, kPi2 = 1.57079632679489661923, kPi4 = 0.785398163397448309616;
constexpr double kTan3Pi8 = 2.41421356237309504880, kTanPi8 = 0.414213562373095048802;

// atan z for |z| ≤ tan(π/8): z P(z²)/Q(z²).
inline double atan_core(double z) {
  const double s = z * z;
  const double p = (((16.1536412982230228262 * s + 268.42548195503973794141) * s + 1153.0293515404850115428136) * s +
                    1780.40631643319697105464587) * s + 896.78597403663861959987488;
  const double q = ((((s + 58.95697050844462222791) * s + 536.265374031215315104235) * s +
                     1666.7838148816337184521798) * s + 2079.33497444540981287275926) * s + 896.78597403663861962481162;
  return z * p / q;
}

// atan a for a ≥ 0.
inline double atan_positive(double a) {
  if (a < kTanPi8) return atan_core(a);
  if (a > kTan3Pi8) return kPi2 - atan_core(1.0 / a);
  return kPi4 + atan_core((a - 1.0) / (a + 1.0));
}
}  // namespace fast_atan_detail

/// atan2(y, x) in [−π, π] (rad).
inline double fast_atan2(double y, double x) {
  using namespace fast_atan_detail;
  const double ax = std::abs(x), ay = std::abs(y);
  // |y| ≤ |x|: atan(|y|/|x|) ∈ [0, π/4]; otherwise π/2 − atan(|x|/|y|) (no overflow, x may be 0).
  double t = ay <= ax ? atan_positive(ay / ax) : kPi2 - atan_positive(ax / ay);
  if (std::signbit(x)) t = kPi - t;
  return std::signbit(y) ? -t : t;
}

}  // namespace diffavatar
