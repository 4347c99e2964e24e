"""Cloth material (paper §4.2.4): orthotropic StVK stretch compliances and bending stiffness."""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass
class ClothMaterial:
    """density: areal density (kg/m²); stretch compliances α (m/N, inverse 2D stiffness) for the
    warp (pattern x), weft (pattern y) and shear Green-strain components; bend_stiffness k (N·m).
    Defaults: a mid-weight woven cotton (about 150 g/m², 1 kN/m in-plane, k = 5e-6 N·m)."""
    density: float = 0.15
    warp_compliance: float = 1.0e-3
    weft_compliance: float = 1.0e-3
    shear_compliance: float = 1.0e-2
    bend_stiffness: float = 5.0e-6

    def __post_init__(self):
        for name in ("density", "warp_compliance", "weft_compliance", "shear_compliance"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"ClothMaterial.{name}: expected a finite value > 0, got {v}")
            setattr(self, name, v)
        k = float(self.bend_stiffness)
        if not (np.isfinite(k) and k >= 0):
            raise ValueError(f"ClothMaterial.bend_stiffness: expected a finite value >= 0 N·m, got {k}")
        self.bend_stiffness = k

    @property
    def compliance(self) -> np.ndarray:
        """(3,) [warp, weft, shear] in m/N."""
        return np.array([self.warp_compliance, self.weft_compliance, self.shear_compliance])

    def to_dict(self) -> dict:
        return asdict(self)
