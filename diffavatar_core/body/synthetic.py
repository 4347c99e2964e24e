"""Bodies and garment-only scans with known ground truth, for the body fit's tests and
bench/fit_body.py (issue 6): a body drawn from the prior, posed in a random world placement,
and a tight garment made by offsetting its surface over the regions a garment kind covers.
Everything in m, core frame (Y up). Draped garments come from pipeline/synthetic.py."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .model import BodyModel
from .params import BodyParams

TORSO = ("pelvis", "spine_1", "spine_2", "spine_3", "spine_4", "chest", "clavicle_left", "clavicle_right")

#: Joints whose skinned regions each offset garment covers, and the garment type the fit is told.
OFFSET_GARMENTS = {"top": (TORSO, None),
                   "trousers": (("pelvis", "hip_left", "hip_right", "knee_left", "knee_right"), "trousers"),
                   "shorts": (("pelvis", "spine_1", "hip_left", "hip_right"), "shorts")}


def random_body(model: BodyModel, rng, shape_sd: float = 0.7, pose_sd: float = 0.12,
                bone_sd: float = 0.02) -> BodyParams:
    """Parameters drawn from the prior: ν ~ N(0, shape_sd²), ψ ~ N(0, pose_sd²) (rad) clamped to
    the joint limits, bone scales 1 ± bone_sd; rest placement."""
    p = model.zero_params()
    p.shape[:] = rng.normal(scale=shape_sd, size=model.num_shape)
    p.pose[:] = model.clamp_pose(rng.normal(scale=pose_sd, size=p.pose.shape))
    p.bone_scales[:] = 1 + rng.normal(scale=bone_sd, size=model.num_joints)
    return p


def vertex_normals(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    fn = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    vn = np.zeros_like(X)
    for k in range(3):
        np.add.at(vn, F[:, k], fn)
    return vn / np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-18)


def region_garment(model: BodyModel, X: np.ndarray, offset: float, joints) -> tuple[np.ndarray, np.ndarray]:
    """(G, Fg): the posed body's (X) surface over the given joints' regions (faces whose vertices
    are all skinned mostly to them), moved offset (m) outward along the vertex normals."""
    inside = np.isin(np.argmax(model.weights, axis=1), [model.joint_index(n) for n in joints])
    F = model.faces[inside[model.faces].all(axis=1)]
    used = np.unique(F)
    remap = -np.ones(model.num_vertices, np.int64)
    remap[used] = np.arange(len(used))
    return X[used] + offset * vertex_normals(X, model.faces)[used], remap[F]


def offset_garment_case(model: BodyModel, seed: int, joints=TORSO, bone_noise: bool = False,
                        offset: float = 0.01):
    """(truth params, posed truth X, garment G, Fg): a body from the prior (pose sd 0.08 rad) in a
    random world placement (yaw, translation ~ N(0, 0.5²) m) under a garment `offset` m (the
    fit's default clearance) from it. Bone scales stay at 1 unless bone_noise (the whole prior)."""
    rng = np.random.default_rng(seed)
    truth = random_body(model, rng, pose_sd=0.08)
    if not bone_noise:
        truth.bone_scales[:] = 1.0
    R = Rotation.from_rotvec([0, rng.uniform(-np.pi, np.pi), 0]).as_matrix()
    truth.rotation[:] = Rotation.from_matrix(R).as_rotvec()
    truth.translation[:] = rng.normal(scale=0.5, size=3)
    X = model.pose(truth)
    G, Fg = region_garment(model, X, offset, joints)
    return truth, X, G, Fg


def stature(model: BodyModel, p: BodyParams) -> float:
    """Standing height (m): the body with its shape and bone lengths, joint angles at zero."""
    q = BodyParams.from_vector(p.to_vector(), model.num_shape, model.num_joints)
    q.pose[:] = 0.0
    V = model.pose(q)
    return float(V[:, 1].max() - V[:, 1].min())
