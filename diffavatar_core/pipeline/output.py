"""Writes a RecoveryResult to a directory — the files the CLI, the node and the client share:
result.json, garment_rest.obj (2D pattern mesh, z = 0), garment_draped.obj (3D, UVs = pattern
coordinates in m), body.obj, loss.png; plus pattern.json/.svg/.png via the pattern exporter
when it is available for this result."""
from __future__ import annotations

import json
import math
import pathlib

import numpy as np

from .result import RecoveryResult


def _obj(path: pathlib.Path, V, F, uv=None, header: str = "") -> None:
    """OBJ with optional per-vertex UVs (1-based indices; vt index = v index)."""
    lines = [f"# {header}"] if header else []
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in np.asarray(V, float)]
    if uv is not None:
        lines += [f"vt {u:.9g} {v:.9g}" for u, v in np.asarray(uv, float)]
        lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in np.asarray(F, np.int64) + 1]
    else:
        lines += [f"f {a} {b} {c}" for a, b, c in np.asarray(F, np.int64) + 1]
    path.write_text("\n".join(lines) + "\n")


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return x


def result_summary(r: RecoveryResult) -> dict:
    """The content of result.json (SI units; metrics named with their unit)."""
    m, b = r.material, r.body
    return _jsonable({
        "garment_type": r.garment_type,
        "template": r.template_name,
        "material": {"bending_stiffness_Nm": m.bending_stiffness,
                     "panel_bending_stiffness_Nm": m.panel_bending_stiffness,
                     "bending_stiffness_range_Nm": list(m.bending_stiffness_range),
                     "compliance_warp_m_per_N": m.compliance_warp,
                     "compliance_weft_m_per_N": m.compliance_weft,
                     "compliance_shear_m_per_N": m.compliance_shear,
                     "density_kg_per_m2": m.density, "thickness_m": m.thickness,
                     "contact_normals": m.contact_normals},
        "body": {"model_id": b.model_id, "shape": b.shape, "joint_names": b.joint_names,
                 "pose_axis_angle_rad": b.pose, "bone_scales": b.bone_scales,
                 "global_transform": b.global_transform},
        "pattern": {"panels": r.pattern.panel_names, "vertices": len(r.pattern.rest_xy),
                    "triangles": len(r.pattern.triangles), "seam_pairs": len(r.pattern.seam_pairs),
                    "handles": len(r.pattern.handles)},
        "metrics": r.metrics,
        "iterations": r.iterations,
        "wall_s": r.wall_s,
        "loss_history": r.loss_history,
        "warnings": list(r.warnings),
        **({"body_params": {"shape": r.body_params.shape, "pose_euler_zyx_rad": r.body_params.pose,
                            "bone_scales": r.body_params.bone_scales, "rotation_axis_angle_rad": r.body_params.rotation,
                            "translation_m": r.body_params.translation}} if r.body_params is not None else {}),
    })


def plot_loss(path: pathlib.Path, history: list, size=(800, 480)) -> None:
    """loss.png: total loss and each term per iteration on a log scale (Pillow only)."""
    from PIL import Image, ImageDraw
    W, H = size
    img = Image.new("RGB", size, "white")
    d = ImageDraw.Draw(img)
    left, right, top, bottom = 70, W - 160, 20, H - 40
    d.rectangle([left, top, right, bottom], outline="black")
    series = {"total": [h["value"] for h in history]}
    for h in history:
        for k, v in (h.get("terms") or {}).items():
            series.setdefault(k, [])
    for k in list(series)[1:]:
        series[k] = [(h.get("terms") or {}).get(k, float("nan")) for h in history]
    vals = np.array([v for s in series.values() for v in s if v is not None and np.isfinite(v) and v > 0])
    d.text(((left + right) // 2 - 20, bottom + 8), "iteration", fill="black")
    if len(history) < 1 or vals.size == 0:
        d.text((left + 10, top + 10), "no loss history", fill="black")
        img.save(path)
        return
    lo, hi = np.log10(vals.min()), np.log10(vals.max())
    hi = hi if hi > lo else lo + 1
    n = max(len(history) - 1, 1)
    d.text((left - 3, bottom + 4), "0", fill="black")
    d.text((right - 8, bottom + 4), str(n), fill="black")
    colors = ["#000000", "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf"]
    for e in range(int(math.floor(lo)), int(math.ceil(hi)) + 1):
        y = bottom - (e - lo) / (hi - lo) * (bottom - top)
        if top <= y <= bottom:
            d.line([left - 4, y, left, y], fill="black")
            d.text((8, y - 6), f"1e{e}", fill="black")
    for i, (name, s) in enumerate(series.items()):
        c = colors[i % len(colors)]
        pts = [(left + j / n * (right - left), bottom - (math.log10(v) - lo) / (hi - lo) * (bottom - top))
               for j, v in enumerate(s) if v is not None and np.isfinite(v) and v > 0]
        if len(pts) > 1:
            d.line(pts, fill=c, width=2)
        elif pts:
            d.ellipse([pts[0][0] - 2, pts[0][1] - 2, pts[0][0] + 2, pts[0][1] + 2], fill=c)
        d.text((right + 10, top + 16 * i), name, fill=c)
    img.save(path)


def write_result(result: RecoveryResult, out_dir: str | pathlib.Path, scan=None) -> pathlib.Path:
    """Writes every output file; returns the directory. Existing files of a previous run in the
    same directory are overwritten. With `scan` ((V, F) of the input scan, m, core frame) also
    writes preview.png (scan vs result from 4 views) and sets metrics["ssim"], the mean render
    SSIM over those views (paper Table 1), before result.json is written. With result.garment
    (the pattern.Garment) also pattern.json, pattern.svg and pattern.png."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result.output_dir = str(out)
    if scan is not None:
        from ..render import preview_side_by_side, ssim_metric
        garment = (result.garment_vertices, result.garment_faces)
        body = (result.body_vertices, result.body_faces)
        result.metrics["ssim"] = ssim_metric(scan, garment, body)
        preview_side_by_side(scan, [garment, body], out / "preview.png")
    (out / "result.json").write_text(json.dumps(result_summary(result), indent=2))
    p = result.pattern
    _obj(out / "garment_rest.obj", np.column_stack([p.rest_xy, np.zeros(len(p.rest_xy))]), p.triangles,
         uv=p.rest_xy, header="DiffAvatar optimized sewing pattern (m, z = 0); vt = pattern coordinates (m)")
    _obj(out / "garment_draped.obj", result.garment_vertices, result.garment_faces, uv=result.garment_uv,
         header="DiffAvatar draped garment (m, Y up); vt = pattern coordinates (m)")
    _obj(out / "body.obj", result.body_vertices, result.body_faces, header="DiffAvatar recovered body (m, Y up)")
    plot_loss(out / "loss.png", result.loss_history)
    if result.garment is not None:
        from ..pattern.export import save_pattern_json, save_png, save_svg
        handles = result.pattern.handles if len(result.pattern.handles) else None
        save_pattern_json(out / "pattern.json", result.garment, handles)
        save_svg(out / "pattern.svg", result.garment, handles)
        save_png(out / "pattern.png", result.garment, handles)
    return out
