"""Feature-matching terms of the DiffAvatar loss (paper §4.2.5), with exact gradients w.r.t. the
simulated garment's vertex positions X (#V×3, m):

- interior: symmetric squared Chamfer distance between the garment surface and the scan's garment
  points — or, given the scan's garment mesh, from the garment's samples to that surface (C++
  `chamfer_loss`);
- boundary: for each garment boundary loop matched to a scan boundary loop (by name: 'hem',
  'neckline', 'sleeve_left', ...), a symmetric squared curve-to-curve Chamfer distance between the
  two closed polylines — it pulls hem heights and sleeve lengths to the scan's;
- boundary length: per matched loop, the squared difference of the garment loop's 3D perimeter
  and the scan loop's — "the boundary loss ... serves to drive correct lengths of the pattern"
  (§4.2.5): a curve-to-curve distance alone lets a too-long hem hide its excess in folds.

Squared distances are in m²; the reported Chamfer *metric* is separate (metrics.py, in cm)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import _core
from . import _validate as val


@dataclass(frozen=True)
class GarmentSamples:
    """Fixed area-uniform sample points on a garment mesh as barycentric combinations:
    point_i = Σ_k bary[i, k] · X[F[tri[i], k]]. Draw once per iteration (or once per run)."""
    tri: np.ndarray   # (S,) int32
    bary: np.ndarray  # (S, 3) float64

    def points(self, X: np.ndarray, F: np.ndarray) -> np.ndarray:
        return np.einsum("sk,skd->sd", self.bary, X[F[self.tri]])


def garment_samples(X, F, n: int, seed: int = 0) -> GarmentSamples:
    """n area-uniform samples on the surface (X: #V×3 m, F: #F×3), reproducible by seed."""
    X, F = val.mesh("X", X, "F", F)
    n = val.positive_int("n", n)
    area = 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)
    if not area.sum() > 0:
        raise ValueError("F: the garment surface has zero area")
    rng = np.random.default_rng(seed)
    tri = rng.choice(len(F), size=n, p=area / area.sum()).astype(np.int32)
    r1, r2 = np.sqrt(rng.random(n)), rng.random(n)
    bary = np.column_stack([1 - r1, r1 * (1 - r2), r1 * r2])
    return GarmentSamples(tri, np.ascontiguousarray(bary))


@dataclass(frozen=True)
class InteriorLoss:
    value: float            # ½(mean garment→scan d² + mean scan→garment d²), m²
    garment_to_scan: float  # m²
    scan_to_garment: float  # m²
    garment_trimmed: int
    scan_trimmed: int
    grad: np.ndarray        # dL/dX, #V×3


def interior_loss(X, F, samples: GarmentSamples, scan_points, trim_distance: float = 0.0,
                  progress=None, cancel=None, scan_surface=None) -> InteriorLoss:
    """Symmetric squared Chamfer between garment samples/surface and scan points (m), pairs
    farther than `trim_distance` (m, ≤ 0: none) ignored. scan_surface (V (N, 3) m, F (M, 3)):
    the scan's garment mesh; given, the garment samples are measured to its closest points
    instead of to the nearest of `scan_points`. See cpp/loss/chamfer_loss.hpp."""
    X, F = val.mesh("X", X, "F", F)
    T = val.points("scan_points", scan_points)
    if samples.tri.size and (samples.tri.min() < 0 or samples.tri.max() >= len(F)):
        raise ValueError("samples: triangle index out of range for F")
    surface = ()
    if scan_surface is not None:
        surface = val.mesh("scan_surface vertices", scan_surface[0], "scan_surface faces", scan_surface[1])
    r = _core.chamfer_loss(X, F, samples.tri, samples.bary, T, float(trim_distance), progress, cancel, *surface)
    return InteriorLoss(r.value, r.garment_to_scan, r.scan_to_garment, r.garment_trimmed, r.scan_trimmed,
                        np.array(r.grad))


def _closest_on_polyline(P: np.ndarray, Q: np.ndarray):
    """For each point of P (n×3), the closest point on the closed polyline Q (m×3): returns
    (segment index, parameter t in [0, 1], closest points)."""
    A, B = Q, np.roll(Q, -1, axis=0)
    AB = B - A
    L2 = np.maximum((AB ** 2).sum(1), 1e-300)
    t = np.clip(np.einsum("nmd,md->nm", P[:, None, :] - A[None], AB) / L2, 0.0, 1.0)
    C = A[None] + t[..., None] * AB[None]
    d2 = ((P[:, None, :] - C) ** 2).sum(-1)
    seg = d2.argmin(1)
    rows = np.arange(len(P))
    return seg, t[rows, seg], C[rows, seg]


@dataclass(frozen=True)
class BoundaryLoss:
    value: float              # Σ over matched loops of the symmetric squared curve Chamfer, m²
    per_loop: dict            # name → value (m²)
    grad: np.ndarray          # dL/dX, #V×3


def boundary_loss(X, garment_loops: dict, scan_loops: dict, scale: float = 0.0) -> BoundaryLoss:
    """Boundary feature matching (paper §4.2.5). garment_loops: name → vertex indices of a closed
    boundary loop of X (in order); scan_loops: name → (K, 3) points along the matching scan loop
    (m). Loops present on one side only are skipped. Per matched loop:
        ½ [ mean_v ρ(d²(x_v, scan polyline)) + mean_k ρ(d²(s_k, garment polyline)) ],
    ρ(d²) = d² (scale ≤ 0, the paper's L2) or, robust, s² log(1 + d²/s²) with s = scale (m):
    the same for d ≪ s, while a point d away pulls with weight 1/(1 + d²/s²) — an opening the
    drape hangs elsewhere (a cuff slipped over the hand) then no longer drags the pattern.
    The gradient is exact: closest-point parameters are optimal on each fixed segment."""
    X = val.points("X", X)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not math.isfinite(scale):
        raise ValueError(f"scale: expected a finite length in m (<= 0: L2), got {scale!r}")

    def rho(d2):   # (value, dρ/d(d²)) per point
        if scale <= 0:
            return d2, np.ones_like(d2)
        return scale ** 2 * np.log1p(d2 / scale ** 2), 1.0 / (1.0 + d2 / scale ** 2)

    grad = np.zeros_like(X)
    per_loop = {}
    for name in sorted(set(garment_loops) & set(scan_loops)):
        idx = np.asarray(garment_loops[name], dtype=np.int64)
        if idx.ndim != 1 or len(idx) < 3 or idx.min() < 0 or idx.max() >= len(X):
            raise ValueError(f"garment_loops[{name!r}]: needs ≥ 3 valid vertex indices")
        S = val.points(f"scan_loops[{name!r}]", scan_loops[name])
        if len(S) < 3:
            raise ValueError(f"scan_loops[{name!r}]: needs ≥ 3 points")
        G = X[idx]
        # garment loop vertices → scan polyline
        _, _, C = _closest_on_polyline(G, S)
        r_g = G - C
        # scan points → garment polyline (gradient through the two segment end vertices)
        seg, t, Cg = _closest_on_polyline(S, G)
        r_s = Cg - S
        v_g, w_g = rho((r_g ** 2).sum(1))
        v_s, w_s = rho((r_s ** 2).sum(1))
        per_loop[name] = 0.5 * (v_g.mean() + v_s.mean())
        r_g, r_s = w_g[:, None] * r_g, w_s[:, None] * r_s
        np.add.at(grad, idx, r_g / len(G))
        np.add.at(grad, idx[seg], (1 - t)[:, None] * r_s / len(S))
        np.add.at(grad, idx[(seg + 1) % len(idx)], t[:, None] * r_s / len(S))
    return BoundaryLoss(float(sum(per_loop.values())), per_loop, grad)


def smooth_closed_polyline(P: np.ndarray, sigma: float) -> np.ndarray:
    """P (K×3, m) with every point replaced by the Gaussian-weighted mean of the loop's points
    within a few σ (m) of arc length of it (periodic; each point weighted by the arc length it
    stands for). Points farther apart than ~3σ are left almost as they were."""
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    total = float(seg.sum())
    s = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    length = 0.5 * (seg + np.roll(seg, 1))
    out = np.empty_like(P)
    for i in range(0, len(P), 512):   # rows in blocks: memory 512 × K on a densely sampled loop
        d = np.abs(s[i:i + 512, None] - s[None, :])
        w = np.exp(-0.5 * (np.minimum(d, total - d) / sigma) ** 2) * length[None, :]
        out[i:i + 512] = (w @ P) / w.sum(axis=1, keepdims=True)
    return out


def polyline_length(P: np.ndarray, spacing: float = 0.0, smoothing: float = 0.0) -> float:
    """Perimeter (m) of the closed polyline P (K×3, m). A noisy, finely sampled curve measures
    longer than the curve: by about ½ σ_d²/l² relative, σ_d the spread of the offset between
    neighbours l apart (2 mm scanner noise at 5 mm spacing: +13–17%, bench/recover.py
    --truth-edge). smoothing > 0 (m): the points first averaged along the loop with a Gaussian
    of that width in arc length (smooth_closed_polyline), which leaves the excess at about
    ½ σ_n² l / (2√π σ³) (σ_n the noise, +1–3% for 2 mm at l = 5 mm and σ = 5 mm) and shrinks a
    circle of radius R by about σ²/2R²; a loop sampled sparser than ~3σ is left as it is.
    spacing > 0: then measured through the points nearest to every `spacing` m of arc length."""
    P = val.points("P", P)
    if len(P) < 3:
        raise ValueError("polyline_length: needs ≥ 3 points")
    if smoothing > 0:
        P = smooth_closed_polyline(P, smoothing)
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    total = float(seg.sum())
    if spacing <= 0 or total < 3 * spacing:
        return total
    s = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    keep = np.unique(np.searchsorted(s, np.arange(0.0, total, total / round(total / spacing))).clip(0, len(P) - 1))
    Q = P[keep]
    return float(np.linalg.norm(np.roll(Q, -1, axis=0) - Q, axis=1).sum())


@dataclass(frozen=True)
class BoundaryLengthLoss:
    value: float       # Σ_loops ½ r², r = L_garment − L_scan beyond ± the tolerance, m²
    per_loop: dict     # name → ½ r²
    lengths: dict      # name → (L_garment, L_scan), m
    grad: np.ndarray   # dL/dX, #V×3


def boundary_length_loss(X, garment_loops: dict, scan_lengths: dict, tolerance: dict | None = None) -> BoundaryLengthLoss:
    """Σ over loops present on both sides of ½ r², r = the part of L_g − L_s beyond ± the loop's
    tolerance (m; 0 when not given): L_g the perimeter of the closed garment loop X[idx] (m), L_s
    the scan loop's (m, e.g. polyline_length of it). The tolerance is how far the scan's
    perimeter can be trusted — a noisy scan loop measures longer than the cloth's edge, a
    resampled one shorter (it cuts the folds); within it the boundary and interior terms decide.
    Exact gradient: dL_g/dx_a = Σ over the loop edges (a, b) at a of (x_a − x_b)/|x_a − x_b|."""
    X = val.points("X", X)
    grad = np.zeros_like(X)
    per_loop, lengths = {}, {}
    tolerance = tolerance or {}
    for name in sorted(set(garment_loops) & set(scan_lengths)):
        idx = np.asarray(garment_loops[name], dtype=np.int64)
        if idx.ndim != 1 or len(idx) < 3 or idx.min() < 0 or idx.max() >= len(X):
            raise ValueError(f"garment_loops[{name!r}]: needs ≥ 3 valid vertex indices")
        Ls = float(scan_lengths[name])
        if not np.isfinite(Ls) or Ls <= 0:
            raise ValueError(f"scan_lengths[{name!r}]: needs a positive finite length (m), got {Ls}")
        tol = float(tolerance.get(name, 0.0))
        if not (np.isfinite(tol) and tol >= 0):
            raise ValueError(f"tolerance[{name!r}]: needs a finite length >= 0 (m), got {tol}")
        E = X[np.roll(idx, -1)] - X[idx]
        le = np.linalg.norm(E, axis=1)
        if le.min() <= 0:
            raise ValueError(f"garment loop {name!r} has a zero-length edge")
        Lg = float(le.sum())
        d = Lg - Ls
        r = float(np.sign(d) * max(abs(d) - tol, 0.0))
        per_loop[name], lengths[name] = 0.5 * r * r, (Lg, Ls)
        U = r * E / le[:, None]
        np.add.at(grad, idx, -U)
        np.add.at(grad, np.roll(idx, -1), U)
    return BoundaryLengthLoss(float(sum(per_loop.values())), per_loop, lengths, grad)


@dataclass(frozen=True)
class BodyDataLoss:
    value: float       # mean over the scan's body points of d²(point, body surface), m² (trimmed pairs count 0)
    used: int          # points closer than the trim distance
    grad: np.ndarray   # dL/dX_body, #Vb×3


def body_data_loss(X, F, points, trim_distance: float = 0.05) -> BodyDataLoss:
    """One-sided scan → body term of the co-optimization: the scan's body-labelled points (m)
    should lie on the posed body surface (X: #Vb×3 m, F: faces). One-sided because the body under
    the garment is not seen. Points farther than `trim_distance` (m; stray fragments, hair) are
    ignored. The gradient is exact: at a fixed closest point on a face the squared distance's
    derivative w.r.t. the face's vertices is −2 b_k (p − c) (the closest point is optimal)."""
    X, F = val.mesh("X", X, "F", F)
    P = val.points("points", points)
    grad = np.zeros_like(X)
    if not len(P):
        return BodyDataLoss(0.0, 0, grad)
    tri, bary, cp = _core.closest_points_on_mesh(X, F, np.ascontiguousarray(P))
    r = P - np.asarray(cp)
    d2 = (r * r).sum(1)
    keep = d2 < trim_distance ** 2 if trim_distance > 0 else np.ones(len(P), bool)
    n = len(P)
    Fi = F[np.asarray(tri)[keep]]
    contrib = -2.0 * np.asarray(bary)[keep][:, :, None] * r[keep][:, None, :] / n
    np.add.at(grad, Fi.reshape(-1), contrib.reshape(-1, 3))
    return BodyDataLoss(float(d2[keep].sum() / n), int(keep.sum()), grad)
