"""Input validation for the core: every public function passes its arrays through these, so
the C++ side receives float64/int32 C-contiguous arrays (mapped without copies) and a bad
input raises ValueError naming the offending argument instead of crashing."""
from __future__ import annotations

import numpy as np


def points(name: str, a, dims: int = 3, allow_empty: bool = False) -> np.ndarray:
    """An (N, dims) float64 C-contiguous array of finite values (a copy only if dtype/layout differ)."""
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not a numeric array ({exc})") from None
    if arr.ndim != 2 or arr.shape[1] != dims:
        raise ValueError(f"{name}: expected shape (N, {dims}), got {arr.shape}")
    if arr.shape[0] == 0 and not allow_empty:
        raise ValueError(f"{name}: is empty")
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr).all(axis=1)))
        raise ValueError(f"{name}: {bad} row(s) contain NaN or Inf")
    return np.ascontiguousarray(arr)


def faces(name: str, f, n_vertices: int, allow_empty: bool = False) -> np.ndarray:
    """An (F, 3) int32 C-contiguous array of indices into n_vertices vertices, no repeated
    index within a face."""
    arr = np.asarray(f)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (F, 3), got {arr.shape}")
    if arr.shape[0] == 0:
        if allow_empty:
            return np.zeros((0, 3), np.int32)
        raise ValueError(f"{name}: has no triangles")
    if not np.issubdtype(arr.dtype, np.integer):
        if not np.issubdtype(arr.dtype, np.floating) or not np.all(np.mod(arr, 1) == 0):
            raise ValueError(f"{name}: indices must be integers, got dtype {arr.dtype}")
    lo, hi = int(arr.min()), int(arr.max())
    if lo < 0 or hi >= n_vertices:
        raise ValueError(f"{name}: index out of range [0, {n_vertices}): min {lo}, max {hi}")
    arr = np.ascontiguousarray(arr, dtype=np.int32)
    degenerate = (arr[:, 0] == arr[:, 1]) | (arr[:, 1] == arr[:, 2]) | (arr[:, 0] == arr[:, 2])
    if degenerate.any():
        raise ValueError(f"{name}: {int(degenerate.sum())} face(s) repeat a vertex index "
                         f"(first: face {int(np.flatnonzero(degenerate)[0])})")
    return arr


def mesh(vname: str, v, fname: str, f, dims: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Validated (V, F) pair; a 2D pattern (dims=2) is lifted to z = 0 for 3D kernels."""
    V = points(vname, v, dims=dims)
    F = faces(fname, f, V.shape[0])
    if dims == 2:
        V = np.ascontiguousarray(np.column_stack([V, np.zeros(len(V))]))
    return V, F


def positive_int(name: str, n) -> int:
    try:
        k = int(n)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a positive integer, got {n!r}") from None
    if k <= 0 or k != n:
        raise ValueError(f"{name}: expected a positive integer, got {n!r}")
    return k


def friction(mu) -> float:
    """A Coulomb coefficient (dimensionless): a finite number >= 0, else ValueError naming it."""
    try:
        v = float(mu)
    except (TypeError, ValueError):
        raise ValueError(f"friction: expected a Coulomb coefficient >= 0 (dimensionless), got {mu!r}") from None
    if isinstance(mu, (bool, str)) or not (np.isfinite(v) and v >= 0):
        raise ValueError(f"friction: expected a Coulomb coefficient >= 0 (dimensionless), got {mu!r}")
    return v


def is_cancelled(cancel) -> bool:
    """Whether `cancel` — None, a CancelToken, a threading.Event, or anything with a
    `cancelled` flag — asks to stop."""
    if cancel is None:
        return False
    return bool(cancel.is_set()) if hasattr(cancel, "is_set") else bool(getattr(cancel, "cancelled", False))


def check_cancel(cancel, stage: str) -> None:
    """Raises diffavatar_core.Cancelled("cancelled during <stage>") when `cancel` is set: the
    check of the Python-level loops (the C++ ones take a CancelToken directly)."""
    if is_cancelled(cancel):
        from ._core import Cancelled
        raise Cancelled(f"cancelled during {stage}")
