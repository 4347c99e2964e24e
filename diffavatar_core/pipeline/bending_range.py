"""The bendings the scan does not tell apart from the recovered one. A 4 cm drape's fold state moves
φ as much as a decade of bending stiffness does on soft fabrics (BENCHMARKS.md stops 49–51), so the
recovered k_b (N·m) comes with the range its own judging cannot exclude: at the recovered pattern
and body, k_b × 10^±d for each d of opts.bending_range_offsets, each judged as a check judges a
bending candidate (CoOptObjective.try_bending, opts.bending_compare) against the recovered
bending's φ. An offset judged worse by more than opts.bending_margin (the spread of re-drapes of one
θ) is excluded; the range ends at the first excluded offset on each side, and is open (None) on a
side where none is — nothing tried there was judged worse, or nothing could be tried (outside
BENDING_RANGE, or no equilibrium). Run on a twin of the objective: the recovery's own state, drape
and results stay as they are, bit for bit."""
from __future__ import annotations

import time

import numpy as np


def _offsets(offsets) -> list:
    """±d for each d > 0, nearest first on each side (the order the range is walked in)."""
    ds = sorted({abs(float(d)) for d in offsets if d})
    return [s * d for d in ds for s in (1.0, -1.0)]


def verdict(value: float, against: float, margin: float) -> str:
    """A candidate's φ against the recovered bending's: 'worse' beyond (1 + margin)·against,
    'better' below (1 − margin)·against (what try_bending would keep), else 'alike'."""
    return "worse" if value > (1.0 + margin) * against else "better" if value < (1.0 - margin) * against else "alike"


def range_ends(offsets, verdicts: dict, b: float) -> tuple:
    """(low, high) N·m: b × 10^d at the first offset d on each side (nearest first) whose verdict
    is 'worse'; None where none is. verdicts: {d: verdict} of the offsets judged (others skipped)."""
    ends = []
    for side in (-1.0, 1.0):
        d = next((d for d in sorted(offsets, key=abs) if d * side > 0 and verdicts.get(d) == "worse"), None)
        ends.append(None if d is None else b * 10.0 ** d)
    return tuple(ends)


def bending_range(obj, params, offsets, margin: float, known=None) -> dict | None:
    """The range of the bending stiffness (N·m) that CoOptObjective `obj` judges no worse than the
    one of `params` (module docstring). Returns None without offsets, without a bending parameter,
    or when φ at `params` has no finite value; else {'bending_Nm': the recovered k_b (geometric mean
    over the material groups), 'low_Nm' / 'high_Nm': the range's ends (None: open), 'margin',
    'value': φ at params from its warm drape, 'judged': [[d decades, k_b N·m, φ judged, φ it is
    judged against, verdict] per offset judged, by d], 'wall_s': its time}. Offsets apply to every
    group alike (log10 k_b + d). known: (φ at params, try_bending's last_bending_judged) of a
    try_bending at `params` from obj's warm start that kept nothing — its value and the candidates
    at these offsets are taken as judged (the same re-drapes bit for bit), the others judged here."""
    ds = _offsets(offsets)
    if not ds or "log_bend" not in params:
        return None
    t0 = time.perf_counter()
    twin = obj.twin()
    value, prior = known if known is not None else (None, [])
    if value is None:
        value = twin._value_or_inf(params)   # the recovered θ re-draped from its warm drape, as a check starts
    if not np.isfinite(value):
        return None
    log_b = np.asarray(params["log_bend"], np.float64).reshape(-1)

    judged = {}

    def record(candidates):   # (the first group's k_b, φ judged, φ against) → judged[its offset d]
        for kb, v, against in candidates:
            d = float(np.log10(kb) - log_b[0])
            near = min(ds, key=lambda e: abs(e - d))
            if abs(near - d) < 1e-9:   # a prior check's candidate at another offset is not one of ours
                judged[near] = [near, kb, v, against, verdict(v, against, margin)]
    record(prior)
    rest = [d for d in ds if d not in judged]
    if rest:
        twin.try_bending(params, rest, current=value)
        record(twin.last_bending_judged)
    b = float(10.0 ** log_b.mean())
    low, high = range_ends(ds, {d: j[4] for d, j in judged.items()}, b)
    return {"bending_Nm": b, "low_Nm": low, "high_Nm": high, "margin": float(margin),
            "value": float(value), "judged": [judged[d] for d in sorted(judged)], "wall_s": time.perf_counter() - t0}


__all__ = ["bending_range"]
