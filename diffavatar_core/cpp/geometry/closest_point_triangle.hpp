// Closest point on a triangle to a query point (Ericson, Real-Time Collision Detection §5.1.5).
// Units: whatever the inputs are in (metres inside the core).
#pragma once
#include "common/types.hpp"

namespace diffavatar {

/// Closest point on triangle (a, b, c) to p, with its barycentric coordinates.
/// Outputs: `bary` (w_a, w_b, w_c; sum 1, each ≥ 0) and the point itself (returned).
/// `region` is 0 for the face interior, 1..3 for edges ab, bc, ca, 4..6 for vertices a, b, c.
inline Vec3 closest_point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                   Eigen::Vector3d& bary, int& region) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) { bary = {1, 0, 0}; region = 4; return a; }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) { bary = {0, 1, 0}; region = 5; return b; }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    bary = {1 - v, v, 0}; region = 1; return a + v * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) { bary = {0, 0, 1}; region = 6; return c; }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    bary = {1 - w, 0, w}; region = 3; return a + w * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    bary = {0, 1 - w, w}; region = 2; return b + w * (c - b);
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  bary = {1 - v - w, v, w}; region = 0;
  return a + ab * v + ac * w;
}

}  // namespace diffavatar
