#include "pattern/mean_value_coordinates.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace diffavatar {

namespace {

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// Strict corners of the convex hull (Andrew's monotone chain); collinear points — turns below
// angle_tol (rad, relative: |oa × ob| ≤ angle_tol |oa| |ob|) — excluded. Points sort by x, and
// those whose x lie within x_tol (m) of the first of their run by y: the chain pops the middle
// of three collinear points, so a straight vertical edge must come in y order. An exact tie
// gives that order; x's 1e-13 m apart (round-off) gave noise's order, and the chain popped the
// edge's real end, a corner, and kept a point from its middle. An absolute area tolerance let
// round-off make middle points of a small panel's straight edge corners (a 3 × 12 cm placket).
std::vector<int> hull_corners(const RefX2d& P, double angle_tol, double x_tol) {
  const int n = static_cast<int>(P.rows());
  std::vector<int> idx(n);
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](int a, int b) {
    return P(a, 0) < P(b, 0) || (P(a, 0) == P(b, 0) && P(a, 1) < P(b, 1));
  });
  for (int lo = 0; lo < n;) {
    int hi = lo + 1;
    while (hi < n && P(idx[hi], 0) - P(idx[lo], 0) <= x_tol) ++hi;
    std::sort(idx.begin() + lo, idx.begin() + hi, [&](int a, int b) { return P(a, 1) < P(b, 1); });
    lo = hi;
  }
  auto left_turn = [&](int o, int a, int b) {   // strictly left of o→b, beyond round-off
    Vec2 oa = P.row(a).transpose() - P.row(o).transpose();
    Vec2 ob = P.row(b).transpose() - P.row(o).transpose();
    return cross2(oa, ob) > angle_tol * oa.norm() * ob.norm();
  };
  std::vector<int> H(2 * n);
  int k = 0;
  for (int i = 0; i < n; ++i) {
    while (k >= 2 && !left_turn(H[k - 2], H[k - 1], idx[i])) --k;
    H[k++] = idx[i];
  }
  for (int i = n - 2, t = k + 1; i >= 0; --i) {
    while (k >= t && !left_turn(H[k - 2], H[k - 1], idx[i])) --k;
    H[k++] = idx[i];
  }
  H.resize(std::max(0, k - 1));
  return H;
}

}  // namespace

VecXi cage_handles(const RefX2d& loop, double angle_threshold_deg) {
  const int n = static_cast<int>(loop.rows());
  if (n < 3) throw std::invalid_argument("loop: needs at least 3 points");
  const Vec2 lo = loop.colwise().minCoeff().transpose(), hi = loop.colwise().maxCoeff().transpose();
  const double scale = (hi - lo).norm();
  std::vector<char> is_handle(n, 0);
  for (int i : hull_corners(loop, 1e-9, 1e-9 * scale)) is_handle[i] = 1;
  const double thr = angle_threshold_deg * M_PI / 180.0;
  for (int i = 0; i < n; ++i) {
    const Vec2 ein = loop.row(i).transpose() - loop.row((i + n - 1) % n).transpose();
    const Vec2 eout = loop.row((i + 1) % n).transpose() - loop.row(i).transpose();
    const double turn = std::atan2(std::abs(cross2(ein, eout)), ein.dot(eout));
    if (turn > thr) is_handle[i] = 1;
  }
  std::vector<int> out;
  for (int i = 0; i < n; ++i)
    if (is_handle[i]) out.push_back(i);
  VecXi r(out.size());
  for (size_t i = 0; i < out.size(); ++i) r[i] = out[i];
  return r;
}

RowMatXd mean_value_coordinates(const RefX2d& cage, const RefX2d& points) {
  const int H = static_cast<int>(cage.rows());
  const int N = static_cast<int>(points.rows());
  if (H < 3) throw std::invalid_argument("cage: needs at least 3 vertices");
  RowMatXd W = RowMatXd::Zero(N, H);
  const Vec2 lo = cage.colwise().minCoeff().transpose(), hi = cage.colwise().maxCoeff().transpose();
  const double eps = 1e-12 * (hi - lo).norm();
#pragma omp parallel for schedule(static)
  for (int p = 0; p < N; ++p) {
    const Vec2 x = points.row(p).transpose();
    std::vector<Vec2> d(H);
    std::vector<double> r(H);
    int at_vertex = -1;
    for (int i = 0; i < H; ++i) {
      d[i] = cage.row(i).transpose() - x;
      r[i] = d[i].norm();
      if (r[i] <= eps) at_vertex = i;
    }
    if (at_vertex >= 0) {
      W(p, at_vertex) = 1.0;
      continue;
    }
    std::vector<double> t(H);  // tan(α_i / 2) for edge i → i+1
    bool on_edge = false;
    for (int i = 0; i < H && !on_edge; ++i) {
      const int j = (i + 1) % H;
      const double A = cross2(d[i], d[j]);  // r_i r_j sin α_i
      const double D = d[i].dot(d[j]);      // r_i r_j cos α_i
      if (std::abs(A) <= eps * (r[i] + r[j]) && D < 0) {  // x on the edge's interior
        const double s = r[i] / (r[i] + r[j]);
        W(p, i) = 1.0 - s;
        W(p, j) = s;
        on_edge = true;
        break;
      }
      // tan(α/2) = sin α / (1 + cos α) = (1 − cos α) / sin α: the first cancels as α → π
      // (x just off an edge: 1e-13 m off gave 0/0 → NaN), the second as α → 0.
      t[i] = D >= 0 ? A / (r[i] * r[j] + D) : (r[i] * r[j] - D) / A;
    }
    if (on_edge) continue;
    double sum = 0.0;
    for (int i = 0; i < H; ++i) {
      const double w = (t[(i + H - 1) % H] + t[i]) / r[i];
      W(p, i) = w;
      sum += w;
    }
    W.row(p) /= sum;
  }
  return W;
}

}  // namespace diffavatar
