"""Reads a recovery's result directory back into simulation-ready objects (paper §5.5: the
assets simulate): the optimized pattern as rest shape, the recovered material, the recovered
body, and the draped garment as the initial state. Units: m, N·m, m/N, kg/m²."""
from __future__ import annotations

import json
import pathlib
from dataclasses import dataclass

import numpy as np

from ..body import BodyModel
from ..body.params import BodyParams
from ..pattern.export import load_pattern_json
from ..pattern.garment import Garment
from ..sim.cloth import CONTACT_NORMALS, Cloth
from ..sim.material import ClothMaterial


@dataclass
class RecoveredAssets:
    garment: Garment            # rest = optimized pattern, x0 = the recovered drape (m)
    materials: list             # ClothMaterial per panel
    thickness: float            # m
    body_model: BodyModel
    body_params: BodyParams
    summary: dict               # result.json
    contact_normals: str = "face"   # the contact plane of the recovery (result.json material; older results: face)

    def cloth(self) -> Cloth:
        """The garment as a Cloth on the recovered body, in its recovered drape, with the recovery's
        contact plane (the drape is an equilibrium of that one)."""
        g = self.garment
        return Cloth(g.rest, g.faces, g.x0, seams=g.seams, groups=g.panel[g.faces[:, 0]], materials=self.materials,
                     body=(self.body_model.pose(self.body_params), self.body_model.faces), thickness=self.thickness,
                     grain=g.face_grain(), contact_normals=self.contact_normals)


def load_result(result_dir, body_model: BodyModel | None = None) -> RecoveredAssets:
    """RecoveredAssets of a directory written by write_result (result.json with body_params and
    pattern.json are required; a clear error names what is missing)."""
    d = pathlib.Path(result_dir)
    for name in ("result.json", "pattern.json"):
        if not (d / name).is_file():
            raise FileNotFoundError(f"{d}: no {name} (not a recovery result directory?)")
    summary = json.loads((d / "result.json").read_text())
    if "body_params" not in summary:
        raise ValueError(f"{d / 'result.json'}: no body_params (written by an older version?)")
    g = load_pattern_json(d / "pattern.json")
    m = summary["material"]
    panel_k = m.get("panel_bending_stiffness_Nm") or []
    ks = panel_k if len(panel_k) == len(g.panels) else [m["bending_stiffness_Nm"]] * len(g.panels)
    materials = [ClothMaterial(density=m["density_kg_per_m2"], warp_compliance=m["compliance_warp_m_per_N"],
                               weft_compliance=m["compliance_weft_m_per_N"],
                               shear_compliance=m["compliance_shear_m_per_N"], bend_stiffness=k) for k in ks]
    model = body_model or BodyModel.default()
    if summary["body"]["model_id"] != model.name:
        raise ValueError(f"{d}: the body model is {summary['body']['model_id']!r}, this installation's is "
                         f"{model.name!r}")
    b = summary["body_params"]
    params = BodyParams(np.asarray(b["shape"]), np.asarray(b["pose_euler_zyx_rad"]), np.asarray(b["bone_scales"]),
                        np.asarray(b["rotation_axis_angle_rad"]), np.asarray(b["translation_m"]))
    normals = m.get("contact_normals", "face")
    if normals not in CONTACT_NORMALS:
        raise ValueError(f"{d / 'result.json'}: material.contact_normals {normals!r} is not one of {CONTACT_NORMALS}")
    return RecoveredAssets(g, materials, float(m["thickness_m"]), model, params, summary, normals)
