"""Body landmarks and girths measured on a posed body (diffavatar_core.landmarks.BodyLandmarks).

Girths are tape measures: the perimeter of the convex hull of the torso's cross-section by a
plane perpendicular to the body's up axis (arms excluded; the hip slice includes the thighs,
as a tape around the buttocks does). Heights of the slices, in the body frame (the global
rotation undone, floor = lowest vertex):
  chest: the largest girth between the spine_4 and clavicle joint heights (bust line),
  waist: the smallest girth between the hip-joint and chest-joint heights,
  hip:   the largest girth between 15 cm below the hip joints and the pelvis joint.
Positions are in m in the world frame; girths and height in m.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from ..landmarks import BodyLandmarks

_ARM_JOINTS = ("shoulder", "elbow", "wrist")
_LEG_JOINTS = ("knee", "ankle")


def _rotation(r) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    return Rotation.from_rotvec(np.asarray(r, np.float64)).as_matrix()


def _slice_hull(V, edges, y):
    """Convex hull (2D points in x-z, perimeter, centroid) of the mesh edges crossing y."""
    a, b = V[edges[:, 0]], V[edges[:, 1]]
    da, db = a[:, 1] - y, b[:, 1] - y
    cross = (da * db) < 0
    if np.count_nonzero(cross) < 3:
        return None
    t = (da[cross] / (da[cross] - db[cross]))[:, None]
    p = a[cross] + t * (b[cross] - a[cross])
    pts = p[:, [0, 2]]
    try:
        hull = ConvexHull(pts)
    except Exception:  # degenerate slice (collinear points)
        return None
    poly = pts[hull.vertices]
    q = np.roll(poly, -1, axis=0)
    cr = poly[:, 0] * q[:, 1] - q[:, 0] * poly[:, 1]
    area = cr.sum() / 2
    c = ((poly + q) * cr[:, None]).sum(axis=0) / (6 * area) if abs(area) > 1e-12 else poly.mean(axis=0)
    return float(hull.area), np.array([c[0], y, c[1]])   # 2D hull "area" is its perimeter


def _scan(V, edges, y0, y1, pick, n=24):
    best = None
    for y in np.linspace(y0, y1, n):
        s = _slice_hull(V, edges, y)
        if s is None:
            continue
        if best is None or (s[0] > best[0] if pick == "max" else s[0] < best[0]):
            best = s
    if best is None:
        raise ValueError(f"body cross-section between heights {y0:.3f} and {y1:.3f} m is empty")
    return best


def body_landmarks(model, params) -> BodyLandmarks:
    names = model.joint_names
    need = ["pelvis", "spine_4", "chest", "neck", "clavicle_left", "shoulder_left", "shoulder_right",
            "elbow_left", "elbow_right", "wrist_left", "wrist_right", "hip_left", "hip_right",
            "knee_left", "knee_right", "ankle_left", "ankle_right"]
    missing = [n for n in need if n not in names]
    if missing:
        raise ValueError(f"landmarks need the default skeleton's joints; model {model.name!r} lacks {missing}")
    R = _rotation(params.rotation)
    t = params.translation
    Vw = model.pose(params)
    Jw = model.joints(params)
    # body frame: undo the global transform (Y up there)
    V = (Vw - t) @ R
    J = (Jw - t) @ R
    j = {n: J[i] for i, n in enumerate(names)}
    dom = np.argmax(model.weights, axis=1)
    arm = np.isin(dom, [i for i, n in enumerate(names) if n.startswith(_ARM_JOINTS)])
    leg = np.isin(dom, [i for i, n in enumerate(names) if n.startswith(_LEG_JOINTS)])
    F = model.faces

    def edges_of(mask_v):
        f = F[mask_v[F].all(axis=1)]
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        return np.unique(np.sort(e, axis=1), axis=0)

    torso_edges = edges_of(~arm & ~leg)
    hip_edges = edges_of(~arm)
    chest_g, chest_c = _scan(V, torso_edges, j["spine_4"][1], j["clavicle_left"][1] - 0.03, "max")
    waist_g, waist_c = _scan(V, torso_edges, j["hip_left"][1] + 0.03, j["chest"][1], "min")
    hip_y = 0.5 * (j["hip_left"][1] + j["hip_right"][1])
    hip_g, hip_c = _scan(V, hip_edges, hip_y - 0.15, j["pelvis"][1], "max")

    def acromion(side):
        s = j[f"shoulder_{side}"]
        near = np.linalg.norm(V - s, axis=1) < 0.08
        top = V[near][np.argmax(V[near][:, 1])]
        return np.array([s[0], top[1], s[2]])

    world = lambda p: R @ p + t  # noqa: E731
    return BodyLandmarks(
        height=float(V[:, 1].max() - V[:, 1].min()),
        chest_girth=chest_g, waist_girth=waist_g, hip_girth=hip_g,
        neck_base=world(j["neck"]),
        shoulder_left=world(acromion("left")), shoulder_right=world(acromion("right")),
        elbow_left=world(j["elbow_left"]), elbow_right=world(j["elbow_right"]),
        wrist_left=world(j["wrist_left"]), wrist_right=world(j["wrist_right"]),
        chest_center=world(chest_c), waist_center=world(waist_c), hip_center=world(hip_c),
        knee_left=world(j["knee_left"]), knee_right=world(j["knee_right"]),
        ankle_left=world(j["ankle_left"]), ankle_right=world(j["ankle_right"]),
    )
