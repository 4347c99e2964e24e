"""Structural similarity (SSIM) of Wang, Bovik, Sheikh and Simoncelli, "Image quality
assessment: from error visibility to structural similarity", IEEE TIP 13(4), 2004 — the
perceptual metric of the paper's Table 1 — on luminance, with the paper's settings: an 11×11
circular-symmetric Gaussian window (σ = 1.5 px, normalized to sum 1), K1 = 0.01, K2 = 0.03,
dynamic range L (255 for 8-bit images), statistics over 'valid' window positions only.

    SSIM(x, y) = (2 μx μy + C1)(2 σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2)),
    C1 = (K1 L)², C2 = (K2 L)²  (eq. 13 of Wang et al.), averaged over windows (mean SSIM, eq. 17).
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import correlate1d

WINDOW = 11
SIGMA = 1.5
K1, K2 = 0.01, 0.03


def luminance(img) -> np.ndarray:
    """Luma Y = 0.299 R + 0.587 G + 0.114 B (ITU-R BT.601, as MATLAB's rgb2gray used by the
    reference implementation) of an H×W×3 image, float64; an H×W image is returned as float64."""
    a = np.asarray(img)
    if a.ndim == 2:
        return a.astype(np.float64)
    if a.ndim == 3 and a.shape[2] == 3:
        return a.astype(np.float64) @ np.array([0.299, 0.587, 0.114])
    raise ValueError(f"img: expected an H×W or H×W×3 image, got shape {a.shape}")


def _gaussian() -> np.ndarray:
    x = np.arange(WINDOW) - (WINDOW - 1) / 2
    g = np.exp(-x * x / (2 * SIGMA * SIGMA))
    return g / g.sum()


def _filter_valid(a: np.ndarray, g: np.ndarray) -> np.ndarray:
    r = (WINDOW - 1) // 2
    out = correlate1d(correlate1d(a, g, axis=0, mode="constant"), g, axis=1, mode="constant")
    return out[r:-r, r:-r]


def ssim_map(img1, img2, data_range: float = 255.0) -> np.ndarray:
    """Local SSIM at every valid 11×11 window position: (H−10)×(W−10) float64."""
    x, y = luminance(img1), luminance(img2)
    if x.shape != y.shape:
        raise ValueError(f"img2: shape {y.shape} differs from img1's {x.shape}")
    if min(x.shape) < WINDOW:
        raise ValueError(f"img1: images must be at least {WINDOW}×{WINDOW} pixels, got {x.shape}")
    if not data_range > 0:
        raise ValueError(f"data_range: expected > 0, got {data_range}")
    g = _gaussian()
    mx, my = _filter_valid(x, g), _filter_valid(y, g)
    sxx = _filter_valid(x * x, g) - mx * mx
    syy = _filter_valid(y * y, g) - my * my
    sxy = _filter_valid(x * y, g) - mx * my
    C1, C2 = (K1 * data_range) ** 2, (K2 * data_range) ** 2
    return ((2 * mx * my + C1) * (2 * sxy + C2)) / ((mx * mx + my * my + C1) * (sxx + syy + C2))


def ssim(img1, img2, data_range: float = 255.0) -> float:
    """Mean SSIM of two images of equal shape (H×W luminance or H×W×3 RGB, both ≥ 11×11);
    1 for identical images, symmetric, ≤ 1."""
    return float(ssim_map(img1, img2, data_range).mean())
