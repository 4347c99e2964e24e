// Forward-mode automatic differentiation on small, fixed-size local variable vectors.
// Dual<N>: value + gradient (first order): derivatives of rest-shape quantities (areas, D̄⁻¹,
//          hinge weights) w.r.t. the pattern.
// Jet<N>:  value + gradient + Hessian (second order): the mixed derivatives ∂²E/∂x∂ū of the
//          equilibrium adjoint (implicit function theorem, issue 4). Newton's ∇ₓE and ∇ₓ²E are
//          in closed form (stretch_kernel.hpp, bending_kernel.hpp).
// Both are exact (no truncation error), so the kernels written once as templates on the scalar
// type give C, ∇C, ∇²C consistently; the double instantiation is the plain forward value.
#pragma once
#include <Eigen/Core>
#include <cmath>

namespace diffavatar {

using std::atan2;
using std::sqrt;

template <int N>
struct Dual {
  using Vec = Eigen::Matrix<double, N, 1>;
  double v = 0.0;
  Vec g = Vec::Zero();
  Dual() = default;
  Dual(double c) : v(c) {}  // NOLINT: constants convert implicitly
  static Dual var(double value, int i) { Dual d(value); d.g[i] = 1.0; return d; }
  // Composition with a scalar function f at u: f(u), f'(u).
  Dual chain(double f, double df) const { Dual r(f); r.g = df * g; return r; }
};

template <int N>
struct Jet {
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  double v = 0.0;
  Vec g = Vec::Zero();
  Mat H = Mat::Zero();
  Jet() = default;
  Jet(double c) : v(c) {}  // NOLINT
  static Jet var(double value, int i) { Jet d(value); d.g[i] = 1.0; return d; }
  Jet chain(double f, double df, double d2f) const {
    Jet r(f);
    r.g = df * g;
    r.H = df * H + d2f * (g * g.transpose());
    return r;
  }
};

// ---- Dual arithmetic -------------------------------------------------------------------------
template <int N> inline Dual<N> operator+(const Dual<N>& a, const Dual<N>& b) { Dual<N> r(a.v + b.v); r.g = a.g + b.g; return r; }
template <int N> inline Dual<N> operator-(const Dual<N>& a, const Dual<N>& b) { Dual<N> r(a.v - b.v); r.g = a.g - b.g; return r; }
template <int N> inline Dual<N> operator-(const Dual<N>& a) { Dual<N> r(-a.v); r.g = -a.g; return r; }
template <int N> inline Dual<N> operator*(const Dual<N>& a, const Dual<N>& b) { Dual<N> r(a.v * b.v); r.g = b.v * a.g + a.v * b.g; return r; }
template <int N> inline Dual<N> operator/(const Dual<N>& a, const Dual<N>& b) {
  Dual<N> r(a.v / b.v); r.g = (a.g - r.v * b.g) / b.v; return r;
}
template <int N> inline Dual<N> operator+(const Dual<N>& a, double c) { Dual<N> r = a; r.v += c; return r; }
template <int N> inline Dual<N> operator+(double c, const Dual<N>& a) { return a + c; }
template <int N> inline Dual<N> operator-(const Dual<N>& a, double c) { Dual<N> r = a; r.v -= c; return r; }
template <int N> inline Dual<N> operator-(double c, const Dual<N>& a) { Dual<N> r = -a; r.v += c; return r; }
template <int N> inline Dual<N> operator*(const Dual<N>& a, double c) { Dual<N> r(a.v * c); r.g = a.g * c; return r; }
template <int N> inline Dual<N> operator*(double c, const Dual<N>& a) { return a * c; }
template <int N> inline Dual<N> operator/(const Dual<N>& a, double c) { return a * (1.0 / c); }
template <int N> inline Dual<N> sqrt(const Dual<N>& a) { double s = std::sqrt(a.v); return a.chain(s, 0.5 / s); }
template <int N> inline Dual<N> atan2(const Dual<N>& y, const Dual<N>& x) {
  double r2 = x.v * x.v + y.v * y.v;
  Dual<N> r(std::atan2(y.v, x.v));
  r.g = (x.v * y.g - y.v * x.g) / r2;
  return r;
}

// ---- Jet arithmetic --------------------------------------------------------------------------
template <int N> inline Jet<N> operator+(const Jet<N>& a, const Jet<N>& b) { Jet<N> r(a.v + b.v); r.g = a.g + b.g; r.H = a.H + b.H; return r; }
template <int N> inline Jet<N> operator-(const Jet<N>& a, const Jet<N>& b) { Jet<N> r(a.v - b.v); r.g = a.g - b.g; r.H = a.H - b.H; return r; }
template <int N> inline Jet<N> operator-(const Jet<N>& a) { Jet<N> r(-a.v); r.g = -a.g; r.H = -a.H; return r; }
template <int N> inline Jet<N> operator*(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r(a.v * b.v);
  r.g = b.v * a.g + a.v * b.g;
  r.H = b.v * a.H + a.v * b.H + a.g * b.g.transpose() + b.g * a.g.transpose();
  return r;
}
template <int N> inline Jet<N> inv(const Jet<N>& b) { double i = 1.0 / b.v; return b.chain(i, -i * i, 2.0 * i * i * i); }
template <int N> inline Jet<N> operator/(const Jet<N>& a, const Jet<N>& b) { return a * inv(b); }
template <int N> inline Jet<N> operator+(const Jet<N>& a, double c) { Jet<N> r = a; r.v += c; return r; }
template <int N> inline Jet<N> operator+(double c, const Jet<N>& a) { return a + c; }
template <int N> inline Jet<N> operator-(const Jet<N>& a, double c) { Jet<N> r = a; r.v -= c; return r; }
template <int N> inline Jet<N> operator-(double c, const Jet<N>& a) { Jet<N> r = -a; r.v += c; return r; }
template <int N> inline Jet<N> operator*(const Jet<N>& a, double c) { Jet<N> r(a.v * c); r.g = a.g * c; r.H = a.H * c; return r; }
template <int N> inline Jet<N> operator*(double c, const Jet<N>& a) { return a * c; }
template <int N> inline Jet<N> operator/(const Jet<N>& a, double c) { return a * (1.0 / c); }
template <int N> inline Jet<N> sqrt(const Jet<N>& a) { double s = std::sqrt(a.v); return a.chain(s, 0.5 / s, -0.25 / (s * a.v)); }
template <int N> inline Jet<N> atan2(const Jet<N>& y, const Jet<N>& x) {
  // f(x, y) = atan2(y, x): fx = -y/r², fy = x/r², fxx = 2xy/r⁴, fyy = -2xy/r⁴, fxy = (y²-x²)/r⁴.
  double r2 = x.v * x.v + y.v * y.v, r4 = r2 * r2;
  double fx = -y.v / r2, fy = x.v / r2;
  double fxx = 2.0 * x.v * y.v / r4, fyy = -fxx, fxy = (y.v * y.v - x.v * x.v) / r4;
  Jet<N> r(std::atan2(y.v, x.v));
  r.g = fx * x.g + fy * y.g;
  r.H = fx * x.H + fy * y.H + fxx * (x.g * x.g.transpose()) + fyy * (y.g * y.g.transpose()) +
        fxy * (x.g * y.g.transpose() + y.g * x.g.transpose());
  return r;
}

// Scalar helpers so kernels can be written once for double, Dual and Jet.
inline double value_of(double a) { return a; }
template <int N> inline double value_of(const Dual<N>& a) { return a.v; }
template <int N> inline double value_of(const Jet<N>& a) { return a.v; }

/// 3-vector of any scalar (kernels do their own small vector algebra; Eigen matrices of custom
/// scalars would need NumTraits and cost compile time for no gain here).
template <class T>
struct V3 {
  T x, y, z;
  V3 operator-(const V3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  V3 operator+(const V3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  V3 operator*(const T& s) const { return {x * s, y * s, z * s}; }
};
template <class T> inline T dot(const V3<T>& a, const V3<T>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <class T> inline V3<T> cross(const V3<T>& a, const V3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class T> inline T norm(const V3<T>& a) { return sqrt(dot(a, a)); }
}  // namespace diffavatar
