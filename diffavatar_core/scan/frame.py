"""Conversion of a scan's own frame (units cm|m|mm, up axis y|z) into the core frame:
metres, Y up, the body faces +Z, +X is the body's left (see diffavatar_core/landmarks.py).

The conversion is a uniform scale, a proper rotation and, for a scan far from its file's origin,
a shift:
    p_core = scale · R · p_scan − origin        (p: (3,) points as rows; scale in m per scan unit)
A Z-up scan is rotated -90° about X, (x, y, z) → (x, z, -y): its +Z becomes +Y and its -Y
(the forward direction of Z-up tools such as Blender) becomes +Z, so +X stays the body's left.
up = -y / -z: a file whose up is its −Y / −Z, turned 180° about X more ((x, y, z) → (x, −y, −z) /
(x, −z, y)).
origin (m, core axes) is 0 unless the subject stands farther than FAR_FROM_ORIGIN from the file's
origin (a rig whose origin is a room's corner; check_scan, centring_origin: the floor below the
subject, rounded to whole metres): the drapes' single-precision sweeps resolve 0.24 µm at 2 m but
3.6 µm at 30 m, where the sample scan's initial drape no longer converged. Results are placed
back with to_scan or by adding origin.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .boundary import LoopGeometry
from .errors import BadOptionError, ImplausibleSizeError

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
FAR_FROM_ORIGIN = 2.0   # m: a scan whose floor below the subject (centring_origin) is farther on some axis is centred
UP_ROTATIONS = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    # upside-down files (Y down: the camera frame of OpenCV and most photogrammetry; Z down): the
    # same frames turned 180° about X, so −Y / −Z becomes +Y (both proper rotations)
    "-y": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
    "-z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
}
UP_AXES = tuple(UP_ROTATIONS)   # the `up` option's values ("-y" on a command line: --up=-y)
FLIPPED_UP = {"y": "-y", "-y": "y", "z": "-z", "-z": "z"}   # the same axis pointing the other way


@dataclass(frozen=True)
class ScanTransform:
    """p_core = scale · rotation · p_scan − origin. scale: metres per scan unit; rotation: (3, 3)
    proper rotation; units/up: the scan's own units and up axis it was made from; origin (3,) m:
    where in the converted scan the core frame's origin lies (zero unless shifted())."""
    scale: float
    rotation: np.ndarray
    units: str = "m"
    up: str = "y"
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def from_options(cls, units: str = "m", up: str = "y") -> "ScanTransform":
        """units: m, cm or mm; up: y, z, -y or -z (case and surrounding spaces ignored; empty = m / y).
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
        Q = np.asarray(Q, np.float64)
        return ScanTransform(self.scale, Q @ self.rotation, self.units, self.up, Q @ self.origin)

    def shifted(self, origin) -> "ScanTransform":
        """This transform with the converted point `origin` (3,) m as the core frame's origin."""
        return ScanTransform(self.scale, self.rotation, self.units, self.up, np.asarray(origin, np.float64).copy())

    def to_core(self, points) -> np.ndarray:
        """(N, 3) scan-frame points (scan units) → core frame (m)."""
        P = self.scale * (np.asarray(points, dtype=np.float64) @ self.rotation.T)
        return P - self.origin if self.origin.any() else P

    def to_scan(self, points) -> np.ndarray:
        """(N, 3) core-frame points (m) → the scan's own frame and units (inverse of to_core)."""
        P = np.asarray(points, dtype=np.float64)
        if self.origin.any():
            P = P + self.origin
        return (P @ self.rotation) / self.scale

    def to_dict(self) -> dict:
        return {"scale_m_per_unit": self.scale, "rotation": self.rotation.tolist(),
                "units": self.units, "up": self.up, "origin_m": self.origin.tolist()}


def centring_origin(V_core: np.ndarray) -> np.ndarray:
    """(3,) m: the origin check_scan shifts a scan to — below the subject on the floor: the median
    vertex's x and z and the lowest percent's y (a floor below a scan's fragments), rounded to
    whole metres, when one of them lies farther than FAR_FROM_ORIGIN from 0; else zero (a scan
    near its file's origin keeps its coordinates, bit for bit). The core frame then stands the
    subject as a rig with its origin on the floor would."""
    V = np.asarray(V_core, np.float64)
    c = np.array([np.median(V[:, 0]), np.percentile(V[:, 1], 1.0), np.median(V[:, 2])])
    return np.round(c) if np.abs(c).max() > FAR_FROM_ORIGIN else np.zeros(3)


#: a garment whose highest opening (waist, neckline) is longer than this × its hem hangs upside down
UPSIDE_DOWN_OPENINGS = 1.25


def upside_down_hint(boundaries: dict, transform: ScanTransform) -> str:
    """'' unless the garment's highest opening (waist or neckline: the highest central loop, as
    scan/boundary.py names them) is more than UPSIDE_DOWN_OPENINGS × as long as its hem (the
    lowest) — a skirt or top is narrower at its waist or neck than at its hem; the bundled skirt
    read upside down had a 140 cm 'waist' over a 77 cm 'hem' and recovered 2.5 cm off without a
    word — else a hint naming both lengths and the up axis that turns the scan over.
    boundaries: {opening name: (K, 3) closed loop, m}."""
    top = next((k for k in ("waist", "neckline") if k in boundaries), None)
    if top is None or "hem" not in boundaries:
        return ""
    lt, lh = (LoopGeometry.of(np.asarray(boundaries[k], np.float64)).perimeter for k in (top, "hem"))
    if not lt > UPSIDE_DOWN_OPENINGS * lh:
        return ""
    other = FLIPPED_UP[transform.up]
    return (f"the garment's highest opening ('{top}', {100 * lt:.0f} cm around) is {lt / lh:.1f}× as long as its "
            f"lowest ('hem', {100 * lh:.0f} cm): is the scan upside down? up={other} reads it turned over (on the "
            f"command line --up={other})")


def lying_hint(V_core: np.ndarray, transform: ScanTransform) -> str:
    """'' for a scan that stands, else a hint that its up axis may be wrong, naming the other
    one and the height it would give (core-frame vertices, m, as converted from the scan). A
    person or a worn garment is taller than at least one of its horizontal extents (a t-shirt's
    sleeves make it wide, not deep); a scan more than 1.2 × as wide and as deep as it is tall is
    likely lying — a Z-up file read as Y-up — though its size is plausible."""
    ext = V_core.max(axis=0) - V_core.min(axis=0)
    if min(ext[0], ext[2]) <= 1.2 * ext[1]:
        return ""
    other = "z" if transform.up in ("y", "-y") else "y"
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
    other_up = "z" if transform.up in ("y", "-y") else "y"
    alt = raw_ext[2] * transform.scale  # the scan's other candidate up axis
    if not hints and min_height <= alt <= max_height:
        hints.append(f"up={other_up} would make it {alt:.3g} m tall")
    raise ImplausibleSizeError(
        f"scan is {height:.4g} m tall (extent {ext[0]:.4g} × {ext[1]:.4g} × {ext[2]:.4g} m in "
        f"x × y(up) × z) after converting from units={transform.units}, up={transform.up}: outside "
        f"the plausible range for a person or garment, {min_height}–{max_height} m"
        + (f" ({'; '.join(hints)})" if hints else ""))
