"""The subject's facing (a turn about the vertical, Y). The core frame has the body face +Z with
+X its left; a scan from a rig whose subject faces elsewhere is turned to that frame once the
body fit has found the facing (scan openings are named by rules that take +X as the left,
templates are laid out facing +Z), and the recovery's outputs are turned back, so the assets
overlay the scan as given. Angles in rad, lengths in m."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..body.params import BodyParams

#: rad: a fitted facing farther than this from +Z is turned to it (smaller ones the rules absorb)
FACING_TURN = np.radians(20.0)


def yaw_rotation(angle: float) -> np.ndarray:
    """(3, 3) proper rotation by `angle` (rad) about +Y: +Z turns towards +X."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def facing_yaw(params: BodyParams) -> float:
    """Angle (rad, in (−π, π]) about +Y from +Z to the direction the fitted body faces: its
    global rotation applied to the model's forward +Z, projected on the floor."""
    f = Rotation.from_rotvec(np.asarray(params.rotation, np.float64)).as_matrix()[:, 2]
    return float(np.arctan2(f[0], f[2]))


def turned_params(params: BodyParams, Q) -> BodyParams:
    """The same body after the world is rotated by Q (3, 3) about the origin: posed vertices
    X ↦ Q X. The global transform X = R x + t becomes (Q R) x + Q t; shape, joints and bone
    scales are unchanged."""
    Q = np.asarray(Q, np.float64)
    p = params.copy()
    R = Rotation.from_rotvec(np.asarray(params.rotation, np.float64)).as_matrix()
    p.rotation = Rotation.from_matrix(Q @ R).as_rotvec()
    p.translation = Q @ np.asarray(params.translation, np.float64)
    return p
