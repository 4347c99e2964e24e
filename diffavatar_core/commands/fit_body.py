"""`diffavatar fit-body SCAN --out DIR [--units cm|m|mm] [--up y|z] [--garment-only] [--garment-type T]`: fits the
parametric body to a scan (mesh or point cloud: OBJ, PLY, ...) and writes DIR/body.obj (posed
body, m, Y up: the core's frame) and DIR/body.json (parameters, landmarks, scan → core frame)."""
import json
import pathlib
import sys

import numpy as np

from ..scan.frame import UP_AXES


def load_scan(path):
    """(points (N,3), faces (F,3) or None) of a mesh or point-cloud file, as stored."""
    import trimesh
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    g = trimesh.load(str(path), process=False)
    if isinstance(g, trimesh.Scene):
        g = g.to_geometry() if hasattr(g, "to_geometry") else g.dump(concatenate=True)
    V = np.asarray(getattr(g, "vertices", np.zeros((0, 3))), np.float64)
    if len(V) == 0:
        raise ValueError(f"{path}: holds no points")
    F = np.asarray(g.faces, np.int64) if getattr(g, "faces", None) is not None and len(g.faces) else None
    return V, F


def run(args) -> int:
    from ..body import BodyModel
    from ..body.fitting import FitOptions, fit_body
    from . import check_out_dir, write_failed
    out = check_out_dir(args.out)   # before the fit, not after
    V, F = load_scan(args.scan)
    model = BodyModel.default()
    opts = FitOptions(iterations=args.iterations, seed=args.seed)

    def progress(it, n, rms):
        if not args.quiet:
            print(f"[fit-body] iteration {it + 1}/{n}: scan→body RMS {1000 * rms:.1f} mm", file=sys.stderr)
    res = fit_body(V, F, model, units=args.units, up=args.up,
                   garment_only=args.garment_only or bool(args.garment_type), garment_type=args.garment_type,
                   options=opts, progress=progress)
    try:
        out.mkdir(parents=True, exist_ok=True)
        model.export_obj(out / "body.obj", res.params)
    except OSError as exc:
        raise write_failed(args.out, exc, "writing the body fit") from None
    doc = {
        "model": model.name,
        "frame": "core: metres, Y up, body facing +Z, +X = body's left",
        "scan": str(args.scan), "scan_units": args.units, "scan_up": args.up,
        "scan_to_core": res.to_core.tolist(),
        "mode": "garment-only" if (args.garment_only or args.garment_type) else "full-scan",
        "rms_m": res.rms,
        "params": res.params.to_dict(model.joint_names),
        "landmarks": model.landmarks(res.params).to_dict(),
    }
    try:
        (out / "body.json").write_text(json.dumps(doc, indent=2))
    except OSError as exc:
        raise write_failed(args.out, exc, "writing the body fit") from None
    print(json.dumps({"body_obj": str(out / "body.obj"), "body_json": str(out / "body.json"),
                      "rms_m": res.rms, "height_m": doc["landmarks"]["height"]}, indent=2))
    return 0


def register(sub) -> None:
    p = sub.add_parser("fit-body", help="fit the parametric body to a scan (or under a garment)")
    p.add_argument("scan", help="scan mesh or point cloud (OBJ, PLY, STL, ...)")
    p.add_argument("--out", required=True, help="output directory for body.obj and body.json")
    p.add_argument("--units", choices=["m", "cm", "mm"], default="m", help="units of the scan")
    p.add_argument("--up", choices=UP_AXES, default="y", help="vertical axis of the scan (a Y-down file: --up=-y)")
    p.add_argument("--garment-type", default=None,
                   help="garment-only scan of this type (config/labels.yaml: tshirt, skirt, shorts, ...): "
                        "tops are placed at the shoulders, skirts and trousers at the waist")
    p.add_argument("--garment-only", action="store_true",
                   help="the scan is a garment: fit the body inside it")
    p.add_argument("--iterations", type=int, default=45, help="Gauss-Newton iterations")
    p.add_argument("--seed", type=int, default=0, help="seed of the per-iteration subsampling")
    p.add_argument("--quiet", action="store_true", help="no per-iteration progress on stderr")
    p.set_defaults(func=run)
