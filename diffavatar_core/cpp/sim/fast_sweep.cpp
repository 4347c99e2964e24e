#include "sim/fast_sweep.hpp"

#include <algorithm>
#include <cmath>

namespace diffavatar {

namespace {

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define DA_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define DA_CLONES
#endif

enum StretchField { kW0, kW1, kW2, kB00, kB01, kB10, kB11, kS00, kS01, kS11, kCa0, kCa1, kCa2 };
enum BendField { kBw0, kBw1, kBw2, kBw3, kTheta0, kInvKw };

// max / min by value (std::max returns a reference, which keeps a branch in the loop)
__attribute__((always_inline)) inline float vmax(float a, float b) { return a > b ? a : b; }
__attribute__((always_inline)) inline float vmin(float a, float b) { return a < b ? a : b; }

// X[i..i+2] = (x, y, z): one vertex's row of the float positions (3 per vertex)
__attribute__((always_inline)) inline void store3(float* X, int i, float x, float y, float z) {
  X[i] = x;
  X[i + 1] = y;
  X[i + 2] = z;
}

// atan2 in float without branches (vectorisable): octant reduction and the odd polynomial of
// Abramowitz & Stegun 4.4.49 for atan on [0, 1] (|error| ≤ 2e-8 rad before float round-off).
__attribute__((always_inline)) inline float atan2_poly(float y, float x) {
  float ax = std::fabs(x), ay = std::fabs(y);
  float mx = vmax(ax, ay), mn = vmin(ax, ay);
  float a = mn / vmax(mx, 1e-30f);   // no conditional division: the loop stays branch-free
  float s = a * a;
  float r = ((((((((0.0028662257f * s - 0.0161657367f) * s + 0.0429096138f) * s - 0.0752896400f) * s +
                 0.1065626393f) * s - 0.1420889944f) * s + 0.1999355085f) * s - 0.3333314528f) * s) * a + a;
  r = ay > ax ? 1.57079637f - r : r;
  r = x < 0.0f ? 3.14159274f - r : r;
  return y < 0.0f ? -r : r;
}

// Orthotropic StVK block (stretch_kernel.hpp, project_stretch) for constraints [b, e) of one
// colour. With p = |f0|², q = |f1|², r = f0·f1 and S_ab = Σ_k w_k c_ak c_bk, the 3×3 matrix
// Σ_k w_k ∇_k C_a·∇_k C_b is [[S00 p, S01 r, ½(S00 r + S01 p)], [·, S11 q, ½(S01 q + S11 r)],
// [·, ·, ¼(S00 q + 2 S01 r + S11 p)]].
DA_CLONES void stretch_block(float* __restrict X, const std::int32_t* __restrict V0, const std::int32_t* __restrict V1,
                             const std::int32_t* __restrict V2, float* const* F, float* __restrict L0,
                             float* __restrict L1, float* __restrict L2, int b, int e, float inv_dt2) {
  const float *__restrict W0 = F[kW0], *__restrict W1 = F[kW1], *__restrict W2 = F[kW2];
  const float *__restrict B00 = F[kB00], *__restrict B01 = F[kB01], *__restrict B10 = F[kB10],
              *__restrict B11 = F[kB11];
  const float *__restrict S00 = F[kS00], *__restrict S01 = F[kS01], *__restrict S11 = F[kS11];
  const float *__restrict Ca0 = F[kCa0], *__restrict Ca1 = F[kCa1], *__restrict Ca2 = F[kCa2];
#pragma omp simd
  for (int j = b; j < e; ++j) {
    const int i0 = 3 * V0[j], i1 = 3 * V1[j], i2 = 3 * V2[j];
    const float x0 = X[i0], y0 = X[i0 + 1], z0 = X[i0 + 2];
    const float x1 = X[i1], y1 = X[i1 + 1], z1 = X[i1 + 2];
    const float x2 = X[i2], y2 = X[i2 + 1], z2 = X[i2 + 2];
    const float d1x = x1 - x0, d1y = y1 - y0, d1z = z1 - z0, d2x = x2 - x0, d2y = y2 - y0, d2z = z2 - z0;
    const float b00 = B00[j], b01 = B01[j], b10 = B10[j], b11 = B11[j];
    const float f0x = d1x * b00 + d2x * b10, f0y = d1y * b00 + d2y * b10, f0z = d1z * b00 + d2z * b10;
    const float f1x = d1x * b01 + d2x * b11, f1y = d1y * b01 + d2y * b11, f1z = d1z * b01 + d2z * b11;
    const float p = f0x * f0x + f0y * f0y + f0z * f0z, q = f1x * f1x + f1y * f1y + f1z * f1z,
                r = f0x * f1x + f0y * f1y + f0z * f1z;
    const float a0 = Ca0[j] * inv_dt2, a1 = Ca1[j] * inv_dt2, a2 = Ca2[j] * inv_dt2;
    const float s00 = S00[j], s01 = S01[j], s11 = S11[j];
    const float A00 = s00 * p + a0, A11 = s11 * q + a1, A22 = 0.25f * (s00 * q + 2.0f * s01 * r + s11 * p) + a2;
    const float A01 = s01 * r, A02 = 0.5f * (s00 * r + s01 * p), A12 = 0.5f * (s01 * q + s11 * r);
    const float l0 = L0[j], l1 = L1[j], l2 = L2[j];
    const float r0 = -(0.5f * (p - 1.0f) + a0 * l0), r1 = -(0.5f * (q - 1.0f) + a1 * l1), r2 = -(0.5f * r + a2 * l2);
    const float c00 = A11 * A22 - A12 * A12, c01 = A02 * A12 - A01 * A22, c02 = A01 * A12 - A02 * A11;
    const float c11 = A00 * A22 - A02 * A02, c12 = A01 * A02 - A00 * A12, c22 = A00 * A11 - A01 * A01;
    const float inv_det = 1.0f / (A00 * c00 + A01 * c01 + A02 * c02);
    const float dl0 = (c00 * r0 + c01 * r1 + c02 * r2) * inv_det;
    const float dl1 = (c01 * r0 + c11 * r1 + c12 * r2) * inv_det;
    const float dl2 = (c02 * r0 + c12 * r1 + c22 * r2) * inv_det;
    L0[j] = l0 + dl0;
    L1[j] = l1 + dl1;
    L2[j] = l2 + dl2;
    // Δx_k = w_k [f0 (c0k Δλ0 + ½ c1k Δλ2) + f1 (c1k Δλ1 + ½ c0k Δλ2)], c0 = (−b00−b10, b00, b10),
    // c1 = (−b01−b11, b01, b11)
    const float c0k[3] = {-(b00 + b10), b00, b10}, c1k[3] = {-(b01 + b11), b01, b11};
    const float wk[3] = {W0[j], W1[j], W2[j]};
    const int ik[3] = {i0, i1, i2};
    const float xk[3][3] = {{x0, y0, z0}, {x1, y1, z1}, {x2, y2, z2}};
    for (int k = 0; k < 3; ++k) {
      const float u = wk[k] * (c0k[k] * dl0 + 0.5f * c1k[k] * dl2), t = wk[k] * (c1k[k] * dl1 + 0.5f * c0k[k] * dl2);
      store3(X, ik[k], xk[k][0] + u * f0x + t * f1x, xk[k][1] + u * f0y + t * f1y, xk[k][2] + u * f0z + t * f1z);
    }
  }
}

// Hinge (bending_kernel.hpp, dihedral_gradient + project_bending) for hinges [b, e) of one colour.
DA_CLONES void bending_block(float* __restrict X, const std::int32_t* const* V, float* const* F, float* __restrict L,
                             int b, int e, float inv_dt2) {
  const std::int32_t *__restrict Va = V[0], *__restrict Vb = V[1], *__restrict Vc = V[2], *__restrict Vd = V[3];
  const float *__restrict W0 = F[kBw0], *__restrict W1 = F[kBw1], *__restrict W2 = F[kBw2], *__restrict W3 = F[kBw3];
  const float *__restrict T0 = F[kTheta0], *__restrict IKw = F[kInvKw];
#pragma omp simd
  for (int j = b; j < e; ++j) {
    const int ia = 3 * Va[j], ib = 3 * Vb[j], ic = 3 * Vc[j], id = 3 * Vd[j];
    const float ax = X[ia], ay = X[ia + 1], az = X[ia + 2];
    const float bx = X[ib], by = X[ib + 1], bz = X[ib + 2];
    const float cx = X[ic], cy = X[ic + 1], cz = X[ic + 2];
    const float dx = X[id], dy = X[id + 1], dz = X[id + 2];
    const float ex = bx - ax, ey = by - ay, ez = bz - az;
    const float cax = cx - ax, cay = cy - ay, caz = cz - az, dax = dx - ax, day = dy - ay, daz = dz - az;
    // n1 = e × (c − a), n2 = (d − a) × e
    const float n1x = ey * caz - ez * cay, n1y = ez * cax - ex * caz, n1z = ex * cay - ey * cax;
    const float n2x = day * ez - daz * ey, n2y = daz * ex - dax * ez, n2z = dax * ey - day * ex;
    const float el2 = ex * ex + ey * ey + ez * ez;
    const float q1 = n1x * n1x + n1y * n1y + n1z * n1z, q2 = n2x * n2x + n2y * n2y + n2z * n2z;
    // a degenerate hinge projects nothing (as dihedral_gradient's false): okf = 0 zeroes its
    // gradient and Δλ; divisions are unconditional (by clamped values), so the loop has no branch
    const float okf = (el2 > 1e-24f) & (q1 > 1e-30f) & (q2 > 1e-30f) ? 1.0f : 0.0f;
    const float el = std::sqrt(el2), inv_el = okf / vmax(el, 1e-12f);
    const float mx = n1y * n2z - n1z * n2y, my = n1z * n2x - n1x * n2z, mz = n1x * n2y - n1y * n2x;
    const float th = atan2_poly((mx * ex + my * ey + mz * ez) * inv_el, n1x * n2x + n1y * n2y + n1z * n2z);
    const float iq1 = okf / vmax(q1, 1e-30f), iq2 = okf / vmax(q2, 1e-30f);
    const float m1x = n1x * iq1, m1y = n1y * iq1, m1z = n1z * iq1, m2x = n2x * iq2, m2y = n2y * iq2, m2z = n2z * iq2;
    const float ce = cax * ex + cay * ey + caz * ez, de = dax * ex + day * ey + daz * ez;
    // (c−a)·ê, (d−a)·ê, (c−b)·ê, (d−b)·ê
    const float tca = ce * inv_el, tda = de * inv_el, tcb = (ce - el2) * inv_el, tdb = (de - el2) * inv_el;
    const float g0x = -tcb * m1x - tdb * m2x, g0y = -tcb * m1y - tdb * m2y, g0z = -tcb * m1z - tdb * m2z;
    const float g1x = tca * m1x + tda * m2x, g1y = tca * m1y + tda * m2y, g1z = tca * m1z + tda * m2z;
    const float g2x = -el * m1x, g2y = -el * m1y, g2z = -el * m1z;
    const float g3x = -el * m2x, g3y = -el * m2y, g3z = -el * m2z;
    const float w0 = W0[j], w1 = W1[j], w2 = W2[j], w3 = W3[j];
    const float at = IKw[j] * inv_dt2;
    const float denom = at + w0 * (g0x * g0x + g0y * g0y + g0z * g0z) + w1 * (g1x * g1x + g1y * g1y + g1z * g1z) +
                        w2 * (g2x * g2x + g2y * g2y + g2z * g2z) + w3 * (g3x * g3x + g3y * g3y + g3z * g3z);
    const float l = L[j];
    const float dl = -okf * (th - T0[j] + at * l) / denom;   // denom ≥ at > 0
    L[j] = l + dl;
    const float s0 = w0 * dl, s1 = w1 * dl, s2 = w2 * dl, s3 = w3 * dl;
    store3(X, ia, ax + s0 * g0x, ay + s0 * g0y, az + s0 * g0z);
    store3(X, ib, bx + s1 * g1x, by + s1 * g1y, bz + s1 * g1z);
    store3(X, ic, cx + s2 * g2x, cy + s2 * g2y, cz + s2 * g2z);
    store3(X, id, dx + s3 * g3x, dy + s3 * g3y, dz + s3 * g3z);
  }
}

// Contacts (contact_kernel.hpp, project_contact; one per vertex, so the loop has no conflicts).
DA_CLONES void contact_block(float* __restrict X, const std::int32_t* __restrict Vi, const float* __restrict W,
                             const float* __restrict Nx, const float* __restrict Ny, const float* __restrict Nz,
                             const float* __restrict D, float* __restrict L, int b, int e, float ac) {
#pragma omp simd
  for (int j = b; j < e; ++j) {
    const int i = 3 * Vi[j];
    const float w = W[Vi[j]], nx = Nx[j], ny = Ny[j], nz = Nz[j];
    const float x = X[i], y = X[i + 1], z = X[i + 2];
    const float C = nx * x + ny * y + nz * z - D[j];
    const float l = L[j];
    const float nl = vmax(l - (C + ac * l) / (w + ac), 0.0f);
    const float dl = nl - l;
    L[j] = nl;
    store3(X, i, x + w * dl * nx, y + w * dl * ny, z + w * dl * nz);
  }
}

}  // namespace

void FastSweep::build(const ClothModel& m, const ClothControl& c, const RestCache& cache, const SweepPlan& plan) {
  stretch_ = Pack();
  bend_ = Pack();
  seam_ = Pack();
  w_.assign(m.num_vertices, 0.0f);
  for (int i = 0; i < m.num_vertices; ++i) w_[i] = static_cast<float>(m.inv_mass[i]);
  auto pack = [&](const SweepBlock& blk) -> Range {
    Pack& P = blk.kind == ConstraintKind::kStretch ? stretch_ : blk.kind == ConstraintKind::kBending ? bend_ : seam_;
    Range r{blk.kind, P.size(), P.size()};
    for (int ci : blk.idx) {
      if (blk.kind == ConstraintKind::kStretch) {
        const Eigen::Matrix2d& B = cache.tri[ci].B;
        double w[3], c0[3] = {-(B(0, 0) + B(1, 0)), B(0, 0), B(1, 0)}, c1[3] = {-(B(0, 1) + B(1, 1)), B(0, 1), B(1, 1)};
        double s00 = 0, s01 = 0, s11 = 0;
        for (int k = 0; k < 3; ++k) {
          P.v[k].push_back(m.faces(ci, k));
          w[k] = m.inv_mass[m.faces(ci, k)];
          s00 += w[k] * c0[k] * c0[k];
          s01 += w[k] * c0[k] * c1[k];
          s11 += w[k] * c1[k] * c1[k];
        }
        const double area = cache.tri[ci].area;
        const double vals[13] = {w[0], w[1], w[2], B(0, 0), B(0, 1), B(1, 0), B(1, 1), s00, s01, s11,
                                 c.stretch_compliance(m.tri_group[ci], 0) / area,
                                 c.stretch_compliance(m.tri_group[ci], 1) / area,
                                 c.stretch_compliance(m.tri_group[ci], 2) / area};
        for (int f = 0; f < 13; ++f) P.f[f].push_back(static_cast<float>(vals[f]));
      } else if (blk.kind == ConstraintKind::kBending) {
        const double kw = c.bend_stiffness[m.hinge_group[ci]] * cache.hinge_weight[ci];
        if (!(kw > 0.0)) continue;   // as XpbdSolver::project: no stiffness, no projection
        for (int k = 0; k < 4; ++k) {
          P.v[k].push_back(m.hinges(ci, k));
          P.f[kBw0 + k].push_back(static_cast<float>(m.inv_mass[m.hinges(ci, k)]));
        }
        P.f[kTheta0].push_back(static_cast<float>(m.hinge_rest_angle[ci]));
        P.f[kInvKw].push_back(static_cast<float>(1.0 / kw));
      } else {
        P.v[0].push_back(m.seams(ci, 0));
        P.v[1].push_back(m.seams(ci, 1));
      }
      ++r.end;
    }
    return r;
  };
  lanes_.assign(plan.lanes.size(), {});
  for (std::size_t l = 0; l < plan.lanes.size(); ++l)
    for (const SweepBlock& blk : plan.lanes[l]) lanes_[l].push_back(pack(blk));
  interface_.clear();
  for (const SweepBlock& blk : plan.interface) interface_.push_back(pack(blk));
  for (Pack* P : {&stretch_, &bend_, &seam_})
    for (auto& l : P->lambda) l.assign(P->size(), 0.0f);
}

void FastSweep::run_range(const Range& r, float inv_dt2, float seam_alpha) {
  if (r.begin == r.end) return;
  if (r.kind == ConstraintKind::kStretch) {
    Pack& P = stretch_;
    float* F[13];
    for (int f = 0; f < 13; ++f) F[f] = P.f[f].data();
    stretch_block(X_.data(), P.v[0].data(), P.v[1].data(), P.v[2].data(), F, P.lambda[0].data(), P.lambda[1].data(),
                  P.lambda[2].data(), r.begin, r.end, inv_dt2);
  } else if (r.kind == ConstraintKind::kBending) {
    Pack& P = bend_;
    float* F[6];
    for (int f = 0; f < 6; ++f) F[f] = P.f[f].data();
    const std::int32_t* V[4] = {P.v[0].data(), P.v[1].data(), P.v[2].data(), P.v[3].data()};
    bending_block(X_.data(), V, F, P.lambda[0].data(), r.begin, r.end, inv_dt2);
  } else {
    // seams (seam_kernel.hpp): few, scalar
    Pack& P = seam_;
    for (int j = r.begin; j < r.end; ++j) {
      const int a = P.v[0][j], b = P.v[1][j];
      const float wa = w_[a], wb = w_[b], denom = wa + wb + seam_alpha;
      if (!(denom > 0.0f)) continue;
      for (int k = 0; k < 3; ++k) {
        float& lk = P.lambda[k][j];
        const float dl = -(X_[3 * a + k] - X_[3 * b + k] + seam_alpha * lk) / denom;
        lk += dl;
        X_[3 * a + k] += wa * dl;
        X_[3 * b + k] -= wb * dl;
      }
    }
  }
}

void FastSweep::run(RowMatX3d& x, int sweeps, double dt, const std::vector<Contact>& contacts,
                    const std::vector<ContactFrame>& frames, double thickness, double contact_stiffness,
                    double seam_compliance) {
  const int nv = static_cast<int>(x.rows());
  X_.resize(3 * static_cast<std::size_t>(nv));
  for (int i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) X_[3 * i + k] = static_cast<float>(x(i, k));
  X0_ = X_;
  for (Pack* P : {&stretch_, &bend_, &seam_})
    for (auto& l : P->lambda) std::fill(l.begin(), l.end(), 0.0f);
  const int nc = static_cast<int>(contacts.size());
  cv_.resize(nc);
  for (auto* a : {&cn_[0], &cn_[1], &cn_[2], &cd_}) a->resize(nc);
  cl_.assign(nc, 0.0f);
  for (int j = 0; j < nc; ++j) {
    const Vec3& n = frames[j].n;
    cv_[j] = contacts[j].vertex;
    for (int k = 0; k < 3; ++k) cn_[k][j] = static_cast<float>(n[k]);
    cd_[j] = static_cast<float>(n.dot(frames[j].q) + thickness);
  }
  const double dt2 = dt * dt;
  const float inv_dt2 = static_cast<float>(1.0 / dt2), seam_alpha = static_cast<float>(seam_compliance / dt2),
              ac = static_cast<float>(1.0 / (contact_stiffness * dt2));
  const int nl = static_cast<int>(lanes_.size());
  const bool par = nl > 1;
#pragma omp parallel if (par)
  for (int sw = 0; sw < sweeps; ++sw) {
#pragma omp for schedule(static)
    for (int l = 0; l < nl; ++l)
      for (const Range& r : lanes_[l]) run_range(r, inv_dt2, seam_alpha);
#pragma omp single
    for (const Range& r : interface_) run_range(r, inv_dt2, seam_alpha);
    // contacts in parallel chunks (one per vertex: no two touch the same row)
#pragma omp for schedule(static)
    for (int c0 = 0; c0 < nc; c0 += 1024)
      contact_block(X_.data(), cv_.data(), w_.data(), cn_[0].data(), cn_[1].data(), cn_[2].data(), cd_.data(),
                    cl_.data(), c0, std::min(nc, c0 + 1024), ac);
  }
  // Add the float displacement to the double positions: vertices the sweeps did not move,
  // pinned ones among them, keep their positions bit for bit.
  for (int i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) x(i, k) += static_cast<double>(X_[3 * i + k] - X0_[3 * i + k]);
}

}  // namespace diffavatar
