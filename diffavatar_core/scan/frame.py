"""Conversion of a scan's own frame (units cm|m|mm, up axis y|z) into the core frame:
metres, Y up, the body faces +Z, +X is the body's left (see diffavatar_core/landmarks.py).

The conversion is a uniform scale and a proper rotation, no translation:
    p_core = scale · R · p_scan        (p: (3,) points as rows; scale in m per scan unit)
A Z-up scan is rotated -90° about X, (x, y, z) → (x, z, -y): its +Z becomes +Y and its -Y
(the forward direction of Z-up tools such as Blender) becomes +Z, so +X stays the body's left.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import BadOptionError, ImplausibleSizeError

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
UP_ROTATIONS = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}


@dataclass(frozen=True)
class ScanTransform:
    """p_core = scale · rotation · p_scan. scale: metres per scan unit; rotation: (3, 3) proper
    rotation; units/up: the scan's own units and up axis it was made from."""
    scale: float
    rotation: np.ndarray
    units: str = "m"
    up: str = "y"

    @classmethod
    def from_options(cls, units: str = "m", up: str = "y") -> "ScanTransform":
        """units: m, cm or mm; up: y or z (case and surrounding spaces ignored; empty = m / y).
        Raises BadOptionError naming the option."""
        u = str(units).strip().lower() or "m"
        a = str(up).strip().lower() or "y"
        if u not in UNITS:
            raise BadOptionError(f"units: expected one of {', '.join(UNITS)}, got {units!r}")
        if a not in UP_ROTATIONS:
            raise BadOptionError(f"up axis (up_axis): expected one of {', '.join(UP_ROTATIONS)}, got {up!r}")
        return cls(UNITS[u], UP_ROTATIONS[a].copy(), u, a)

    def turned(self, Q) -> "ScanTransform":
        """This transform followed by the proper rotation Q (3, 3) of the core frame — a turn
        about the vertical that makes the subject face +Z (the recovery's facing)."""
        return ScanTransform(self.scale, np.asarray(Q, np.float64) @ self.rotation, self.units, self.up)

    def to_core(self, points) -> np.ndarray:
        """(N, 3) scan-frame points (scan units) → core frame (m)."""
        P = np.asarray(points, dtype=np.float64)
        return self.scale * (P @ self.rotation.T)

    def to_scan(self, points) -> np.ndarray:
        """(N, 3) core-frame points (m) → the scan's own frame and units (inverse of to_core)."""
        P = np.asarray(points, dtype=np.float64)
        return (P @ self.rotation) / self.scale

    def to_dict(self) -> dict:
        return {"scale_m_per_unit": self.scale, "rotation": self.rotation.tolist(),
                "units": self.units, "up": self.up}


def lying_hint(V_core: np.ndarray, transform: ScanTransform) -> str:
    """'' for a scan that stands, else a hint that its up axis may be wrong, naming the other
    one and the height it would give (core-frame vertices, m, as converted from the scan). A
    person or a worn garment is taller than at least one of its horizontal extents (a t-shirt's
    sleeves make it wide, not deep); a scan more than 1.2 × as wide and as deep as it is tall is
    likely lying — a Z-up file read as Y-up — though its size is plausible."""
    ext = V_core.max(axis=0) - V_core.min(axis=0)
    if min(ext[0], ext[2]) <= 1.2 * ext[1]:
        return ""
    other = "z" if transform.up == "y" else "y"
    return (f"the scan is {ext[1]:.3g} m tall but {ext[0]:.3g} m wide and {ext[2]:.3g} m deep — lying? "
            f"up={other} would make it {ext[2]:.3g} m tall")


def check_plausible_size(V_core: np.ndarray, transform: ScanTransform, min_height: float,
                         max_height: float) -> float:
    """Height (Y extent, m) of core-frame vertices; raises ImplausibleSizeError when it is
    outside [min_height, max_height] or a horizontal extent exceeds max_height, saying which
    units / up axis would have been plausible."""
    ext = V_core.max(axis=0) - V_core.min(axis=0)
    height = float(ext[1])
    if min_height <= height <= max_height and float(ext.max()) <= max_height:
        return height
    raw_ext = ext / transform.scale  # extents in scan units, core axis order
    hints = []
    for u, s in UNITS.items():
        if u != transform.units and min_height <= raw_ext[1] * s <= max_height and raw_ext.max() * s <= max_height:
            hints.append(f"units={u} would make it {raw_ext[1] * s:.3g} m tall")
    other_up = "z" if transform.up == "y" else "y"
    alt = raw_ext[2] * transform.scale  # the scan's other candidate up axis
    if not hints and min_height <= alt <= max_height:
        hints.append(f"up={other_up} would make it {alt:.3g} m tall")
    raise ImplausibleSizeError(
        f"scan is {height:.4g} m tall (extent {ext[0]:.4g} × {ext[1]:.4g} × {ext[2]:.4g} m in "
        f"x × y(up) × z) after converting from units={transform.units}, up={transform.up}: outside "
        f"the plausible range for a person or garment, {min_height}–{max_height} m"
        + (f" ({'; '.join(hints)})" if hints else ""))
