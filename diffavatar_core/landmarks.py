"""Body landmarks: the contract between the body model (which computes them from a posed body)
and the garment templates (which place their panels around them).

Frame (the core's): metres, Y up, the body faces +Z, +X is the body's left; the origin is
wherever the body mesh puts it (landmarks are absolute positions in that frame).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields

import numpy as np

_POINTS = ("neck_base", "shoulder_left", "shoulder_right", "elbow_left", "elbow_right",
           "wrist_left", "wrist_right", "chest_center", "waist_center", "hip_center",
           "knee_left", "knee_right", "ankle_left", "ankle_right")


@dataclass
class BodyLandmarks:
    """Landmarks of a posed body (all positions (3,) in m; girths in m, circumferences).

    neck_base: front-back midpoint of the neck at its base; shoulder_*: acromion (shoulder tip);
    elbow_*/wrist_*/knee_*/ankle_*: joint centres; chest/waist/hip_center: centre of the torso
    cross-section at that height; *_girth: circumference of that cross-section;
    height: floor to top of head (m).
    """
    height: float
    chest_girth: float
    waist_girth: float
    hip_girth: float
    neck_base: np.ndarray
    shoulder_left: np.ndarray
    shoulder_right: np.ndarray
    elbow_left: np.ndarray
    elbow_right: np.ndarray
    wrist_left: np.ndarray
    wrist_right: np.ndarray
    chest_center: np.ndarray
    waist_center: np.ndarray
    hip_center: np.ndarray
    knee_left: np.ndarray
    knee_right: np.ndarray
    ankle_left: np.ndarray
    ankle_right: np.ndarray

    def __post_init__(self):
        for name in _POINTS:
            p = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"BodyLandmarks.{name}: expected a finite (3,) point, got {p}")
            setattr(self, name, p)
        for name in ("height", "chest_girth", "waist_girth", "hip_girth"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"BodyLandmarks.{name}: expected a positive length in m, got {v}")
            setattr(self, name, v)

    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in d.items()}

    @classmethod
    def from_dict(cls, d: dict) -> "BodyLandmarks":
        names = {f.name for f in fields(cls)}
        missing = names - set(d)
        if missing:
            raise ValueError(f"BodyLandmarks: missing {sorted(missing)}")
        return cls(**{k: d[k] for k in names})

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)
