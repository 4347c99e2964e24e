"""What a recovery produces (paper §4.2): the simulation-ready assets and the run's metrics.
Plain arrays in SI units, so the CLI writer, the Python API and the ROS converters share it."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class PatternAssets:
    """The optimized 2D sewing pattern, all panels concatenated."""
    rest_xy: np.ndarray             # (N, 2) pattern coordinates, m
    triangles: np.ndarray           # (T, 3) indices into rest_xy
    panel_vertex_start: np.ndarray  # (P+1,) panel p owns vertices [start[p], start[p+1])
    panel_names: list               # (P,) names
    panel_grain_rad: np.ndarray     # (P,) warp direction, rad from the pattern x axis
    seam_pairs: np.ndarray          # (S, 2) sewn pattern-vertex pairs
    handles: np.ndarray             # (H,) control-cage handle vertex indices


@dataclass
class MaterialAssets:
    """Recovered cloth material (orthotropic StVK stretching, hinge bending)."""
    bending_stiffness: float        # N·m
    panel_bending_stiffness: np.ndarray  # (P,) N·m, or empty for one garment-wide value
    compliance_warp: float          # m/N
    compliance_weft: float          # m/N
    compliance_shear: float         # m/N
    density: float                  # kg/m²
    thickness: float                # m (collision thickness)
    contact_normals: str = "face"   # the cloth–body contact plane the drape is an equilibrium of (sim.cloth.CONTACT_NORMALS)
    # N·m: the bendings judged alike bending_stiffness lie within (low, high); None: open on that side or not judged
    # (pipeline/bending_range.py)
    bending_stiffness_range: tuple = (None, None)


@dataclass
class BodyAssets:
    """Recovered body parameters (paper §3.1)."""
    model_id: str
    shape: np.ndarray               # (K,) shape coefficients ν
    joint_names: list               # (J,)
    pose: np.ndarray                # (J, 3) axis-angle per joint, rad
    bone_scales: np.ndarray         # (J,) dimensionless
    global_transform: np.ndarray    # (6,) axis-angle rad + translation m


@dataclass
class RecoveryResult:
    garment_type: str
    template_name: str
    pattern: PatternAssets
    material: MaterialAssets
    body: BodyAssets
    garment_vertices: np.ndarray    # (V, 3) draped garment, m, core frame (Y up)
    garment_faces: np.ndarray       # (F, 3)
    garment_uv: np.ndarray          # (V, 2) pattern coordinates of each draped vertex, m
    body_vertices: np.ndarray       # (Vb, 3) posed body, m
    body_faces: np.ndarray          # (Fb, 3)
    metrics: dict                   # chamfer_initial_cm, chamfer_final_cm, mesh_quality_min/avg, seam_length_mismatch_max_pct
    iterations: int
    wall_s: float
    loss_history: list = field(default_factory=list)  # per iteration: {"iteration", "value", "terms", "stage"}
    # (stage: 'measurements' — the template measurement fit, first — or 'co_optimization')
    output_dir: str = ""
    garment: object = None          # the recovered pattern.Garment (writes pattern.json/.svg/.png)
    body_params: object = None      # body.BodyParams as fitted (Euler joint angles; exact re-posing)
    warnings: list = field(default_factory=list)  # what preprocessing dropped or could not find
    scan_mesh: tuple | None = None  # (V, F) of the cleaned scan, m, core frame (preview.png, SSIM)
