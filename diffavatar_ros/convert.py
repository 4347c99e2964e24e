"""Pure conversions between numpy arrays and diffavatar_msgs messages (no ROS graph needed).

Bulk data travels as flat primitive arrays (float32[] / uint32[] / uint8[]) so rclpy takes its
fast buffer path; reading uses np.frombuffer (no per-element Python objects).
"""
from __future__ import annotations

import numpy as np

from diffavatar_core.scan.frame import UNITS as _UNITS, UP_ROTATIONS as _UP_ROTATIONS
from diffavatar_msgs.msg import SegmentedScan

#: The units and up axes a scan may state: those of the core's scan frame conversion.
UNITS = tuple(_UNITS)
UP_AXES = tuple(_UP_ROTATIONS)


def scan_to_msg(vertices, faces, labels=None, label_names=(), *, units: str = "m", up_axis: str = "y",
                job_id: str = "", garment_type: str = "", template_name: str = "",
                iterations: int = 0, frame_id: str = "scan") -> SegmentedScan:
    """SegmentedScan from vertices (V, 3) in `units`, faces (F, 3), optional per-vertex labels (V,)."""
    V = np.ascontiguousarray(vertices, dtype=np.float32)
    F = np.ascontiguousarray(faces, dtype=np.uint32)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"vertices: expected shape (V, 3), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"faces: expected shape (F, 3), got {F.shape}")
    if units not in UNITS:
        raise ValueError(f"units: expected one of {UNITS}, got {units!r}")
    if up_axis not in UP_AXES:
        raise ValueError(f"up_axis: expected one of {UP_AXES}, got {up_axis!r}")
    msg = SegmentedScan()
    msg.header.frame_id = frame_id
    msg.job_id = job_id
    msg.vertices = V.ravel()
    msg.faces = F.ravel()
    if labels is not None:
        L = np.ascontiguousarray(labels, dtype=np.uint8)
        if L.shape != (V.shape[0],):
            raise ValueError(f"labels: expected shape ({V.shape[0]},), got {L.shape}")
        msg.labels = L.tobytes()
    msg.label_names = [str(n) for n in label_names]
    msg.units = units
    msg.up_axis = up_axis
    msg.garment_type = garment_type
    msg.template_name = template_name
    msg.iterations = int(iterations)
    return msg


def msg_to_arrays(msg: SegmentedScan) -> dict:
    """Flat arrays of a SegmentedScan as numpy views, unvalidated (validation belongs to the
    core's scan checks, diffavatar_core.scan.check_scan / load_scan accept this dict and name
    every problem): vertices (3V,) float32, faces (3F,) uint32,
    labels (V,) uint8, plus the scalar fields."""
    return {
        "vertices": np.frombuffer(msg.vertices, dtype=np.float32),
        "faces": np.frombuffer(msg.faces, dtype=np.uint32),
        "labels": np.frombuffer(bytes(msg.labels), dtype=np.uint8),
        "label_names": list(msg.label_names),
        "units": msg.units,
        "up_axis": msg.up_axis,
        "job_id": msg.job_id,
        "garment_type": msg.garment_type,
        "template_name": msg.template_name,
        "iterations": int(msg.iterations),
    }


# --- results -------------------------------------------------------------------------------

def _f32(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float32).ravel())


def _u32(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.uint32).ravel())


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).ravel())


def flat_mesh(vertices, faces, uvs=None):
    from diffavatar_msgs.msg import FlatMesh
    m = FlatMesh()
    m.vertices, m.faces = _f32(vertices), _u32(faces)
    if uvs is not None:
        m.uvs = _f32(uvs)
    return m


def error_code(name: str) -> int:
    """AvatarAssets.ERROR_<name>, or ERROR_INTERNAL for a name the interface does not know."""
    from diffavatar_msgs.msg import AvatarAssets
    return int(getattr(AvatarAssets, f"ERROR_{name}", AvatarAssets.ERROR_INTERNAL))


def error_assets(job_id: str, code: str, message: str):
    """AvatarAssets carrying only an error (code name as in AvatarAssets.ERROR_*)."""
    from diffavatar_msgs.msg import AvatarAssets
    msg = AvatarAssets()
    msg.job_id, msg.error_code, msg.error_msg = job_id, error_code(code), message
    return msg


def result_to_assets(job_id: str, result) -> "AvatarAssets":
    """AvatarAssets from a diffavatar_core.pipeline.result.RecoveryResult (SI units kept)."""
    from diffavatar_msgs.msg import AvatarAssets
    msg = AvatarAssets()
    msg.job_id, msg.error_code = job_id, AvatarAssets.ERROR_NONE
    msg.garment_type, msg.template_name = result.garment_type, result.template_name
    p = result.pattern
    msg.pattern.rest_xy = _f64(p.rest_xy)
    msg.pattern.triangles = _u32(p.triangles)
    msg.pattern.panel_vertex_start = _u32(p.panel_vertex_start)
    msg.pattern.panel_names = [str(n) for n in p.panel_names]
    msg.pattern.panel_grain_rad = _f64(p.panel_grain_rad)
    msg.pattern.seam_pairs = _u32(p.seam_pairs)
    msg.pattern.handles = _u32(p.handles)
    m = result.material
    msg.material.bending_stiffness = float(m.bending_stiffness)
    msg.material.panel_bending_stiffness = _f64(m.panel_bending_stiffness)
    low, high = m.bending_stiffness_range   # None (open, not judged) → 0
    msg.material.bending_stiffness_low, msg.material.bending_stiffness_high = float(low or 0.0), float(high or 0.0)
    msg.material.compliance_warp = float(m.compliance_warp)
    msg.material.compliance_weft = float(m.compliance_weft)
    msg.material.compliance_shear = float(m.compliance_shear)
    msg.material.density = float(m.density)
    msg.material.thickness = float(m.thickness)
    msg.material.contact_normals = str(m.contact_normals)
    b = result.body
    msg.body.model_id = b.model_id
    msg.body.shape = _f64(b.shape)
    msg.body.joint_names = [str(n) for n in b.joint_names]
    msg.body.pose = _f64(b.pose)
    msg.body.bone_scales = _f64(b.bone_scales)
    msg.body.global_transform = _f64(b.global_transform)
    msg.garment_draped = flat_mesh(result.garment_vertices, result.garment_faces, result.garment_uv)
    msg.body_mesh = flat_mesh(result.body_vertices, result.body_faces)
    mt = result.metrics
    msg.chamfer_initial_cm = float(mt.get("chamfer_initial_cm", float("nan")))
    msg.chamfer_final_cm = float(mt.get("chamfer_final_cm", float("nan")))
    msg.mesh_quality_min = float(mt.get("mesh_quality_min", float("nan")))
    msg.mesh_quality_avg = float(mt.get("mesh_quality_avg", float("nan")))
    msg.seam_length_mismatch_max_pct = float(mt.get("seam_length_mismatch_max_pct", float("nan")))
    msg.iterations = int(result.iterations)
    msg.wall_s = float(result.wall_s)
    msg.output_dir = str(result.output_dir or "")
    msg.warnings = [str(w) for w in getattr(result, "warnings", ())]
    return msg


def assets_to_arrays(msg) -> dict:
    """The bulk arrays of an AvatarAssets as shaped numpy arrays (for clients and tests)."""
    p = msg.pattern
    return {
        "rest_xy": np.frombuffer(p.rest_xy, np.float64).reshape(-1, 2),
        "triangles": np.frombuffer(p.triangles, np.uint32).reshape(-1, 3),
        "panel_vertex_start": np.frombuffer(p.panel_vertex_start, np.uint32),
        "seam_pairs": np.frombuffer(p.seam_pairs, np.uint32).reshape(-1, 2),
        "handles": np.frombuffer(p.handles, np.uint32),
        "garment_vertices": np.frombuffer(msg.garment_draped.vertices, np.float32).reshape(-1, 3),
        "garment_faces": np.frombuffer(msg.garment_draped.faces, np.uint32).reshape(-1, 3),
        "garment_uv": np.frombuffer(msg.garment_draped.uvs, np.float32).reshape(-1, 2),
        "body_vertices": np.frombuffer(msg.body_mesh.vertices, np.float32).reshape(-1, 3),
        "body_faces": np.frombuffer(msg.body_mesh.faces, np.uint32).reshape(-1, 3),
        "shape": np.frombuffer(msg.body.shape, np.float64),
        "pose": np.frombuffer(msg.body.pose, np.float64).reshape(-1, 3),
    }


def progress_msg(job_id: str, stage: str, iteration: int, max_iterations: int, loss: float,
                 terms: dict, elapsed_s: float, eta_s: float):
    from diffavatar_msgs.msg import OptimizationProgress
    m = OptimizationProgress()
    m.job_id, m.stage = job_id, stage
    m.iteration, m.max_iterations = int(iteration), int(max_iterations)
    m.loss = float(loss)
    m.loss_term_names = list(terms)
    m.loss_terms = _f64([terms[k] for k in terms])
    m.elapsed_s, m.eta_s = float(elapsed_s), float(eta_s)
    return m


def mesh_to_shape_msgs(vertices, faces):
    """shape_msgs/Mesh for interoperability only (slow in rclpy: one Python object per vertex)."""
    from geometry_msgs.msg import Point
    from shape_msgs.msg import Mesh, MeshTriangle
    m = Mesh()
    m.vertices = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in np.asarray(vertices, float)]
    m.triangles = [MeshTriangle(vertex_indices=[int(a), int(b), int(c)]) for a, b, c in np.asarray(faces)]
    return m


def shape_msgs_to_mesh(msg) -> tuple[np.ndarray, np.ndarray]:
    V = np.array([[p.x, p.y, p.z] for p in msg.vertices], dtype=np.float64).reshape(-1, 3)
    F = np.array([list(t.vertex_indices) for t in msg.triangles], dtype=np.int64).reshape(-1, 3)
    return V, F


def assets_to_result(msg, loss_history=()):
    """A diffavatar_core.pipeline.result.RecoveryResult from a successful AvatarAssets (the
    inverse of result_to_assets), so a client writes the same files as the CLI with
    diffavatar_core.pipeline.output.write_result. loss_history: per iteration
    {"iteration", "value", "terms"}, e.g. gathered from the job's progress messages."""
    from diffavatar_core.pipeline.result import BodyAssets, MaterialAssets, PatternAssets, RecoveryResult
    a = assets_to_arrays(msg)
    p, m, b = msg.pattern, msg.material, msg.body
    metrics = {"chamfer_initial_cm": msg.chamfer_initial_cm, "chamfer_final_cm": msg.chamfer_final_cm,
               "mesh_quality_min": msg.mesh_quality_min, "mesh_quality_avg": msg.mesh_quality_avg,
               "seam_length_mismatch_max_pct": msg.seam_length_mismatch_max_pct}
    uv = a["garment_uv"] if len(a["garment_uv"]) == len(a["garment_vertices"]) else None
    return RecoveryResult(
        garment_type=msg.garment_type, template_name=msg.template_name,
        pattern=PatternAssets(rest_xy=a["rest_xy"], triangles=a["triangles"],
                              panel_vertex_start=a["panel_vertex_start"], panel_names=list(p.panel_names),
                              panel_grain_rad=np.frombuffer(p.panel_grain_rad, np.float64),
                              seam_pairs=a["seam_pairs"], handles=a["handles"]),
        material=MaterialAssets(bending_stiffness=m.bending_stiffness,
                                panel_bending_stiffness=np.frombuffer(m.panel_bending_stiffness, np.float64),
                                compliance_warp=m.compliance_warp, compliance_weft=m.compliance_weft,
                                compliance_shear=m.compliance_shear, density=m.density, thickness=m.thickness,
                                contact_normals=m.contact_normals or "face",
                                bending_stiffness_range=(m.bending_stiffness_low or None,
                                                         m.bending_stiffness_high or None)),
        body=BodyAssets(model_id=b.model_id, shape=a["shape"], joint_names=list(b.joint_names), pose=a["pose"],
                        bone_scales=np.frombuffer(b.bone_scales, np.float64),
                        global_transform=np.frombuffer(b.global_transform, np.float64)),
        garment_vertices=a["garment_vertices"].astype(np.float64), garment_faces=a["garment_faces"].astype(np.int64),
        garment_uv=uv, body_vertices=a["body_vertices"].astype(np.float64),
        body_faces=a["body_faces"].astype(np.int64), metrics=metrics, iterations=int(msg.iterations),
        wall_s=float(msg.wall_s), loss_history=list(loss_history), warnings=list(msg.warnings))
