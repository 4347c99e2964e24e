"""Cameras for the headless renderer: a small value type and the standard 4-view orbit
(front/right/back/left around a scene's bounding box, Y up). Positions in m, angles in rad."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate

VIEW_NAMES = ("front", "right", "back", "left")


@dataclass(frozen=True)
class Camera:
    """Camera at `eye` (m) looking at `target` (m), `up` the approximate up direction.
    Perspective with vertical field of view `fov_y` (rad), or orthographic when `orthographic`
    with a view `ortho_height` m tall. Geometry nearer than `near` m is not drawn (perspective)."""
    eye: tuple
    target: tuple
    up: tuple = (0.0, 1.0, 0.0)
    orthographic: bool = False
    fov_y: float = 0.6
    ortho_height: float = 2.0
    near: float = 1e-3

    def __post_init__(self):
        for name in ("eye", "target", "up"):
            v = np.asarray(getattr(self, name), dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"camera.{name}: expected 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        d = np.subtract(self.target, self.eye)
        if np.linalg.norm(d) == 0.0:
            raise ValueError("camera.eye: coincides with camera.target")
        if np.linalg.norm(np.cross(d / np.linalg.norm(d), self.up)) < 1e-9:
            raise ValueError("camera.up: parallel to the view direction")
        if not self.orthographic and not (0.0 < self.fov_y < math.pi):
            raise ValueError(f"camera.fov_y: expected a value in (0, pi) rad, got {self.fov_y}")
        if self.orthographic and not self.ortho_height > 0.0:
            raise ValueError(f"camera.ortho_height: expected > 0 m, got {self.ortho_height}")
        if not self.near > 0.0:
            raise ValueError(f"camera.near: expected > 0 m, got {self.near}")


def scene_bounds(meshes) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounding box (lo, hi), m, of the vertices of all meshes ((V, F[, colour]) items)."""
    pts = [_validate.points(f"meshes[{i}].V", m[0]) for i, m in enumerate(meshes)]
    if not pts:
        raise ValueError("meshes: is empty")
    allp = np.concatenate(pts)
    return allp.min(axis=0), allp.max(axis=0)


def orbit_cameras(meshes, *, fov_y: float = 0.6, margin: float = 1.05, orthographic: bool = False,
                  views=VIEW_NAMES) -> dict[str, Camera]:
    """Cameras around the bounding box of `meshes`, Y up, looking at the box centre c, at
    azimuths front (+Z side, looking towards −Z), right (+X), back (−Z), left (−X).

    The bounding sphere of the box (radius R = half its diagonal) fits the image:
    perspective eye distance R·margin / sin(fov_y/2); orthographic height 2R·margin. The same
    meshes always give the same cameras, so two scenes rendered with cameras from their union
    are compared under identical conditions."""
    lo, hi = scene_bounds(meshes)
    c = 0.5 * (lo + hi)
    R = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    dirs = {"front": (0.0, 0.0, 1.0), "right": (1.0, 0.0, 0.0), "back": (0.0, 0.0, -1.0), "left": (-1.0, 0.0, 0.0)}
    out = {}
    for name in views:
        if name not in dirs:
            raise ValueError(f"views: unknown view {name!r}; expected some of {VIEW_NAMES}")
        d = np.array(dirs[name])
        if orthographic:
            eye = c + d * (3.0 * R)
            out[name] = Camera(tuple(eye), tuple(c), orthographic=True, ortho_height=2.0 * R * margin)
        else:
            dist = R * margin / math.sin(0.5 * fov_y)
            out[name] = Camera(tuple(c + d * dist), tuple(c), fov_y=fov_y)
    return out
