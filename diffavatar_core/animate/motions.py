"""Body motions as joint-angle keyframes on the body model (diffavatar_core.body: Euler angles
per joint in rad, R = R_z R_y R_x about the rest A-pose's world axes; X flexes hips/knees, Z
raises the arms). Built-ins are periodic over a phase s ∈ [0, 1); a JSON file gives keyframes
{"keyframes": [{"t": seconds, "pose": {"joint": [x, y, z], ...}}, ...]} interpolated linearly."""
from __future__ import annotations

import json
import pathlib

import numpy as np


def _walk(s):
    a = np.sin(2 * np.pi * s)
    return {"hip_left": [-0.45 * a, 0, 0], "hip_right": [0.45 * a, 0, 0],
            "knee_left": [0.6 * max(0.0, a), 0, 0], "knee_right": [0.6 * max(0.0, -a), 0, 0],
            "shoulder_left": [0.35 * a, 0, 0], "shoulder_right": [-0.35 * a, 0, 0],
            "elbow_left": [-0.3, 0, 0], "elbow_right": [-0.3, 0, 0]}


def _arms_raise(s):
    u = 0.5 - 0.5 * np.cos(2 * np.pi * s)  # 0 → 1 → 0
    return {"shoulder_left": [0, 0, 1.2 * u], "shoulder_right": [0, 0, -1.2 * u]}


def _torso_twist(s):
    a = 0.18 * np.sin(2 * np.pi * s)
    return {f"spine_{k}": [0, a, 0] for k in range(1, 5)}


MOTIONS = {"walk": _walk, "arms_raise": _arms_raise, "torso_twist": _torso_twist}


def motion_pose(joint_names, motion, s: float) -> np.ndarray:
    """(J, 3) joint angles (rad) of a built-in motion at phase s, or of keyframes (a callable)."""
    fn = MOTIONS[motion] if isinstance(motion, str) else motion
    pose = np.zeros((len(joint_names), 3))
    for name, ang in fn(s).items():
        if name not in joint_names:
            raise ValueError(f"motion: unknown joint {name!r}")
        pose[joint_names.index(name)] = ang
    return pose


def load_keyframes(path, duration: float | None = None):
    """A motion callable from a keyframe JSON (phase s maps to t = s × the last keyframe time)."""
    data = json.loads(pathlib.Path(path).read_text())
    kfs = sorted(data.get("keyframes", []), key=lambda k: float(k["t"]))
    if len(kfs) < 2:
        raise ValueError(f"{path}: needs at least two keyframes with 't' and 'pose'")
    times = np.array([float(k["t"]) for k in kfs])
    joints = sorted({j for k in kfs for j in k["pose"]})
    values = np.array([[k["pose"].get(j, [0, 0, 0]) for j in joints] for k in kfs], dtype=float)
    if not np.all(np.isfinite(values)) or values.shape[-1] != 3:
        raise ValueError(f"{path}: every pose entry must be three finite angles (rad)")
    span = times[-1] - times[0]

    def fn(s):
        t = times[0] + (s % 1.0) * span
        return {j: [float(np.interp(t, times, values[:, i, a])) for a in range(3)] for i, j in enumerate(joints)}
    return fn
