"""`diffavatar preview SCAN --garment MESH [--body MESH] --out PNG`: the scan vs the recovered
drape from 4 views (front/right/back/left) side by side, and their render SSIM (paper Table 1)."""
import json

from ..io import load_mesh
from ..render import preview_side_by_side, ssim_metric


def run(args) -> int:
    from . import check_out_file, write_failed
    check_out_file(args.out)   # before loading and rendering
    scan = load_mesh(args.scan)
    garment = load_mesh(args.garment)
    body = load_mesh(args.body) if args.body else None
    result = [garment] + ([body] if body is not None else [])
    try:
        preview_side_by_side(scan, result, args.out, size=args.size)
    except OSError as exc:
        raise write_failed(args.out, exc, "writing the preview") from None
    out = {"preview": str(args.out), "ssim": ssim_metric(scan, garment, body, size=args.size),
           "ssim_views": ["front", "right", "back", "left"]}
    print(json.dumps(out, indent=2))
    return 0


def register(sub) -> None:
    p = sub.add_parser("preview", help="PNG of a scan vs a recovered garment (+ body) from 4 views, and SSIM")
    p.add_argument("scan", help="scan mesh file")
    p.add_argument("--garment", required=True, help="recovered (draped) garment mesh file")
    p.add_argument("--body", help="recovered body mesh file")
    p.add_argument("--out", required=True, help="output PNG path")
    p.add_argument("--size", type=int, default=256, help="pixels per view (square)")
    p.set_defaults(func=run)
