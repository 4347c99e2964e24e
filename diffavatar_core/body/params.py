"""Body parameters (the Control of the body): shape ν, joint angles ψ, bone-length scales and a
global rigid transform, with a JSON round trip and the flat vector layout of the Jacobians."""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np


@dataclass
class BodyParams:
    """shape: (K,) unit-variance shape coefficients ν; pose: (J, 3) Euler angles ψ in rad,
    R_j = R_z R_y R_x about the rest pose's world axes; bone_scales: (J,) bone-length scales
    (1 = rest); rotation: (3,) global axis-angle (rad); translation: (3,) global offset (m)."""
    shape: np.ndarray
    pose: np.ndarray
    bone_scales: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        def arr(name, shape):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            try:
                a = a.reshape(shape)
            except ValueError:
                raise ValueError(f"BodyParams.{name}: expected shape {shape}, got {a.shape}") from None
            if not np.all(np.isfinite(a)):
                raise ValueError(f"BodyParams.{name}: contains NaN or Inf")
            setattr(self, name, np.ascontiguousarray(a))
        arr("shape", (-1,))
        arr("pose", (-1, 3))
        arr("bone_scales", (-1,))
        arr("rotation", (3,))
        arr("translation", (3,))
        if len(self.bone_scales) != len(self.pose):
            raise ValueError(f"BodyParams.bone_scales: {len(self.bone_scales)} values for "
                             f"{len(self.pose)} joints")
        if np.any(self.bone_scales <= 0):
            raise ValueError("BodyParams.bone_scales: must be positive")

    @classmethod
    def zeros(cls, num_shape: int, num_joints: int) -> "BodyParams":
        """Mean shape, rest pose, unit bone scales, identity transform."""
        return cls(np.zeros(num_shape), np.zeros((num_joints, 3)), np.ones(num_joints))

    def copy(self) -> "BodyParams":
        return BodyParams(self.shape.copy(), self.pose.copy(), self.bone_scales.copy(),
                          self.rotation.copy(), self.translation.copy())

    # flat vector in the Jacobian's column order: [ν, ψ (joint-major x,y,z), s, r, t]
    def to_vector(self) -> np.ndarray:
        return np.concatenate([self.shape, self.pose.reshape(-1), self.bone_scales,
                               self.rotation, self.translation])

    @classmethod
    def from_vector(cls, x, num_shape: int, num_joints: int) -> "BodyParams":
        x = np.asarray(x, dtype=np.float64).reshape(-1)
        K, J = num_shape, num_joints
        if x.shape != (K + 4 * J + 6,):
            raise ValueError(f"params vector: expected {K + 4 * J + 6} values, got {x.shape}")
        return cls(x[:K], x[K:K + 3 * J].reshape(J, 3), x[K + 3 * J:K + 4 * J],
                   x[K + 4 * J:K + 4 * J + 3], x[K + 4 * J + 3:])

    def to_dict(self, joint_names=None) -> dict:
        d = {"units": {"pose": "rad", "rotation": "rad (axis-angle)", "translation": "m"},
             "euler_order": "R = Rz Ry Rx",
             "shape": self.shape.tolist(), "pose": self.pose.tolist(),
             "bone_scales": self.bone_scales.tolist(), "rotation": self.rotation.tolist(),
             "translation": self.translation.tolist()}
        if joint_names is not None:
            d["joint_names"] = list(joint_names)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "BodyParams":
        missing = {"shape", "pose", "bone_scales", "rotation", "translation"} - set(d)
        if missing:
            raise ValueError(f"BodyParams: missing {sorted(missing)}")
        return cls(d["shape"], d["pose"], d["bone_scales"], d["rotation"], d["translation"])

    def to_json(self, joint_names=None) -> str:
        return json.dumps(self.to_dict(joint_names), indent=2)

    @classmethod
    def from_json(cls, text: str) -> "BodyParams":
        return cls.from_dict(json.loads(text))
