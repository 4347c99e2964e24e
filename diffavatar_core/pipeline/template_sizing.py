"""Template sizing from the scan's openings: a first estimate of a built-in template's length and
sleeve length (m), read off where the scan's openings are against where the template's initial
drape put them, before the measurement fit (measurement_fit.py) refines every measurement through
the adjoint.

The fit starts from the template's warm-started drape, and a cloth carried along by warm starts
keeps its fold state: a sleeve 8 cm too long ends in a cuff flapping past the hand, whose drape
the gradient cannot shorten out of (the benchmark's long sleeve stopped at 0.523 m, truth 0.495,
the template 0.58; docs/pipeline.md). Here the template is re-made at the estimated
measurements and draped fresh instead, as the template itself was; the recovery starts from it
when that drape is nearer the scan (Chamfer distance): a stuck fit shows as a drape far from the
scan, and the folds of the nearer start are those no gradient step would find.

First-order model (inextensible cloth hanging from the body): an opening that hangs Δ farther
along the body needs Δ more cloth above it.
- length (tops, dress, skirt): the hem's mean height; the garment hangs from the shoulders or the
  waist, so m = m₀ + (y_hem, template drape − y_hem, scan).
- sleeve_length (tops, dress): a cuff's centre's distance from its shoulder landmark (the sleeve
  hangs from the shoulder), m = m₀ + (d_scan − d_template), averaged over the sides found in both.
One step can fall short — a long sleeve 7 cm too long moved its cuff 4.6 cm (it bunches at the
wrist) — so the recovery applies it again from the re-made template's drape (SIZING_ROUNDS).
Estimates move a measurement by at most MAX_CHANGE of its template value (a badly segmented
opening must not remake the garment into something else). Units: m, core frame (Y up)."""
from __future__ import annotations

import numpy as np

from ..pattern.templates import FIT_MEASUREMENTS, default_landmarks, template_measurements

MAX_CHANGE = 0.3    # an estimate stays within ×(1 ± this) of the template's value
MIN_CHANGE = 0.005  # m: smaller estimated changes are not worth another drape
SIZING_ROUNDS = 2   # re-made and re-draped at most this many times (each from the last one's drape)


def _centre(points) -> np.ndarray:
    return np.asarray(points, float).reshape(-1, 3).mean(axis=0)


def size_from_openings(name: str, landmarks, x, garment_loops: dict, scan_loops: dict,
                       measurements: dict | None = None) -> dict:
    """{measurement: estimate (m)} for built-in template `name` on a body with `landmarks`
    (BodyLandmarks; None: the templates' default body's), from its drape x (V, 3) m made with the
    default measurements overridden by `measurements` (m; a previous estimate: applied again, the
    estimate converges as a fixed-point iteration where one step falls short, e.g. a long sleeve
    bunching at the wrist) — garment_loops: opening name → vertex indices of x — against the
    scan's openings scan_loops (name → (K, 3) m). Only measurements the template fits
    (FIT_MEASUREMENTS) whose opening both sides show, and whose estimate moves them by at least
    MIN_CHANGE from the drape's; bounded to ×(1 ± MAX_CHANGE) of the template's default; empty
    when nothing is to be changed."""
    if name not in FIT_MEASUREMENTS:
        return {}
    fitted = FIT_MEASUREMENTS[name]
    landmarks = landmarks or default_landmarks()
    default = template_measurements(name, landmarks)
    m0 = template_measurements(name, landmarks, **(measurements or {}))
    x = np.asarray(x, float)
    both = set(garment_loops) & set(scan_loops)
    out = {}
    if "length" in fitted and "hem" in both:
        drop = _centre(x[np.asarray(garment_loops["hem"])])[1] - _centre(scan_loops["hem"])[1]
        out["length"] = float(m0.length) + float(drop)
    if "sleeve_length" in fitted and float(getattr(m0, "sleeve_length", 0.0)) > 0:
        deltas = []
        for side in ("left", "right"):
            key = f"sleeve_{side}"
            if key in both:
                shoulder = np.asarray(getattr(landmarks, f"shoulder_{side}"), float)
                d_scan = np.linalg.norm(_centre(scan_loops[key]) - shoulder)
                d_tpl = np.linalg.norm(_centre(x[np.asarray(garment_loops[key])]) - shoulder)
                deltas.append(d_scan - d_tpl)
        if deltas:
            out["sleeve_length"] = float(m0.sleeve_length) + float(np.mean(deltas))
    sized = {}
    for k, v in out.items():
        base, now = float(getattr(default, k)), float(getattr(m0, k))
        v = float(np.clip(v, (1 - MAX_CHANGE) * base, (1 + MAX_CHANGE) * base))
        if np.isfinite(v) and abs(v - now) >= MIN_CHANGE:
            sized[k] = v
    return sized


__all__ = ["size_from_openings", "MAX_CHANGE", "MIN_CHANGE", "SIZING_ROUNDS"]
